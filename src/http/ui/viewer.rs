//! Who is reading a page: the [`Viewer`] every page takes, found from the
//! session cookie (back to sign-in when there is none, it expired, or its
//! token was revoked), and the refusal of a form post the browser
//! announces as cross-site. Signing in and out is [`super::session`].

use axum::extract::{FromRequestParts, OriginalUri};
use axum::http::HeaderMap;
use axum::http::request::Parts;
use axum_extra::extract::cookie::CookieJar;

use super::UiError;
use crate::domain::auth::{self, Principal};
use crate::domain::timestamp::Timestamp;
use crate::http::AppState;
use crate::http::auth::still_valid;

/// The session cookie.
pub const SESSION_COOKIE: &str = "accelcal_session";
/// Where to go after signing in when nowhere (or nowhere safe) was asked.
pub const HOME: &str = "/ui/sensors";

/// The signed-in principal of a page request.
#[derive(Debug, Clone)]
pub struct Viewer {
    /// Who.
    pub principal: Principal,
    /// The session's CSRF token, for its forms.
    pub csrf: String,
    pub(super) id_hash: [u8; 32],
}

impl FromRequestParts<AppState> for Viewer {
    type Rejection = UiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, UiError> {
        // Inside `/ui` the router sees the path without its prefix; the
        // original URI is the page to come back to.
        let uri = parts
            .extensions
            .get::<OriginalUri>()
            .map_or(&parts.uri, |o| &o.0);
        let next = uri
            .path_and_query()
            .map_or(HOME.to_owned(), |p| p.as_str().to_owned());
        let sign_in = |reason| UiError::SignIn {
            next: next.clone(),
            reason,
        };
        let jar = CookieJar::from_headers(&parts.headers);
        let Some(cookie) = jar.get(SESSION_COOKIE) else {
            return Err(sign_in(None));
        };
        let id_hash = auth::hash(cookie.value());
        let Some(s) = state.store.session(id_hash).await? else {
            return Err(sign_in(Some("expired")));
        };
        if s.expires_at <= Timestamp::now() {
            state.store.delete_session(id_hash).await?;
            return Err(sign_in(Some("expired")));
        }
        let Some(principal) = still_valid(state, &s.principal, &s.credential_hash).await? else {
            state.store.delete_session(id_hash).await?;
            return Err(sign_in(Some("ended")));
        };
        Ok(Viewer {
            principal,
            csrf: s.csrf,
            id_hash,
        })
    }
}

/// Refuses a form post the browser says came from another site.
pub fn cross_site(headers: &HeaderMap) -> bool {
    headers
        .get("sec-fetch-site")
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.eq_ignore_ascii_case("cross-site"))
}
