//! [`Json`]: the answers' JSON bodies, serialized into one growing buffer.
//!
//! It stands in for `axum::Json` as a response. axum's writes each token
//! of the serialization into a `BytesMut` through `std::io::Write`, a
//! reservation check per token; this writes into a `Vec` and hands it to
//! the body without a copy. On the history route (twenty calibrations) that
//! saved an eighth of the request's instructions (BENCHMARKS.md,
//! "Observed as deployed"). A value that cannot be serialized (none
//! of ours can fail) is a 500 problem, not axum's plain-text 500.

use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use super::problem::Problem;

/// A JSON answer (`application/json`).
#[derive(Clone, Copy, Debug)]
pub struct Json<T>(pub T);

/// The `Content-Type` of every JSON answer.
pub(crate) static APPLICATION_JSON: HeaderValue = HeaderValue::from_static("application/json");

impl<T: Serialize> IntoResponse for Json<T> {
    fn into_response(self) -> Response {
        match serde_json::to_vec(&self.0) {
            Ok(body) => ([(header::CONTENT_TYPE, APPLICATION_JSON.clone())], body).into_response(),
            Err(e) => {
                tracing::error!(error = %e, "an answer could not be serialized");
                Problem::internal().into_response()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn the_body_is_the_values_json_with_its_media_type() {
        let value = serde_json::json!({"a": [1, 2.5, "x\"y"], "b": null});
        let res = Json(&value).into_response();
        assert_eq!(res.status(), 200);
        assert_eq!(res.headers()[header::CONTENT_TYPE], "application/json");
        let body = axum::body::to_bytes(res.into_body(), usize::MAX)
            .await
            .unwrap();
        assert_eq!(
            serde_json::from_slice::<serde_json::Value>(&body).unwrap(),
            value
        );
    }

    /// A map with keys that are not strings cannot be JSON: a problem.
    #[tokio::test]
    async fn what_cannot_be_serialized_is_a_problem() {
        let value: std::collections::HashMap<(u8, u8), u8> = [((1, 2), 3)].into();
        let res = Json(value).into_response();
        assert_eq!(res.status(), 500);
        assert_eq!(
            res.headers()[header::CONTENT_TYPE],
            "application/problem+json"
        );
    }
}
