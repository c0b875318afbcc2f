//! The laboratory's signature on its Digital Calibration Certificates
//! (issue 46): an enveloped W3C XML Signature with XAdES-BES signed
//! properties, made and checked by a maintained library (`bergshamra`,
//! pure Rust over RustCrypto; docs/developers.md says why), never by hand.
//!
//! **What is signed.** `ds:Signature` is the DCC root's last child, where
//! PTB's schema (3.3.0) places it. Its `SignedInfo` holds two references,
//! each digested with SHA-256 after exclusive canonicalisation (also
//! `SignedInfo`'s own canonicalisation):
//! 1. `URI=""` with the enveloped-signature transform — the whole
//!    certificate, every element and attribute of it, except the
//!    signature itself;
//! 2. `#accelcal-signed-properties` (typed as XAdES signed properties) —
//!    the signing time and the SHA-256 of the signing certificate
//!    (`xades:SigningCertificateV2`), so that neither can be changed or
//!    swapped.
//!
//! The signature value is RSA-SHA256 (PKCS#1 v1.5) or ECDSA-SHA256 on
//! P-256, and `ds:KeyInfo/ds:X509Data` carries the signing certificate and
//! its chain — never a bare `ds:KeyValue`, so a verifier trusts a
//! certificate, not a key the document brings along.
//!
//! **What a key must be** ([`Signer::from_pem`]): a PEM PKCS#8 private key,
//! RSA of at least 2048 bits or ECDSA P-256, matching the first
//! certificate of the PEM chain, that certificate valid now. Anything else
//! is a [`KeyError`], which the command line reports with the file's name.
//!
//! **Verification** ([`verify`]) checks the document's structure (a DCC
//! root, the signature its last child and the only one, the whole document
//! referenced), then the signature and both digests, then that the signed
//! properties name the certificate that verified and a signing time within
//! its validity. Trust is either the certificates a caller names (only
//! they may have signed) or the certificate the document embeds (integrity
//! and the signer's name, not who should be trusted).

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;
use bergshamra::keys::loader;
use bergshamra::{DsigContext, Key, KeysManager, VerifyResult};
use sha2::{Digest, Sha256};
use x509_cert::Certificate;
use x509_cert::der::Encode;

use super::timestamp::Timestamp;

mod structure;
#[cfg(test)]
mod tests;

pub use structure::NotADcc;

/// The XML Signature namespace.
pub const DS_NS: &str = "http://www.w3.org/2000/09/xmldsig#";
/// The XAdES 1.3.2 namespace.
pub const XADES_NS: &str = "http://uri.etsi.org/01903/v1.3.2#";
/// The `Id` of the signature element.
const SIGNATURE_ID: &str = "accelcal-signature";
/// The `Id` of the XAdES signed properties.
const PROPERTIES_ID: &str = "accelcal-signed-properties";
const EXC_C14N: &str = "http://www.w3.org/2001/10/xml-exc-c14n#";
const ENVELOPED: &str = "http://www.w3.org/2000/09/xmldsig#enveloped-signature";
const SHA256_URI: &str = "http://www.w3.org/2001/04/xmlenc#sha256";
const SIGNED_PROPERTIES_TYPE: &str = "http://uri.etsi.org/01903#SignedProperties";
/// The smallest RSA modulus accepted, in bits.
pub const MIN_RSA_BITS: usize = 2048;

/// The signature algorithm a key signs with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Algorithm {
    /// RSA PKCS#1 v1.5 with SHA-256, and the modulus size in bits.
    RsaSha256 {
        /// The modulus size.
        bits: usize,
    },
    /// ECDSA on P-256 with SHA-256.
    EcdsaP256Sha256,
}

impl Algorithm {
    /// Its XML Signature identifier.
    pub fn uri(self) -> &'static str {
        match self {
            Algorithm::RsaSha256 { .. } => "http://www.w3.org/2001/04/xmldsig-more#rsa-sha256",
            Algorithm::EcdsaP256Sha256 => "http://www.w3.org/2001/04/xmldsig-more#ecdsa-sha256",
        }
    }
}

