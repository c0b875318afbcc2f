//! Issued certificates (issue 42 item 3): a certificate is issued with its
//! approval — rendered in the approval's transaction with the signatures
//! it leaves, the laboratory, customer and item as they are then, and
//! stored (`crate::store::issued`) — and every later request for it answers
//! what was issued: the DCC byte for byte, the HTML as issued (with, when the
//! calibration was withdrawn, superseded or held since, that notice put
//! before it). Changing what an issued certificate says is an amendment: the
//! next revision of the same certificate number, with the current facts and
//! its reason; every revision stays retrievable (`?revision=N`).
//!
//! A calibration that is not approved has no issued certificate: its
//! certificate is rendered on request, as a draft that carries no approval.
//! One approved before certificates were issued at approval is issued at
//! its first request.

use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};

use sha2::{Digest, Sha256};

use super::certificate::{Amendment, Context, DccFile, context};
use super::stored::{StoredDoc, load_stored};
use crate::app::review::Issuing;
use crate::domain::audit::Actor;
use crate::domain::dcc_signature::Signer;
use crate::domain::review::{Act, Action, Signature, State};
use crate::domain::timestamp::Timestamp;
use crate::http::problem::{Kind, Problem};
use crate::http::{AppState, path_id};
use crate::store::{IssuedCertificate, Render, Rendered};
use uuid::Uuid;

/// What a certificate is rendered from, read now: the stored result and
/// everything beside it.
pub struct Draft {
    doc: StoredDoc,
    ctx: Context,
    signer: Option<std::sync::Arc<Signer>>,
}

/// The certificate `act` issues on calibration `id`, when it is an
/// approval and a certificate can be rendered now (read before the act,
/// rendered in its transaction); none otherwise — an approval then issues
/// its certificate at the certificate's first request.
pub async fn issuing(
    state: &AppState,
    headers: &HeaderMap,
    id: Uuid,
    act: &Act,
) -> Option<Issuing> {
    if act.action != Action::Approve {
        return None;
    }
    match draft(state, headers, &id.to_string()).await {
        Ok(draft) => Some(Box::new(move |at| draft.issuing_at(at))),
        // No certificate can be rendered (an unknown calibration, or a
        // stored result that does not read back): the act is judged as
        // any other.
        Err(p) => {
            tracing::warn!(calibration = %id, problem = %p.detail, "an approval issues no certificate now");
            None
        }
    }
}

/// Reads what calibration `raw_id`'s certificate is rendered from.
pub async fn draft(state: &AppState, headers: &HeaderMap, raw_id: &str) -> Result<Draft, Problem> {
    let doc = load_stored(state, raw_id).await?;
    let sensor = doc.sensor_id().to_owned();
    let ctx = context(state, headers, raw_id, &sensor).await?;
    Ok(Draft {
        doc,
        ctx,
        signer: state.web.dcc_signer.clone(),
    })
}

impl Draft {
    /// Its DCC, signed at its issue time when a signer is configured (or
    /// why none: the records lack what it needs, or signing failed), then
    /// its HTML, which names the DCC's SHA-256 and signer.
    fn render(mut self) -> Rendered {
        // The document is built once more for the DCC only when one is
        // issued (a draft builds it once).
        let dcc = super::dcc::issuable(&self.ctx)
            .map(|()| super::dcc::render(&super::kinds::document(&self.doc, &self.ctx), &self.ctx))
            .map_err(|p| p.detail);
        let dcc = match (&self.signer, dcc) {
            (Some(signer), Ok(xml)) => signer.sign(&xml, self.ctx.issued).map_err(|e| {
                tracing::error!(error = %e, "a DCC could not be signed: issued without one");
                format!("the DCC could not be signed ({e}); amend the certificate to issue it")
            }),
            (_, dcc) => dcc,
        };
        self.ctx.dcc = dcc.as_ref().ok().map(|xml| DccFile {
            sha256: hex::encode(Sha256::digest(xml.as_bytes())),
            signed_by: self.signer.as_ref().map(|s| {
                let c = s.certificate();
                (c.subject.clone(), c.sha256.clone())
            }),
        });
        let doc = super::kinds::document(&self.doc, &self.ctx);
        let html = super::certificate::render(&doc, &self.ctx).into_string();
        Rendered { html, dcc }
    }

