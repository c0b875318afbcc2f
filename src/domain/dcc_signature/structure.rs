//! A DCC's structure as a verifier needs it, read in one pass before any
//! cryptography: the root, the order of its children, where and how many
//! signatures there are, what the signature references, and the three
//! values its signed properties and key info state (signing time,
//! certificate digest, the first embedded certificate).

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;
use quick_xml::events::Event;
use quick_xml::name::ResolveResult;
use quick_xml::reader::NsReader;

use super::{DS_NS, XADES_NS};

/// The DCC namespace.
const DCC_NS: &str = "https://ptb.de/dcc";

/// Why a document is not a DCC a signature could be checked on.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("{0}")]
pub struct NotADcc(pub String);

/// What [`read`] found.
#[derive(Debug, Default)]
pub struct Found {
    /// The root's children (namespace, local name), in order.
    pub children: Vec<(String, String)>,
    /// `ds:Signature` elements anywhere.
    pub signatures: usize,
    /// The `URI`s of the signature's references.
    pub references: Vec<String>,
    /// The first `ds:X509Certificate`, DER.
    pub certificate: Option<Vec<u8>>,
    /// `xades:SigningTime`.
    pub signing_time: Option<String>,
    /// The `ds:DigestValue` of `xades:CertDigest`.
    pub certificate_digest: Option<String>,
}

impl Found {
    /// Why its structure is not that of a signed DCC, if it is not.
    pub fn problem(&self) -> Option<String> {
        let names: Vec<&str> = self.children.iter().map(|(_, l)| l.as_str()).collect();
        if self.signatures == 0 {
            return Some("the document carries no signature: it was issued unsigned".into());
        }
        if self.signatures > 1 {
            return Some(format!(
                "the document carries {} signatures where a DCC issued by accelcal carries one",
                self.signatures
            ));
        }
        if names.first() != Some(&"administrativeData")
            || names.get(1) != Some(&"measurementResults")
        {
            return Some(
                "the root's children are not dcc:administrativeData then dcc:measurementResults, \
                 as the schema orders them"
                    .into(),
            );
        }
        if self
            .children
            .last()
            .map(|(ns, l)| (ns.as_str(), l.as_str()))
            != Some((DS_NS, "Signature"))
        {
            return Some(
                "the signature is not the root's last child, where the schema places it".into(),
            );
        }
        if !self.references.iter().any(String::is_empty) {
            return Some("the signature does not reference the whole document (URI=\"\")".into());
        }
        None
    }
}

/// The element being read: (namespace, local name).
type Open = (String, String);

/// Reads `xml`'s structure, or says why it is not a DCC.
pub fn read(xml: &str) -> Result<Found, NotADcc> {
    let mut reader = NsReader::from_str(xml);
    reader.config_mut().check_end_names = true;
    let mut stack: Vec<Open> = Vec::new();
    let mut found = Found::default();
    let mut text = String::new();
    let mut seen_root = false;
    loop {
        let (ns, event) = reader
            .read_resolved_event()
            .map_err(|e| NotADcc(format!("the document is not well-formed XML: {e}")))?;
        let ns = match ns {
            ResolveResult::Bound(n) => n.as_ref().to_owned(),
            _ => String::new(),
        };
        match event {
            Event::DocType(_) => {
                return Err(NotADcc(
                    "the document declares a DTD, which a DCC never does".into(),
                ));
            }
            Event::Start(e) => {
                let open = open(&mut found, &stack, ns, &e, &mut seen_root)?;
                text.clear();
                stack.push(open);
            }
            Event::Empty(e) => {
                open(&mut found, &stack, ns, &e, &mut seen_root)?;
                text.clear();
            }
            Event::Text(t) => text.push_str(&t.xml10_content()),
            Event::End(_) => {
                let Some((ns, local)) = stack.pop() else {
                    return Err(NotADcc("the document is not well-formed XML".into()));
                };
                let value = text.split_whitespace().collect::<String>();
                match (ns.as_str(), local.as_str()) {
                    (DS_NS, "X509Certificate") if found.certificate.is_none() => {
                        found.certificate = STANDARD.decode(value.as_bytes()).ok();
                    }
                    (XADES_NS, "SigningTime") => found.signing_time = Some(value),
                    (DS_NS, "DigestValue") if parent_is(&stack, XADES_NS, "CertDigest") => {
                        found.certificate_digest = Some(value);
                    }
                    _ => {}
                }
                text.clear();
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if !seen_root {
        return Err(NotADcc(
            "the document is not well-formed XML: it has no root element".into(),
        ));
    }
    Ok(found)
}

/// Records element `e` (in namespace `ns`, under `stack`) and answers it.
fn open(
    found: &mut Found,
    stack: &[Open],
    ns: String,
    e: &quick_xml::events::BytesStart<'_>,
    seen_root: &mut bool,
) -> Result<Open, NotADcc> {
    let local = e.local_name().as_ref().to_owned();
    if stack.is_empty() {
        if *seen_root {
            return Err(NotADcc(
                "the document has more than one root element".into(),
            ));
        }
        if ns != DCC_NS || local != "digitalCalibrationCertificate" {
            return Err(NotADcc(format!(
                "the root element is {{{ns}}}{local}, not a DCC's \
                 {{{DCC_NS}}}digitalCalibrationCertificate"
            )));
        }
        *seen_root = true;
    } else if stack.len() == 1 {
        found.children.push((ns.clone(), local.clone()));
    }
    if ns == DS_NS && local == "Signature" {
        found.signatures += 1;
    }
    if ns == DS_NS && local == "Reference" && parent_is(stack, DS_NS, "SignedInfo") {
        let uri = e
            .try_get_attribute("URI")
            .ok()
            .flatten()
            .map(|a| a.value.into_owned());
        found
            .references
            .push(uri.unwrap_or_else(|| "(none)".into()));
    }
    Ok((ns, local))
}

/// Whether the innermost open element is `{ns}local`.
fn parent_is(stack: &[Open], ns: &str, local: &str) -> bool {
    stack
        .last()
        .is_some_and(|(n, l)| n.as_str() == ns && l.as_str() == local)
}