/// What a signer's (or a verified signature's) certificate says, as a
/// receiver would quote it.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, utoipa::ToSchema)]
pub struct CertificateFacts {
    /// Its subject (RFC 4514).
    pub subject: String,
    /// Its issuer (RFC 4514).
    pub issuer: String,
    /// Its serial number, hex.
    pub serial: String,
    /// Valid from (RFC 3339).
    pub not_before: String,
    /// Valid until (RFC 3339).
    pub not_after: String,
    /// SHA-256 of its DER encoding, hex (its fingerprint).
    pub sha256: String,
}

/// A certificate read, with what the checks need.
struct Read {
    der: Vec<u8>,
    facts: CertificateFacts,
    not_before: i64,
    not_after: i64,
}

fn rfc3339(unix: i64) -> String {
    time::OffsetDateTime::from_unix_timestamp(unix)
        .ok()
        .and_then(|t| {
            t.format(&time::format_description::well_known::Rfc3339)
                .ok()
        })
        .unwrap_or_else(|| unix.to_string())
}

fn read(cert: &Certificate) -> Result<Read, String> {
    let der = cert.to_der().map_err(|e| e.to_string())?;
    let tbs = &cert.tbs_certificate;
    let secs = |t: x509_cert::time::Time| {
        i64::try_from(t.to_unix_duration().as_secs()).unwrap_or(i64::MAX)
    };
    let (not_before, not_after) = (secs(tbs.validity.not_before), secs(tbs.validity.not_after));
    Ok(Read {
        facts: CertificateFacts {
            subject: tbs.subject.to_string(),
            issuer: tbs.issuer.to_string(),
            serial: hex::encode(tbs.serial_number.as_bytes()),
            not_before: rfc3339(not_before),
            not_after: rfc3339(not_after),
            sha256: hex::encode(Sha256::digest(&der)),
        },
        der,
        not_before,
        not_after,
    })
}

/// Why a signing key and certificate are refused at start.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum KeyError {
    /// The key file is not a PEM PKCS#8 private key.
    #[error("is not a PEM PKCS#8 private key (-----BEGIN PRIVATE KEY-----): {0}")]
    NotPkcs8(String),
    /// The key file does not read as a private key.
    #[error("does not read as a private key: {0}")]
    Unreadable(String),
    /// The certificate file holds no certificate that reads.
    #[error("does not read as a PEM X.509 certificate: {0}")]
    Certificate(String),
    /// Neither RSA nor ECDSA P-256.
    #[error("holds a {0} key; a DCC signing key is RSA of at least 2048 bits or ECDSA P-256")]
    Unsupported(String),
    /// An RSA key under [`MIN_RSA_BITS`].
    #[error("holds an RSA key of {0} bits; a DCC signing key needs at least 2048")]
    Weak(usize),
    /// The key is not the certificate's.
    #[error("is not the key of the signing certificate ({0})")]
    Mismatch(String),
    /// The certificate is past its validity.
    #[error("expired on {0}: a DCC signed with it would not verify")]
    Expired(String),
    /// The certificate is not valid yet.
    #[error("is not valid before {0}")]
    NotYetValid(String),
}

impl KeyError {
    /// Whether the certificate file (rather than the key file) is at fault.
    pub fn is_certificate(&self) -> bool {
        matches!(
            self,
            KeyError::Certificate(_) | KeyError::Expired(_) | KeyError::NotYetValid(_)
        )
    }
}

/// The laboratory's signing key and certificate, checked. Its `Debug`
/// never shows the key.
pub struct Signer {
    key: Key,
    algorithm: Algorithm,
    certificate: CertificateFacts,
    certificate_digest: String,
}

impl std::fmt::Debug for Signer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Signer")
            .field("algorithm", &self.algorithm)
            .field("certificate", &self.certificate)
            .finish_non_exhaustive()
    }
}

/// The label of the first PEM block in `pem`.
fn pem_label(pem: &[u8]) -> Option<&str> {
    let text = std::str::from_utf8(pem).ok()?;
    let start = text.find("-----BEGIN ")? + "-----BEGIN ".len();
    let end = text[start..].find("-----")?;
    Some(&text[start..start + end])
}