    /// The renderer an approval at `at` issues with: the signatures and
    /// state the approval leaves, issued then.
    pub fn issuing_at(self, at: Timestamp) -> Render {
        Box::new(move |signatures: &[Signature], state: State| {
            let mut d = self;
            d.ctx.signatures = signatures.to_vec();
            d.ctx.state = state;
            d.ctx.issued = at;
            d.render()
        })
    }

    /// Its certificate as issued now by `by`: revision `revision`, an
    /// amendment with `reason` past the first.
    fn issue(mut self, revision: u32, reason: Option<String>, by: Actor) -> IssuedCertificate {
        let at = Timestamp::now();
        self.ctx.issued = at;
        self.ctx.amendment = reason.clone().map(|reason| Amendment {
            number: revision - 1,
            reason,
        });
        let id = self.id();
        IssuedCertificate::new(id, revision, at, by, reason, self.render())
    }

    fn id(&self) -> uuid::Uuid {
        self.doc.id()
    }
}

/// The `?revision=` of a certificate request, if any.
pub fn revision(query: Option<&str>) -> Result<Option<u32>, Problem> {
    let Some(q) = query else { return Ok(None) };
    let mut found = None;
    for (k, v) in form_urlencoded::parse(q.as_bytes()) {
        match k.as_ref() {
            "revision" if found.is_none() => {
                found = Some(v.parse::<u32>().ok().filter(|n| *n >= 1).ok_or_else(|| {
                    Problem::bad_parameter("revision", "must be a whole number from 1")
                })?);
            }
            "revision" => return Err(Problem::bad_parameter("revision", "is given twice")),
            other => {
                return Err(Problem::bad_parameter(
                    other,
                    "is not a parameter of a certificate (revision)",
                ));
            }
        }
    }
    Ok(found)
}

/// The issued revision of calibration `raw_id` asked for (its latest when
/// `revision` is none), issuing revision 1 of an approved calibration that
/// has none yet; none for a calibration not approved.
async fn issued(
    state: &AppState,
    headers: &HeaderMap,
    raw_id: &str,
    revision: Option<u32>,
) -> Result<Option<IssuedCertificate>, Problem> {
    let id = path_id(raw_id, "calibration")?;
    if let Some(c) = state.store.certificate(id, revision).await? {
        return Ok(Some(c));
    }
    if let Some(n) = revision {
        return Err(Problem::not_found(format!(
            "certificate No. {id} has no revision {n}"
        )));
    }
    let draft = draft(state, headers, raw_id).await?;
    if draft.ctx.state != State::Approved {
        return Ok(None);
    }
    // Approved before certificates were issued at approval: issued now,
    // once (a concurrent request's revision 1 wins, and is the one served).
    let c = draft.issue(1, None, Actor::service());
    if !state.store.issue_certificate(c.clone()).await? {
        return Ok(state.store.certificate(id, Some(1)).await?);
    }
    tracing::info!(calibration_id = %id, "certificate issued at its first request");
    Ok(Some(c))
}

/// The frozen HTML of `c`, with the notice of what became of the
/// calibration since, when it was withdrawn, superseded or held after it
/// was issued: put into the running header, after the number, so that every
/// printed page says so, as a withdrawn draft's does (the document itself
/// stays as issued).
fn served_html(c: &IssuedCertificate, now: State, signatures: &[Signature]) -> String {
    let Some(notice) = super::review::notice(now, signatures) else {
        return c.html.clone();
    };
    let banner = maud::html! {
        div.cert-withdrawn role="status" data-added="after issue" { (notice) }
    }
    .into_string();
    let running = "<div class=\"cert-running\">";
    let at = c
        .html
        .find(running)
        .and_then(|start| c.html[start..].find("</div>").map(|end| start + end + 6))
        .unwrap_or(0);
    let mut out = String::with_capacity(c.html.len() + banner.len());
    out.push_str(&c.html[..at]);
    out.push_str(&banner);
    out.push_str(&c.html[at..]);
    out
}

