//! Request bodies, already received whole by the admission layer
//! ([`super::stack::admit`]): their media type, and typed readings.

use axum::extract::{FromRequest, Request};
use axum::http::header;
use serde::de::DeserializeOwned;

use super::AppState;
use super::problem::Problem;
use crate::domain::submission::Media;
use crate::domain::typed;

/// A request body with its media type: the application layer's
/// [`Upload`](crate::app::Upload), read from the request (its typed readings below).
pub use crate::app::Upload as Body;

/// The media type named by a `Content-Type` value (UTF-8 only).
fn media(content_type: &str) -> Result<Media, Problem> {
    let mut parts = content_type.split(';').map(str::trim);
    let essence = parts.next().unwrap_or_default().to_ascii_lowercase();
    for param in parts.filter(|p| !p.is_empty()) {
        let (name, value) = param.split_once('=').unwrap_or((param, ""));
        let value = value.trim_matches('"');
        if !(name.eq_ignore_ascii_case("charset") && value.eq_ignore_ascii_case("utf-8")) {
            return Err(Problem::unsupported_media(format!(
                "unsupported media type parameter `{}`; bodies are UTF-8",
                crate::domain::text::echo(param)
            )));
        }
    }
    match essence.as_str() {
        "application/json" => Ok(Media::Json),
        "text/csv" => Ok(Media::Csv),
        _ => Err(Problem::unsupported_media(format!(
            "Content-Type `{}` is not accepted; send application/json (or text/csv for submissions)",
            crate::domain::text::echo(content_type)
        ))),
    }
}

impl FromRequest<AppState> for Body {
    type Rejection = Problem;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Problem> {
        let content_type = req
            .headers()
            .get(header::CONTENT_TYPE)
            .ok_or_else(|| {
                Problem::unsupported_media("a Content-Type header is required (application/json)")
            })?
            .to_str()
            .map_err(|_| Problem::unsupported_media("the Content-Type header is not ASCII"))?
            .to_owned();
        let media = media(&content_type)?;
        // The admission layer received the body whole, within the limits;
        // here it is only taken out (no second limit).
        let _ = state;
        let bytes = axum::body::to_bytes(req.into_body(), usize::MAX)
            .await
            .map_err(|_| Problem::bad_request("the body could not be read"))?;
        Ok(Body {
            media,
            bytes,
            content_type,
        })
    }
}

impl Body {
    /// The body as a JSON value of type `T` (refusing CSV with 415).
    pub fn json<T: DeserializeOwned>(&self) -> Result<T, Problem> {
        if self.media != Media::Json {
            return Err(Problem::unsupported_media(
                "this operation accepts application/json only",
            ));
        }
        Ok(typed::from_json(&self.bytes)?)
    }
}