/// The algorithm a certificate's public key signs with, or why none.
fn algorithm(cert: &Certificate) -> Result<Algorithm, KeyError> {
    const RSA: &str = "1.2.840.113549.1.1.1";
    const EC: &str = "1.2.840.10045.2.1";
    const P256: &str = "1.2.840.10045.3.1.7";
    let spki = &cert.tbs_certificate.subject_public_key_info;
    match spki.algorithm.oid.to_string().as_str() {
        RSA => {
            use pkcs1::der::Decode as _;
            let raw = spki.subject_public_key.raw_bytes();
            let key = pkcs1::RsaPublicKey::from_der(raw)
                .map_err(|e| KeyError::Certificate(format!("its RSA key does not read: {e}")))?;
            let n = key.modulus.as_bytes();
            let bits = n.len() * 8 - n.first().map_or(0, |b| b.leading_zeros() as usize);
            if bits < MIN_RSA_BITS {
                return Err(KeyError::Weak(bits));
            }
            Ok(Algorithm::RsaSha256 { bits })
        }
        EC => {
            let curve = spki
                .algorithm
                .parameters
                .as_ref()
                .and_then(|p| p.decode_as::<x509_cert::der::asn1::ObjectIdentifier>().ok())
                .map(|o| o.to_string());
            match curve.as_deref() {
                Some(P256) => Ok(Algorithm::EcdsaP256Sha256),
                Some(other) => Err(KeyError::Unsupported(format!("ECDSA ({other})"))),
                None => Err(KeyError::Unsupported("ECDSA (unnamed curve)".into())),
            }
        }
        other => Err(KeyError::Unsupported(format!(
            "public-key algorithm {other}"
        ))),
    }
}

impl Signer {
    /// The signer over `key_pem` (PEM PKCS#8) and `cert_pem` (the signing
    /// certificate, then its chain), checked at `now`.
    pub fn from_pem(key_pem: &[u8], cert_pem: &[u8], now: Timestamp) -> Result<Self, KeyError> {
        match pem_label(key_pem) {
            Some("PRIVATE KEY") => {}
            Some("ENCRYPTED PRIVATE KEY") => {
                return Err(KeyError::NotPkcs8(
                    "it is encrypted, and accelcal takes no passphrase; keep it decrypted in a \
                     file only the service's user may read"
                        .into(),
                ));
            }
            Some(label) => {
                return Err(KeyError::NotPkcs8(format!(
                    "it is a {label}; convert it with `openssl pkcs8 -topk8 -nocrypt -in KEY -out KEY.p8`"
                )));
            }
            None => return Err(KeyError::NotPkcs8("it holds no PEM block".into())),
        }
        let chain = Certificate::load_pem_chain(cert_pem)
            .map_err(|e| KeyError::Certificate(e.to_string()))?;
        let leaf = chain
            .first()
            .ok_or_else(|| KeyError::Certificate("it holds no certificate".into()))?;
        let algorithm = algorithm(leaf)?;
        let leaf_read = read(leaf).map_err(KeyError::Certificate)?;
        let mut key = loader::load_pem_auto(key_pem, None)
            .map_err(|e| KeyError::Unreadable(e.to_string()))?;
        if !key.has_private_key() {
            return Err(KeyError::Unreadable("it holds no private key".into()));
        }
        let certified = loader::load_x509_cert_der(&leaf_read.der)
            .map_err(|e| KeyError::Certificate(e.to_string()))?;
        if key.to_spki_der().is_none() || key.to_spki_der() != certified.to_spki_der() {
            return Err(KeyError::Mismatch(leaf_read.facts.subject));
        }
        let at = now.datetime().unix_timestamp();
        if at > leaf_read.not_after {
            return Err(KeyError::Expired(leaf_read.facts.not_after));
        }
        if at < leaf_read.not_before {
            return Err(KeyError::NotYetValid(leaf_read.facts.not_before));
        }
        let mut ders = Vec::with_capacity(chain.len());
        for c in &chain {
            ders.push(
                c.to_der()
                    .map_err(|e| KeyError::Certificate(e.to_string()))?,
            );
        }
        key.x509_chain = ders;
        Ok(Signer {
            key,
            algorithm,
            certificate_digest: STANDARD.encode(Sha256::digest(&leaf_read.der)),
            certificate: leaf_read.facts,
        })
    }

    /// The signing certificate.
    pub fn certificate(&self) -> &CertificateFacts {
        &self.certificate
    }

    /// The algorithm it signs with.
    pub fn algorithm(&self) -> Algorithm {
        self.algorithm
    }