/// The certificate of calibration `raw_id` as a response: the DCC when
/// `xml`, the HTML otherwise; what was issued (revision `revision`, else
/// the latest), or for a calibration not approved a draft rendered now
/// (its DCC refused).
pub async fn respond(
    state: &AppState,
    headers: &HeaderMap,
    raw_id: &str,
    revision: Option<u32>,
    xml: bool,
) -> Result<Response, Problem> {
    let Some(c) = issued(state, headers, raw_id, revision).await? else {
        let d = draft(state, headers, raw_id).await?;
        if xml {
            super::dcc::issuable(&d.ctx)?;
        }
        let html = d.render().html;
        return Ok(document(html, false, None));
    };
    if xml {
        let Some(dcc) = c.dcc else {
            return Err(Problem::new(
                Kind::Incomplete,
                format!(
                    "certificate No. {} (revision {}) was issued without a Digital Calibration \
                     Certificate: {}; complete the records, then amend it \
                     (POST /v1/calibrations/{}/amend) to issue one",
                    c.calibration_id,
                    c.revision,
                    c.dcc_missing
                        .as_deref()
                        .unwrap_or("the records were incomplete"),
                    c.calibration_id
                ),
            ));
        };
        return Ok(document(dcc, true, Some((&c.calibration_id, c.revision))));
    }
    let (now, signatures) = super::stored::record(state, raw_id).await?;
    let html = served_html(&c, now, &signatures);
    Ok(document(html, false, Some((&c.calibration_id, c.revision))))
}

/// A certificate document as a response, with its revision when issued.
fn document(body: String, xml: bool, issued: Option<(&uuid::Uuid, u32)>) -> Response {
    let mut res = body.into_response();
    let h = res.headers_mut();
    if xml {
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/xml; charset=utf-8"),
        );
    } else {
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/html; charset=utf-8"),
        );
        if let Ok(v) = HeaderValue::from_str(&super::certificate::CSP) {
            h.insert(header::CONTENT_SECURITY_POLICY, v);
        }
    }
    let revision = match issued {
        Some((id, n)) => {
            // Named as the DCC identifies itself: the number, and `-A1` for
            // the first amendment.
            let name = match n {
                1 => format!("dcc-{id}.xml"),
                n => format!("dcc-{id}-A{}.xml", n - 1),
            };
            if xml && let Ok(v) = HeaderValue::from_str(&format!("inline; filename=\"{name}\"")) {
                h.insert(header::CONTENT_DISPOSITION, v);
            }
            n.to_string()
        }
        None => "draft".to_owned(),
    };
    if let Ok(v) = HeaderValue::from_str(&revision) {
        h.insert("certificate-revision", v);
    }
    res
}

/// Amends calibration `raw_id`'s issued certificate for `reason`, by `by`:
/// its next revision, rendered with today's facts. 409 when it has none
/// issued or is not approved.
pub async fn amend(
    state: &AppState,
    headers: &HeaderMap,
    raw_id: &str,
    reason: String,
    by: Actor,
) -> Result<IssuedCertificate, Problem> {
    let id = path_id(raw_id, "calibration")?;
    let Some(latest) = issued(state, headers, raw_id, None).await? else {
        let (now, _) = super::stored::record(state, raw_id).await?;
        return Err(Problem::new(
            Kind::StateConflict,
            format!(
                "the calibration is {}: only an approved calibration's issued certificate is \
                 amended (approve it, and its certificate is issued)",
                now.as_str()
            ),
        ));
    };
    let d = draft(state, headers, raw_id).await?;
    if d.ctx.state != State::Approved {
        return Err(Problem::new(
            Kind::StateConflict,
            format!(
                "the calibration is {}: its certificate is not amended (a withdrawn or \
                 superseded calibration's certificate stays as issued, with the notice)",
                d.ctx.state.as_str()
            ),
        ));
    }
    let c = d.issue(latest.revision + 1, Some(reason), by);
    if !state.store.issue_certificate(c.clone()).await? {
        return Err(Problem::new(
            Kind::StateConflict,
            format!(
                "certificate No. {id} was amended meanwhile (revision {} is no longer the \
                 latest); read it again, then amend it",
                latest.revision
            ),
        ));
    }
    Ok(c)
}
