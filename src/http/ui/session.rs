//! Signing in to the pages with a token, sessions, and CSRF (who is
//! reading a page is [`super::viewer`]).
//!
//! * `GET /ui/login` shows the form and sets a short-lived sign-in cookie
//!   whose random value the form repeats in a hidden field (double submit):
//!   a form posted from another site cannot know it.
//! * `POST /ui/login` checks that pair, then the token exactly as the API
//!   does; a wrong, revoked or malformed token gets the form again with the
//!   reason. Any valid token may sign in (a reader's is enough: the pages only
//!   read). Success opens a session ([`crate::domain::session`]) and sets the
//!   session cookie: `HttpOnly`, `SameSite=Strict`, `Path=/ui`, `Secure` when
//!   the public URL is https or a proxy says the request came over TLS, and
//!   no `Max-Age` (it ends with the browser; the server ends the session
//!   itself after `--session-ttl`, and says so).
//! * Every page checks the session: unknown or expired — back to sign-in;
//!   its token revoked (or the configured admin token changed) — ended.
//! * `POST /ui/logout` needs the session's CSRF token; it ends the session.
//!
//! Form posts announced by the browser as cross-site are refused outright.

use axum::extract::{Extension, RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Redirect, Response};
use axum_extra::extract::cookie::{Cookie, CookieJar, SameSite};
use bytes::Bytes;
use maud::html;
use serde::Deserialize;

use super::viewer::{HOME, SESSION_COOKIE, Viewer, cross_site};
use super::{Html, UiError, layout};
use crate::domain::session::{self, same_secret};
use crate::domain::timestamp::Timestamp;
use crate::http::AppState;
use crate::http::auth::{ClientAddr, authenticate};
use crate::http::problem::Problem;

/// The sign-in form's double-submit cookie.
pub const LOGIN_COOKIE: &str = "accelcal_login";
/// How long a sign-in form stays usable, in seconds.
const LOGIN_FORM_SECONDS: i64 = 3600;

/// Whether cookies must be `Secure`: the public URL is https, or a proxy in
/// front says the request came over TLS (`X-Forwarded-Proto: https`).
fn secure(state: &AppState, headers: &HeaderMap) -> bool {
    state
        .web
        .public_url
        .as_deref()
        .is_some_and(|u| u.starts_with("https://"))
        || headers
            .get("x-forwarded-proto")
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| v.eq_ignore_ascii_case("https"))
}

/// A cookie of the pages: `HttpOnly`, `SameSite=Strict`, under `path`;
/// kept `seconds` (none: until the browser closes).
fn cookie(
    name: &'static str,
    value: String,
    path: &'static str,
    seconds: Option<i64>,
    secure: bool,
) -> Cookie<'static> {
    let mut c = Cookie::build((name, value))
        .path(path)
        .http_only(true)
        .same_site(SameSite::Strict)
        .secure(secure)
        .build();
    if let Some(s) = seconds {
        c.set_max_age(time::Duration::seconds(s));
    }
    c
}

/// A path inside the pages to return to; anything else goes home (no open
/// redirect: an absolute or protocol-relative URL is never followed).
pub fn safe_next(next: Option<&str>) -> String {
    next.filter(|n| {
        n.starts_with("/ui/")
            && n.len() <= 1024
            && !n.contains("//")
            && !n.contains('\\')
            && !n.chars().any(char::is_control)
            && !n.starts_with("/ui/login")
            && !n.starts_with("/ui/logout")
    })
    .unwrap_or(HOME)
    .to_owned()
}

#[derive(Debug, Default, Deserialize)]
struct LoginQuery {
    next: Option<String>,
    reason: Option<String>,
}

/// The sign-in form, with a fresh double-submit value and an optional
/// message, answered with `status`.
fn form(
    state: &AppState,
    headers: &HeaderMap,
    next: &str,
    message: Option<(&str, &str)>,
    status: StatusCode,
) -> Result<Response, UiError> {
    let value = session::secret().map_err(|_| Problem::internal())?;
    let jar = CookieJar::new().add(cookie(
        LOGIN_COOKIE,
        value.clone(),
        "/ui/login",
        Some(LOGIN_FORM_SECONDS),
        secure(state, headers),
    ));
    let page = layout(
        "Sign in",
        None,
        html! {
            h1 { "Sign in" }
            p.lead { "Paste an accelcal token. A reader token is enough: these pages only read." }
            @if let Some((class, text)) = message {
                p class={"notice " (class)} role="alert" { (text) }
            }
            form.login method="post" action="/ui/login" {
                input type="hidden" name="csrf" value=(value);
                input type="hidden" name="next" value=(next);
                label for="token" {
                    "Token"
                    input id="token" name="token" type="password" required
                        autocomplete="current-password" spellcheck="false"
                        placeholder="acc_…";
                }
                button type="submit" { "Sign in" }
            }
        },
    );
    Ok((jar, Html::ok(page).with_status(status)).into_response())
}

