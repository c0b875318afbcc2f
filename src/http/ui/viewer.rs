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
use crate::http::problem::Problem;

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

/// Why a request has no [`Viewer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Absent {
    /// No session cookie.
    NoCookie,
    /// The cookie names no session (signed out, or ended before).
    Unknown,
    /// This session is past its expiry.
    Expired([u8; 32]),
    /// This session's token was revoked (or its holder's role changed).
    Ended([u8; 32]),
}

impl Absent {
    /// The sign-in form's `reason`.
    fn reason(self) -> Option<&'static str> {
        match self {
            Absent::NoCookie => None,
            Absent::Unknown | Absent::Expired(_) => Some("expired"),
            Absent::Ended(_) => Some("ended"),
        }
    }

    /// The dead session to delete, by its hash.
    fn dead(self) -> Option<[u8; 32]> {
        match self {
            Absent::Expired(h) | Absent::Ended(h) => Some(h),
            Absent::NoCookie | Absent::Unknown => None,
        }
    }
}

/// The viewer of a request with these headers, or why there is none,
/// changing nothing: the pages' event stream asks this, and leaves a dead
/// session for the page that next asks to end, with its reason.
pub async fn look(
    headers: &HeaderMap,
    state: &AppState,
) -> Result<Result<Viewer, Absent>, Problem> {
    let jar = CookieJar::from_headers(headers);
    let Some(cookie) = jar.get(SESSION_COOKIE) else {
        return Ok(Err(Absent::NoCookie));
    };
    let id_hash = auth::hash(cookie.value());
    let Some(s) = state.store.session(id_hash).await? else {
        return Ok(Err(Absent::Unknown));
    };
    if s.expires_at <= Timestamp::now() {
        return Ok(Err(Absent::Expired(id_hash)));
    }
    let Some(principal) = still_valid(state, &s.principal, &s.credential_hash).await? else {
        return Ok(Err(Absent::Ended(id_hash)));
    };
    Ok(Ok(Viewer {
        principal,
        csrf: s.csrf,
        id_hash,
    }))
}

impl FromRequestParts<AppState> for Viewer {
    type Rejection = UiError;

    /// [`look`], then a dead session is deleted and the page is the
    /// sign-in form, saying why, and back.
    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, UiError> {
        let absent = match look(&parts.headers, state).await? {
            Ok(viewer) => return Ok(viewer),
            Err(absent) => absent,
        };
        if let Some(id_hash) = absent.dead() {
            state.store.delete_session(id_hash).await?;
        }
        // Inside `/ui` the router sees the path without its prefix; the
        // original URI is the page to come back to.
        let uri = parts
            .extensions
            .get::<OriginalUri>()
            .map_or(&parts.uri, |o| &o.0);
        Err(UiError::SignIn {
            next: uri
                .path_and_query()
                .map_or(HOME.to_owned(), |p| p.as_str().to_owned()),
            reason: absent.reason(),
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
