//! The web pages under `/ui/`: server-rendered HTML (maud), charts drawn as
//! inline SVG on the server, one embedded stylesheet — no CDN, nothing
//! fetched from elsewhere; the pages work offline and under a
//! Content-Security-Policy that allows only this origin's stylesheet and
//! script. The one script (`live.js`) keeps the fleet and a sensor's page
//! current from the event stream ([`live`]); every page reads the same
//! without it.
//!
//! * [`session`]: sign-in with a token, session cookies, CSRF;
//! * [`fleet`], [`sensor`], [`calibration`]: the pages; [`live`]: their
//!   event stream;
//! * [`certificate`]: the printable certificate (also `GET
//!   /v1/calibrations/{id}/certificate`); [`dcc`]: the same as a Digital
//!   Calibration Certificate (XML);
//! * [`plot`]: the charts; [`format`](mod@format): how numbers read; [`result`]: stored
//!   result documents read back; [`assets`]: the stylesheet.
//!
//! The pages are read-only views over the same store the API serves; every
//! number they show is the stored result's, and every chart has a table of
//! the same numbers beside it.

pub mod assets;
pub mod axis;
pub mod calibration;
pub mod certificate;
pub mod coverage;
pub mod dcc;
pub mod document;
pub mod fleet;
pub mod format;
pub mod issue;
pub mod kinds;
pub mod live;
pub mod plot;
pub mod result;
pub mod review;
pub mod sensor;
pub mod session;
pub mod sign;
pub mod stored;
pub mod thermal_result;
pub mod triad_result;
pub mod viewer;
pub mod xml;

use axum::Router;
use axum::http::{HeaderName, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use maud::{DOCTYPE, Markup, html};

use super::AppState;
use super::problem::Problem;
use viewer::Viewer;

/// The Content-Security-Policy of every page: this origin's stylesheet and
/// script (no inline script), requests only to this origin (the script's
/// event stream and page fetches), and nothing else — no frame, forms
/// posting only here.
pub const PAGE_CSP: &str = "default-src 'none'; style-src 'self'; script-src 'self'; \
     connect-src 'self'; img-src 'self'; form-action 'self'; frame-ancestors 'none'; \
     base-uri 'none'";

/// The pages' routes (nested under `/ui`).
pub fn router() -> Router<AppState> {
    Router::new()
        .route("/", get(|| async { Redirect::to("/ui/sensors") }))
        .route("/login", get(session::login_form).post(session::login))
        .route("/logout", post(session::logout))
        .route("/sensors", get(fleet::page))
        .route("/events", get(live::stream))
        .route("/sensors/{sensor_id}", get(sensor::page))
        .route("/calibrations/{id}", get(calibration::page))
        .route(
            "/calibrations/{id}/submission",
            get(calibration::submission),
        )
        .route(
            "/calibrations/{id}/certificate",
            get(calibration::certificate),
        )
        .route("/calibrations/{id}/certificate.xml", get(calibration::dcc))
        .route("/calibrations/{id}/review", post(sign::sign))
        .route(
            "/calibrations/{id}/export/{format}",
            get(calibration::export),
        )
        .route("/assets/{file}", get(assets::serve))
        .fallback(not_found)
}

/// An HTML page with its status and extra headers (cookies).
pub struct Html {
    /// Status.
    pub status: StatusCode,
    /// The whole document.
    pub markup: Markup,
    /// Extra headers.
    pub headers: Vec<(HeaderName, HeaderValue)>,
}

impl Html {
    /// A 200 page.
    pub fn ok(markup: Markup) -> Self {
        Html {
            status: StatusCode::OK,
            markup,
            headers: Vec::new(),
        }
    }

    /// With another status.
    pub fn with_status(mut self, status: StatusCode) -> Self {
        self.status = status;
        self
    }
}

impl IntoResponse for Html {
    fn into_response(self) -> Response {
        let mut res = (self.status, self.markup.into_string()).into_response();
        let h = res.headers_mut();
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/html; charset=utf-8"),
        );
        h.insert(
            header::CONTENT_SECURITY_POLICY,
            HeaderValue::from_static(PAGE_CSP),
        );
        for (name, value) in self.headers {
            h.append(name, value);
        }
        res
    }
}

/// Why a page could not be shown.
#[derive(Debug)]
pub enum UiError {
    /// Not signed in (or the session ended): to the sign-in page, then back.
    SignIn {
        /// The page asked for.
        next: String,
        /// Why: `expired`, `ended` or none.
        reason: Option<&'static str>,
    },
    /// A problem, shown as a page.
    Problem(Problem),
}

