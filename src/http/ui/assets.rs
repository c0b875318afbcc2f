//! The embedded assets — the stylesheet, and the one script (`live.js`,
//! which keeps the fleet and sensor pages current from the event stream)
//! — each served under a name that changes with its content
//! (`/ui/assets/style-<hash>.css`, `/ui/assets/live-<hash>.js`), so
//! browsers may keep them forever.

use std::sync::LazyLock;

use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use super::UiError;
use crate::http::problem::Problem;

/// The stylesheet, compiled into the binary.
pub const STYLESHEET: &str = include_str!("assets/style.css");
/// The pages' script, compiled into the binary.
pub const SCRIPT: &str = include_str!("assets/live.js");

/// One asset: its plain name, its name with the content's hash, its
/// content and type.
struct Asset {
    plain: &'static str,
    hashed: String,
    content: &'static str,
    content_type: &'static str,
}

impl Asset {
    /// `plain` is `<stem>.<ext>`; the hashed name `<stem>-<12 hex>.<ext>`.
    fn new(plain: &'static str, content: &'static str, content_type: &'static str) -> Asset {
        let (stem, ext) = plain.split_once('.').unwrap_or((plain, ""));
        let digest = Sha256::digest(content.as_bytes());
        Asset {
            plain,
            hashed: format!("{stem}-{}.{ext}", &hex::encode(digest)[..12]),
            content,
            content_type,
        }
    }
}

static ASSETS: LazyLock<[Asset; 2]> = LazyLock::new(|| {
    [
        Asset::new("style.css", STYLESHEET, "text/css; charset=utf-8"),
        Asset::new("live.js", SCRIPT, "text/javascript; charset=utf-8"),
    ]
});

/// The stylesheet's path, with its content hash.
pub fn stylesheet_path() -> String {
    format!("/ui/assets/{}", ASSETS[0].hashed)
}

/// The script's path, with its content hash.
pub fn script_path() -> String {
    format!("/ui/assets/{}", ASSETS[1].hashed)
}

/// `GET /ui/assets/{file}`: an asset (public; cached for good by its
/// hashed name, revalidated by its plain one).
pub async fn serve(Path(file): Path<String>) -> Result<Response, UiError> {
    let Some((asset, cache)) = ASSETS.iter().find_map(|a| {
        if file == a.hashed {
            Some((a, "public, max-age=31536000, immutable"))
        } else if file == a.plain {
            Some((a, "no-cache"))
        } else {
            None
        }
    }) else {
        return Err(UiError::Problem(Problem::not_found(
            "there is no such asset",
        )));
    };
    let mut res = asset.content.into_response();
    let h = res.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(asset.content_type),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    Ok(res)
}
