//! Issued certificates (issue 42 item 3): what a certificate said when it
//! was issued, kept as it was rendered — the printable HTML and the Digital
//! Calibration Certificate — revision by revision. Revision 1 is issued
//! with the approval, in its transaction; each amendment is the next
//! revision, with its reason. A stored revision never changes; the audit
//! trail records each one's SHA-256.

use sha2::{Digest, Sha256};
use uuid::Uuid;

use crate::domain::audit::Actor;
use crate::domain::review::{Signature, State};
use crate::domain::timestamp::Timestamp;

/// What rendering a certificate gave: the HTML, and the Digital Calibration
/// Certificate or why the records allow none (the `incomplete-record`
/// detail).
#[derive(Clone, Debug, PartialEq)]
pub struct Rendered {
    /// The printable HTML.
    pub html: String,
    /// The DCC, or why none could be issued.
    pub dcc: Result<String, String>,
}

/// Renders a certificate given the calibration's signatures (the one being
/// recorded included) and the state they leave: called by the store inside
/// the transaction that records an approval, so that what is issued names
/// the very signature the transaction stores.
pub type Render = Box<dyn FnOnce(&[Signature], State) -> Rendered + Send>;

/// One revision of an issued certificate.
#[derive(Clone, Debug, PartialEq)]
pub struct IssuedCertificate {
    /// The calibration (the certificate's number).
    pub calibration_id: Uuid,
    /// 1 for the certificate as issued, then one more per amendment.
    pub revision: u32,
    /// When it was issued.
    pub issued_at: Timestamp,
    /// Who issued it: the approving reviewer, or the one who amended it.
    pub issued_by: Actor,
    /// Why it was amended (none for revision 1).
    pub reason: Option<String>,
    /// The printable HTML, as issued.
    pub html: String,
    /// The DCC, as issued; none when the records lacked what it needs.
    pub dcc: Option<String>,
    /// Why there is no DCC.
    pub dcc_missing: Option<String>,
    /// The HTML's SHA-256, hex.
    pub html_sha256: String,
    /// The DCC's SHA-256, hex.
    pub dcc_sha256: Option<String>,
}

fn sha256(text: &str) -> String {
    hex::encode(Sha256::digest(text.as_bytes()))
}

impl IssuedCertificate {
    /// Revision `revision` of calibration `id`'s certificate as `rendered`,
    /// issued at `at` by `by`, for `reason` (amendments).
    pub fn new(
        id: Uuid,
        revision: u32,
        at: Timestamp,
        by: Actor,
        reason: Option<String>,
        rendered: Rendered,
    ) -> Self {
        let (dcc, dcc_missing) = match rendered.dcc {
            Ok(x) => (Some(x), None),
            Err(why) => (None, Some(why)),
        };
        IssuedCertificate {
            calibration_id: id,
            revision,
            issued_at: at,
            issued_by: by,
            reason,
            html_sha256: sha256(&rendered.html),
            dcc_sha256: dcc.as_deref().map(sha256),
            html: rendered.html,
            dcc,
            dcc_missing,
        }
    }

    /// Whether its documents still have the digests recorded with it.
    pub fn intact(&self) -> bool {
        sha256(&self.html) == self.html_sha256 && self.dcc.as_deref().map(sha256) == self.dcc_sha256
    }
}

/// A revision without its documents.
#[derive(Clone, Debug, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct Revision {
    /// Its number.
    pub revision: u32,
    /// When it was issued.
    pub issued_at: Timestamp,
    /// Who issued it.
    pub issued_by: Actor,
    /// Why (amendments).
    pub reason: Option<String>,
    /// The HTML's SHA-256, hex.
    pub html_sha256: String,
    /// The DCC's SHA-256, hex; null when issued without one.
    pub dcc_sha256: Option<String>,
}

impl From<&IssuedCertificate> for Revision {
    fn from(c: &IssuedCertificate) -> Self {
        Revision {
            revision: c.revision,
            issued_at: c.issued_at,
            issued_by: c.issued_by.clone(),
            reason: c.reason.clone(),
            html_sha256: c.html_sha256.clone(),
            dcc_sha256: c.dcc_sha256.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_revision_carries_the_digests_of_its_documents() {
        let c = IssuedCertificate::new(
            Uuid::from_u128(1),
            1,
            Timestamp::parse("2026-11-27T00:00:00Z").unwrap(),
            Actor::service(),
            None,
            Rendered {
                html: "<p>x</p>".into(),
                dcc: Err("no customer".into()),
            },
        );
        assert_eq!(c.html_sha256, sha256("<p>x</p>"));
        assert_eq!((c.dcc.clone(), c.dcc_sha256.clone()), (None, None));
        assert_eq!(c.dcc_missing.as_deref(), Some("no customer"));
        let mut c2 = c.clone();
        assert!(c2.intact());
        c2.html.push(' ');
        assert!(!c2.intact());
    }
}