    /// `dcc` (a DCC as accelcal writes it, unsigned) signed at `at`.
    pub fn sign(&self, dcc: &str, at: Timestamp) -> Result<String, SignError> {
        let close = dcc
            .rfind("</dcc:digitalCalibrationCertificate>")
            .ok_or(SignError::NotADcc)?;
        let mut template = String::with_capacity(dcc.len() + 4096);
        template.push_str(&dcc[..close]);
        template.push_str(&self.template(at));
        template.push_str(&dcc[close..]);
        let mut keys = KeysManager::new();
        keys.add_key(self.key.clone());
        let ctx = DsigContext::new(keys);
        bergshamra::sign(&ctx, &template).map_err(|e| SignError::Library(e.to_string()))
    }

    /// The `ds:Signature` template: empty digests and value, the empty
    /// `X509Data` the library fills with the chain, and the signed
    /// properties.
    fn template(&self, at: Timestamp) -> String {
        let time = at
            .datetime()
            .replace_nanosecond(0)
            .ok()
            .and_then(|t| {
                t.format(&time::format_description::well_known::Rfc3339)
                    .ok()
            })
            .unwrap_or_else(|| at.to_string());
        let sig = self.algorithm.uri();
        let digest = &self.certificate_digest;
        format!(
            "<ds:Signature xmlns:ds=\"{DS_NS}\" Id=\"{SIGNATURE_ID}\"><ds:SignedInfo>\
<ds:CanonicalizationMethod Algorithm=\"{EXC_C14N}\"/><ds:SignatureMethod Algorithm=\"{sig}\"/>\
<ds:Reference URI=\"\"><ds:Transforms><ds:Transform Algorithm=\"{ENVELOPED}\"/>\
<ds:Transform Algorithm=\"{EXC_C14N}\"/></ds:Transforms><ds:DigestMethod Algorithm=\"{SHA256_URI}\"/>\
<ds:DigestValue></ds:DigestValue></ds:Reference>\
<ds:Reference Type=\"{SIGNED_PROPERTIES_TYPE}\" URI=\"#{PROPERTIES_ID}\"><ds:Transforms>\
<ds:Transform Algorithm=\"{EXC_C14N}\"/></ds:Transforms><ds:DigestMethod Algorithm=\"{SHA256_URI}\"/>\
<ds:DigestValue></ds:DigestValue></ds:Reference></ds:SignedInfo>\
<ds:SignatureValue></ds:SignatureValue><ds:KeyInfo><ds:X509Data/></ds:KeyInfo>\
<ds:Object><xades:QualifyingProperties xmlns:xades=\"{XADES_NS}\" Target=\"#{SIGNATURE_ID}\">\
<xades:SignedProperties Id=\"{PROPERTIES_ID}\"><xades:SignedSignatureProperties>\
<xades:SigningTime>{time}</xades:SigningTime><xades:SigningCertificateV2><xades:Cert><xades:CertDigest>\
<ds:DigestMethod Algorithm=\"{SHA256_URI}\"/><ds:DigestValue>{digest}</ds:DigestValue>\
</xades:CertDigest></xades:Cert></xades:SigningCertificateV2></xades:SignedSignatureProperties>\
</xades:SignedProperties></xades:QualifyingProperties></ds:Object></ds:Signature>"
        )
    }
}

/// Why a DCC could not be signed.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum SignError {
    /// The document has no DCC root to put the signature in.
    #[error("the document is not a DCC (no closing dcc:digitalCalibrationCertificate)")]
    NotADcc,
    /// The signing library refused.
    #[error("the XML Signature library refused: {0}")]
    Library(String),
}

/// Whom a verification trusts.
pub enum Trust<'a> {
    /// Only these certificates may have signed: PEM files, each the
    /// signer's certificate first (a chain after it is not trusted to sign).
    Certificates(&'a [Vec<u8>]),
    /// The certificate the document embeds: integrity and the signer's
    /// name, not whether the signer is one to trust.
    Embedded,
}

/// What a verification found.
#[derive(Clone, Debug, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct Verification {
    /// Whether the signature holds: both digests, the value, the
    /// certificate named in the signed properties, and the trust asked for.
    pub valid: bool,
    /// Whether the document carries a signature at all.
    pub signed: bool,
    /// The certificate that signed it (when it verified, or when the
    /// document embeds one).
    pub signer: Option<CertificateFacts>,
    /// The signed signing time (RFC 3339), when the document states one.
    pub signing_time: Option<String>,
    /// SHA-256 of the document's bytes, hex: the figure the printed
    /// certificate names.
    pub sha256: String,
    /// Why it is not valid.
    pub reason: Option<String>,
}

