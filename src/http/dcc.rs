//! `POST /v1/dcc/verify`: a Digital Calibration Certificate's signature
//! checked for whoever holds one (issue 46) — the signature, both digests,
//! the schema's structure, who signed it and when. It trusts the
//! certificate the document embeds (the `accelcal dcc verify --cert`
//! command line names a certificate to trust instead).

use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::{HeaderMap, header};

use super::AppState;
use super::auth::require;
use super::problem::Problem;
use crate::domain::auth::{Principal, Role};
use crate::domain::dcc_signature::{Trust, Verification, verify as check};
use crate::domain::field::Invalid;

/// Whether `headers` name an XML body in UTF-8.
fn xml(headers: &HeaderMap) -> Result<(), Problem> {
    let value = headers
        .get(header::CONTENT_TYPE)
        .ok_or_else(|| {
            Problem::unsupported_media("a Content-Type header is required (application/xml)")
        })?
        .to_str()
        .map_err(|_| Problem::unsupported_media("the Content-Type header is not ASCII"))?;
    let mut parts = value.split(';').map(str::trim);
    let essence = parts.next().unwrap_or_default().to_ascii_lowercase();
    let params_ok = parts.filter(|p| !p.is_empty()).all(|p| {
        p.split_once('=').is_some_and(|(n, v)| {
            n.trim().eq_ignore_ascii_case("charset")
                && v.trim().trim_matches('"').eq_ignore_ascii_case("utf-8")
        })
    });
    if matches!(essence.as_str(), "application/xml" | "text/xml") && params_ok {
        Ok(())
    } else {
        Err(Problem::unsupported_media(format!(
            "Content-Type `{}` is not accepted; send the DCC as application/xml (UTF-8)",
            crate::domain::text::echo(value)
        )))
    }
}

/// `POST /v1/dcc/verify`: whether an uploaded DCC's signature holds.
#[utoipa::path(
    post,
    path = "/v1/dcc/verify",
    tag = "calibrations",
    operation_id = "verifyDcc",
    summary = "Check a Digital Calibration Certificate's signature.",
    description = "The uploaded DCC (application/xml, UTF-8) is checked as a receiver would: \
        its structure (a DCC root; one ds:Signature, the root's last child, referencing the \
        whole document), the signature value and both digests (the document, and the XAdES \
        signed properties), and that the signed properties name the certificate that \
        verified, with a signing time within its validity. The signer is trusted by the \
        certificate the document embeds: the answer says who signed it and when, and the \
        reader decides whether that is the laboratory they expect (`accelcal dcc verify \
        --cert` trusts a named certificate only). A signature that does not hold is an \
        answer (`valid: false` and the reason), not an error; a body that is not a DCC at \
        all is refused (422).",
    request_body(content((String = "application/xml"))),
    responses(
        (status = 200, description = "The verdict, the signer and the signing time.", body = Verification),
        (status = 403, response = super::openapi::Forbidden),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn verify(
    State(_): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Json<Verification>, Problem> {
    require(&principal, Role::Reader)?;
    xml(&headers)?;
    let text = std::str::from_utf8(&body).map_err(|e| {
        Problem::validation(Invalid::one("", format!("the body is not UTF-8: {e}")))
    })?;
    // Parsing and checking a signature is CPU work of milliseconds: off
    // the runtime's threads.
    let text = text.to_owned();
    let verdict = tokio::task::spawn_blocking(move || check(&text, &Trust::Embedded))
        .await
        .map_err(|_| Problem::internal())?;
    verdict
        .map(Json)
        .map_err(|e| Problem::validation(Invalid::one("", format!("the body is not a DCC: {e}"))))
}