/// `GET /ui/login`.
pub async fn login_form(
    State(state): State<AppState>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Response, UiError> {
    let q: LoginQuery =
        serde_urlencoded::from_str(query.as_deref().unwrap_or_default()).unwrap_or_default();
    let message = match q.reason.as_deref() {
        Some("expired") => Some(("warning", "Your session has expired. Sign in again.")),
        Some("ended") => Some((
            "warning",
            "Your session has ended: its token was revoked or replaced. Sign in with a valid token.",
        )),
        Some("signed-out") => Some(("", "You have signed out.")),
        _ => None,
    };
    form(
        &state,
        &headers,
        &safe_next(q.next.as_deref()),
        message,
        StatusCode::OK,
    )
}

#[derive(Debug, Default, Deserialize)]
struct LoginForm {
    #[serde(default)]
    token: String,
    #[serde(default)]
    csrf: String,
    #[serde(default)]
    next: Option<String>,
}

/// `POST /ui/login`.
pub async fn login(
    State(state): State<AppState>,
    client: Option<Extension<ClientAddr>>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, UiError> {
    let f: LoginForm = serde_urlencoded::from_bytes(&body).unwrap_or_default();
    let next = safe_next(f.next.as_deref());
    let jar = CookieJar::from_headers(&headers);
    let expected = jar.get(LOGIN_COOKIE).map(|c| c.value().to_owned());
    let forged = cross_site(&headers)
        || f.csrf.is_empty()
        || !expected.is_some_and(|e| same_secret(&e, &f.csrf));
    if forged {
        tracing::warn!("a sign-in form without its CSRF value was refused");
        return form(
            &state,
            &headers,
            &next,
            Some((
                "error",
                "This sign-in form had expired or did not come from this site. Please sign in again.",
            )),
            StatusCode::FORBIDDEN,
        );
    }
    let (principal, credential) =
        match authenticate(&state, f.token.trim(), client.map(|c| c.0)).await {
            Ok(ok) => ok,
            Err(p)
                if matches!(
                    p.status,
                    StatusCode::UNAUTHORIZED | StatusCode::TOO_MANY_REQUESTS
                ) =>
            {
                let why = format!("That token was not accepted: {}.", p.detail);
                return form(&state, &headers, &next, Some(("error", &why)), p.status);
            }
            Err(p) => return Err(p.into()),
        };
    let ttl = state.web.session_ttl.as_secs().max(1) as i64;
    let (record, id) = session::open(principal.id.clone(), credential, Timestamp::now(), ttl)
        .map_err(|_| Problem::internal())?;
    state.store.insert_session(record).await?;
    tracing::info!(principal = %principal.id, role = %principal.role, "signed in to the pages");
    let secure = secure(&state, &headers);
    let jar = CookieJar::new()
        .add(cookie(SESSION_COOKIE, id, "/ui", None, secure))
        .add(cookie(
            LOGIN_COOKIE,
            String::new(),
            "/ui/login",
            Some(0),
            secure,
        ));
    Ok((jar, Redirect::to(&next)).into_response())
}

#[derive(Debug, Default, Deserialize)]
struct LogoutForm {
    #[serde(default)]
    csrf: String,
}

/// `POST /ui/logout`: ends the session (its CSRF token required).
pub async fn logout(
    State(state): State<AppState>,
    headers: HeaderMap,
    viewer: Viewer,
    body: Bytes,
) -> Result<Response, UiError> {
    let f: LogoutForm = serde_urlencoded::from_bytes(&body).unwrap_or_default();
    if cross_site(&headers) || !same_secret(&viewer.csrf, &f.csrf) {
        tracing::warn!(principal = %viewer.principal.id, "a form without the session's CSRF token was refused");
        return Err(UiError::Problem(Problem::forbidden(
            "this form did not carry the session's CSRF token; reload the page and try again",
        )));
    }
    state.store.delete_session(viewer.id_hash).await?;
    tracing::info!(principal = %viewer.principal.id, "signed out of the pages");
    let jar = CookieJar::new().add(cookie(
        SESSION_COOKIE,
        String::new(),
        "/ui",
        Some(0),
        secure(&state, &headers),
    ));
    let mut res = (jar, Redirect::to("/ui/login?reason=signed-out")).into_response();
    res.headers_mut()
        .insert("clear-site-data", HeaderValue::from_static("\"cookies\""));
    Ok(res)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_paths_inside_the_pages_are_returned_to() {
        assert_eq!(
            safe_next(Some("/ui/sensors/ACC-1?from=x")),
            "/ui/sensors/ACC-1?from=x"
        );
        for bad in [
            "https://evil.example/ui/",
            "//evil.example/ui/",
            "/ui//evil.example",
            "/ui/\\evil",
            "/v1/tokens",
            "/ui/login",
            "/ui/logout",
            "/ui/x\n",
        ] {
            assert_eq!(safe_next(Some(bad)), HOME, "{bad:?}");
        }
        assert_eq!(safe_next(None), HOME);
    }
}
