//! The embedded stylesheet, served under a name that changes with its
//! content (`/ui/assets/style-<hash>.css`), so browsers may keep it forever.

use std::sync::LazyLock;

use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use super::UiError;
use crate::http::problem::Problem;

/// The stylesheet, compiled into the binary.
pub const STYLESHEET: &str = include_str!("assets/style.css");

static NAME: LazyLock<String> = LazyLock::new(|| {
    let digest = Sha256::digest(STYLESHEET.as_bytes());
    format!("style-{}.css", &hex::encode(digest)[..12])
});

/// The stylesheet's path, with its content hash.
pub fn stylesheet_path() -> String {
    format!("/ui/assets/{}", *NAME)
}

/// `GET /ui/assets/{file}`: the stylesheet (public, cached by name).
pub async fn serve(Path(file): Path<String>) -> Result<Response, UiError> {
    let cache = if file == *NAME {
        "public, max-age=31536000, immutable"
    } else if file == "style.css" {
        "no-cache"
    } else {
        return Err(UiError::Problem(Problem::not_found(
            "there is no such asset",
        )));
    };
    let mut res = STYLESHEET.into_response();
    let h = res.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/css; charset=utf-8"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    Ok(res)
}