/// Verifies `xml` (a DCC) under `trust`; [`NotADcc`] when it is not a DCC
/// at all (not well-formed, a DTD, another root).
pub fn verify(xml: &str, trust: &Trust<'_>) -> Result<Verification, NotADcc> {
    let found = structure::read(xml)?;
    let mut v = Verification {
        valid: false,
        signed: found.signatures > 0,
        signer: found
            .certificate
            .as_deref()
            .and_then(from_der)
            .and_then(|c| read(&c).ok())
            .map(|r| r.facts),
        signing_time: found.signing_time.clone(),
        sha256: hex::encode(Sha256::digest(xml.as_bytes())),
        reason: None,
    };
    let refuse = |mut v: Verification, why: String| {
        v.reason = Some(why);
        Ok(v)
    };
    if let Some(why) = found.problem() {
        return refuse(v, why);
    }
    let mut keys = KeysManager::new();
    match trust {
        Trust::Certificates(pems) => {
            for pem in *pems {
                let chain = match Certificate::load_pem_chain(pem) {
                    Ok(c) => c,
                    Err(e) => {
                        return refuse(v, format!("a trusted certificate does not read: {e}"));
                    }
                };
                // The file's first certificate: the signer's (a chain after
                // it names who vouches for it, not another signer).
                match chain
                    .first()
                    .map(|c| c.to_der().map(|der| loader::load_x509_cert_der(&der)))
                {
                    Some(Ok(Ok(k))) => keys.add_key(k),
                    _ => {
                        return refuse(
                            v,
                            "a trusted certificate file holds no certificate that reads".into(),
                        );
                    }
                }
            }
        }
        // The embedded signer's certificate, and only it.
        Trust::Embedded => match found.certificate.as_deref().map(loader::load_x509_cert_der) {
            Some(Ok(k)) => keys.add_key(k),
            Some(Err(e)) => {
                return refuse(v, format!("its embedded certificate does not read: {e}"));
            }
            None => {
                return refuse(
                    v,
                    "the signature embeds no certificate (ds:X509Certificate)".into(),
                );
            }
        },
    }
    // Only those keys (never one the document brings as a bare key value);
    // strict reference positions would refuse the XAdES reference (its
    // target lies inside the signature), so `structure` has required the
    // whole-document reference instead.
    let ctx = DsigContext::new(keys).with_strict_verification(false);
    let key_info = match bergshamra::verify(&ctx, xml) {
        Ok(VerifyResult::Valid { key_info, .. }) => key_info,
        Ok(VerifyResult::Invalid { reason }) => return refuse(v, reason),
        Err(e) => return refuse(v, e.to_string()),
    };
    let signer_der = key_info
        .x509_chain
        .first()
        .cloned()
        .or_else(|| found.certificate.clone());
    let Some(signer) = signer_der
        .as_deref()
        .and_then(from_der)
        .and_then(|c| read(&c).ok())
    else {
        return refuse(
            v,
            "the signature verified, but no certificate names its signer".into(),
        );
    };
    v.signer = Some(signer.facts.clone());
    let digest = STANDARD.encode(Sha256::digest(&signer.der));
    if found.certificate_digest.as_deref() != Some(digest.as_str()) {
        return refuse(
            v,
            "the signed properties do not name the certificate that verified the signature".into(),
        );
    }
    if let Some(t) = &found.signing_time {
        let Ok(at) = Timestamp::parse(t) else {
            return refuse(
                v,
                format!("the signing time {t} is not an RFC 3339 instant"),
            );
        };
        let at = at.datetime().unix_timestamp();
        if at < signer.not_before || at > signer.not_after {
            return refuse(
                v,
                format!(
                    "signed at {t}, outside its certificate's validity ({} to {})",
                    signer.facts.not_before, signer.facts.not_after
                ),
            );
        }
    }
    v.valid = true;
    Ok(v)
}

/// The certificate `der` encodes, if it reads.
fn from_der(der: &[u8]) -> Option<Certificate> {
    use x509_cert::der::Decode as _;
    Certificate::from_der(der).ok()
}