impl From<Problem> for UiError {
    fn from(p: Problem) -> Self {
        UiError::Problem(p)
    }
}

impl From<crate::store::StoreError> for UiError {
    fn from(e: crate::store::StoreError) -> Self {
        UiError::Problem(e.into())
    }
}

impl IntoResponse for UiError {
    fn into_response(self) -> Response {
        match self {
            UiError::SignIn { next, reason } => {
                let mut to = format!(
                    "/ui/login?next={}",
                    form_urlencoded::byte_serialize(next.as_bytes()).collect::<String>()
                );
                if let Some(r) = reason {
                    to.push_str("&reason=");
                    to.push_str(r);
                }
                Redirect::to(&to).into_response()
            }
            UiError::Problem(p) => {
                let mut res = Html::ok(layout(
                    p.kind.title(),
                    None,
                    html! {
                        h1 { (p.kind.title()) }
                        p.notice.error { (p.detail) }
                        p { a href="/ui/sensors" { "Back to the fleet" } }
                    },
                ))
                .with_status(p.status)
                .into_response();
                if let Some(s) = p.retry_after {
                    res.headers_mut()
                        .insert(header::RETRY_AFTER, HeaderValue::from(s));
                }
                res
            }
        }
    }
}

/// An unknown page.
async fn not_found() -> UiError {
    UiError::Problem(Problem::not_found("there is no such page"))
}

/// The frame of every page: header with navigation and the signed-in
/// principal (with its sign-out form), the content, a footer.
pub fn layout(title: &str, viewer: Option<&Viewer>, content: Markup) -> Markup {
    frame(title, viewer, None, content)
}

/// [`layout`] for a page kept current from the event stream ([`live`]) of
/// `sensor_id`, or of every sensor: the script, the stream's URL on
/// `<main>`, and a status line that says when the page was last updated.
pub fn live_layout(
    title: &str,
    viewer: &Viewer,
    sensor_id: Option<&str>,
    content: Markup,
) -> Markup {
    let stream = match sensor_id {
        Some(id) => format!(
            "/ui/events?sensor_id={}",
            form_urlencoded::byte_serialize(id.as_bytes()).collect::<String>()
        ),
        None => "/ui/events".to_owned(),
    };
    frame(title, Some(viewer), Some(&stream), content)
}

fn frame(title: &str, viewer: Option<&Viewer>, live: Option<&str>, content: Markup) -> Markup {
    html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                meta name="viewport" content="width=device-width, initial-scale=1";
                meta name="color-scheme" content="light dark";
                title { (title) " · accelcal" }
                link rel="stylesheet" href=(assets::stylesheet_path());
                @if live.is_some() {
                    script src=(assets::script_path()) defer {}
                }
            }
            body {
                a.skip href="#content" { "Skip to content" }
                header.site {
                    div.bar {
                        a.brand href="/ui/sensors" { "accelcal" }
                        @if viewer.is_some() {
                            nav aria-label="Main" {
                                a href="/ui/sensors" { "Fleet" }
                            }
                        }
                        @if let Some(v) = viewer {
                            div.who {
                                span {
                                    "Signed in as "
                                    @if let Some(h) = &v.principal.holder { (h) ", " }
                                    (v.principal.role) " " code { (short_id(&v.principal.id)) }
                                }
                                form.inline method="post" action="/ui/logout" {
                                    input type="hidden" name="csrf" value=(v.csrf);
                                    button.link type="submit" { "Sign out" }
                                }
                            }
                        }
                    }
                }
                main id="content" data-live=[live] { (content) }
                @if live.is_some() {
                    p #live-status .muted role="status" aria-live="polite" {}
                }
                footer.site {
                    "accelcal " (env!("CARGO_PKG_VERSION"))
                    " · identification of the accelerometer's static model by data fusion (Pei & Wang, 2005)"
                }
            }
        }
    }
}

/// How a principal is named on the pages: the configured admin token by
/// name, a stored token by the first eight characters of its id.
pub fn short_id(id: &str) -> &str {
    if id == crate::domain::auth::ENV_ADMIN {
        "(configured admin token)"
    } else {
        id.get(..8).unwrap_or(id)
    }
}

/// A verdict or status badge.
pub fn badge(class: &str, text: &str) -> Markup {
    html! { span class={"badge " (class)} { (text) } }
}
