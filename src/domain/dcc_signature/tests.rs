use super::*;

fn fixture(name: &str) -> Vec<u8> {
    let path = format!("{}/tests/data/signing/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn signer(key: &str, cert: &str) -> Result<Signer, KeyError> {
    Signer::from_pem(&fixture(key), &fixture(cert), Timestamp::now())
}

const DCC: &str = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
<dcc:digitalCalibrationCertificate xmlns:dcc=\"https://ptb.de/dcc\" xmlns:si=\"https://ptb.de/si\" \
schemaVersion=\"3.3.0\"><dcc:administrativeData><dcc:items><dcc:item><dcc:identifications>\
<dcc:identification><dcc:value>SN-0042</dcc:value></dcc:identification></dcc:identifications>\
</dcc:item></dcc:items></dcc:administrativeData><dcc:measurementResults><si:real><si:value>\
1.0012345</si:value></si:real></dcc:measurementResults></dcc:digitalCalibrationCertificate>";

fn at() -> Timestamp {
    Timestamp::now()
}

fn trusted(names: &[&str]) -> Vec<Vec<u8>> {
    names.iter().map(|n| fixture(n)).collect()
}

#[test]
fn a_signed_dcc_verifies_with_its_certificate_and_with_the_one_it_embeds() {
    let s = signer("lab.key", "lab.pem").unwrap();
    assert_eq!(s.algorithm(), Algorithm::RsaSha256 { bits: 2048 });
    let signed = s.sign(DCC, at()).unwrap();
    // The signature is the root's last child, and the original is intact
    // before it.
    let sig = signed.find("<ds:Signature").unwrap();
    assert_eq!(&signed[..sig], &DCC[..DCC.rfind("</dcc:").unwrap()]);
    assert!(signed.ends_with("</ds:Signature></dcc:digitalCalibrationCertificate>"));
    assert!(!signed.contains("KeyValue"), "no bare key: {signed}");
    for trust in [Trust::Embedded, Trust::Certificates(&trusted(&["lab.pem"]))] {
        let v = verify(&signed, &trust).unwrap();
        assert!(v.valid, "{v:?}");
        assert!(v.signed);
        let signer = v.signer.unwrap();
        assert_eq!(
            signer.subject,
            "CN=DCC signing 2026,O=Inertial Test Lab,C=CH"
        );
        assert_eq!(signer, *s.certificate());
        assert_eq!(v.sha256, hex::encode(Sha256::digest(signed.as_bytes())));
        assert!(v.reason.is_none());
    }
}

#[test]
fn the_signing_time_is_the_issue_time_to_the_second() {
    let s = signer("lab.key", "lab.pem").unwrap();
    let t = Timestamp::parse("2026-11-28T09:30:15.123456Z").unwrap();
    let signed = s.sign(DCC, t).unwrap();
    assert!(signed.contains("<xades:SigningTime>2026-11-28T09:30:15Z</xades:SigningTime>"));
    let v = verify(&signed, &Trust::Embedded).unwrap();
    assert_eq!(v.signing_time.as_deref(), Some("2026-11-28T09:30:15Z"));
}

#[test]
fn a_p256_key_signs_too() {
    let s = signer("p256.key", "p256.pem").unwrap();
    assert_eq!(s.algorithm(), Algorithm::EcdsaP256Sha256);
    let signed = s.sign(DCC, at()).unwrap();
    assert!(signed.contains("xmldsig-more#ecdsa-sha256"));
    let v = verify(&signed, &Trust::Certificates(&trusted(&["p256.pem"]))).unwrap();
    assert!(v.valid, "{v:?}");
}

#[test]
fn one_changed_digit_anywhere_signed_is_refused() {
    let s = signer("lab.key", "lab.pem").unwrap();
    let signed = s
        .sign(DCC, Timestamp::parse("2026-11-28T09:30:15Z").unwrap())
        .unwrap();
    for (from, to) in [
        ("1.0012345", "1.0012346"),
        ("SN-0042", "SN-0043"),
        ("09:30:15Z", "09:30:16Z"),
        ("schemaVersion=\"3.3.0\"", "schemaVersion=\"3.3.1\""),
    ] {
        assert_eq!(signed.matches(from).count(), 1, "{from}");
        let forged = signed.replace(from, to);
        for trust in [Trust::Embedded, Trust::Certificates(&trusted(&["lab.pem"]))] {
            let v = verify(&forged, &trust).unwrap();
            assert!(!v.valid, "{from} → {to} verified");
            assert!(v.reason.is_some());
        }
    }
}

#[test]
fn only_the_named_certificates_may_have_signed() {
    let signed = signer("rotated.key", "rotated.pem")
        .unwrap()
        .sign(DCC, at())
        .unwrap();
    let v = verify(&signed, &Trust::Certificates(&trusted(&["lab.pem"]))).unwrap();
    assert!(!v.valid, "{v:?}");
    // A rotation: the old and the new certificate both trusted.
    let v = verify(
        &signed,
        &Trust::Certificates(&trusted(&["lab.pem", "rotated.pem"])),
    )
    .unwrap();
    assert!(v.valid, "{v:?}");
    assert_eq!(
        v.signer.unwrap().subject,
        "CN=DCC signing 2027,O=Inertial Test Lab,C=CH"
    );
}

#[test]
fn a_signature_made_with_another_key_under_the_same_certificate_is_refused() {
    // The embedded certificate swapped for another: the signature value no
    // longer matches its key.
    let lab = signer("lab.key", "lab.pem")
        .unwrap()
        .sign(DCC, at())
        .unwrap();
    let rotated = signer("rotated.key", "rotated.pem")
        .unwrap()
        .sign(DCC, at())
        .unwrap();
    let cert = |doc: &str| {
        let a = doc.find("<ds:X509Certificate>").unwrap();
        let b = doc.find("</ds:X509Certificate>").unwrap();
        doc[a..b].to_string()
    };
    let forged = lab.replace(&cert(&lab), &cert(&rotated));
    let v = verify(&forged, &Trust::Embedded).unwrap();
    assert!(!v.valid, "{v:?}");
}

#[test]
fn an_unsigned_or_twice_signed_dcc_is_not_valid() {
    let v = verify(DCC, &Trust::Embedded).unwrap();
    assert!(!v.valid && !v.signed);
    assert!(v.reason.unwrap().contains("issued unsigned"));
    let s = signer("lab.key", "lab.pem").unwrap();
    let once = s.sign(DCC, at()).unwrap();
    let sig = &once[once.find("<ds:Signature").unwrap()..once.rfind("</dcc:").unwrap()];
    let twice = once.replacen(
        "<dcc:measurementResults>",
        &format!("{sig}<dcc:measurementResults>"),
        1,
    );
    let v = verify(&twice, &Trust::Embedded).unwrap();
    assert!(!v.valid);
    assert!(v.reason.unwrap().contains("2 signatures"));
}

#[test]
fn what_is_not_a_dcc_is_said_to_be_so() {
    for (doc, why) in [
        ("<a", "well-formed"),
        ("<!DOCTYPE x [<!ENTITY e \"e\">]><x/>", "DTD"),
        ("<x xmlns=\"urn:x\"/>", "root element is {urn:x}x"),
        ("", "no root element"),
    ] {
        let e = verify(doc, &Trust::Embedded).unwrap_err();
        assert!(e.0.contains(why), "{doc}: {e}");
    }
}

#[test]
fn a_signature_moved_from_the_end_is_refused() {
    let s = signer("lab.key", "lab.pem").unwrap();
    let signed = s.sign(DCC, at()).unwrap();
    let sig =
        signed[signed.find("<ds:Signature").unwrap()..signed.rfind("</dcc:").unwrap()].to_string();
    let moved = signed.replace(&sig, "").replacen(
        "<dcc:measurementResults>",
        &format!("{sig}<dcc:measurementResults>"),
        1,
    );
    let v = verify(&moved, &Trust::Embedded).unwrap();
    assert!(!v.valid);
    assert!(
        v.reason.unwrap().contains("dcc:administrativeData then"),
        "{moved}"
    );
}

#[test]
fn keys_that_may_not_sign_are_refused_naming_why() {
    assert_eq!(
        signer("weak.key", "weak.pem").unwrap_err(),
        KeyError::Weak(1024)
    );
    assert!(
        matches!(signer("p384.key", "p384.pem").unwrap_err(), KeyError::Unsupported(a) if a.contains("1.3.132.0.34"))
    );
    let e = signer("lab.pkcs1.key", "lab.pem").unwrap_err();
    assert!(
        matches!(&e, KeyError::NotPkcs8(why) if why.contains("RSA PRIVATE KEY") && why.contains("openssl pkcs8")),
        "{e}"
    );
    let e = signer("lab.key", "rotated.pem").unwrap_err();
    assert_eq!(
        e,
        KeyError::Mismatch("CN=DCC signing 2027,O=Inertial Test Lab,C=CH".into())
    );
    assert!(!e.is_certificate());
    let e = signer("lab.pem", "lab.pem").unwrap_err();
    assert!(
        matches!(e, KeyError::NotPkcs8(ref why) if why.contains("CERTIFICATE")),
        "{e}"
    );
    let e = signer("lab.key", "lab.key").unwrap_err();
    assert!(
        matches!(e, KeyError::Certificate(_)) && e.is_certificate(),
        "{e}"
    );
    let e = Signer::from_pem(
        b"-----BEGIN ENCRYPTED PRIVATE KEY-----\n",
        &fixture("lab.pem"),
        at(),
    )
    .unwrap_err();
    assert!(
        matches!(e, KeyError::NotPkcs8(ref why) if why.contains("encrypted")),
        "{e}"
    );
    let e = Signer::from_pem(b"not a key", &fixture("lab.pem"), at()).unwrap_err();
    assert!(matches!(e, KeyError::NotPkcs8(_)), "{e}");
    let e = Signer::from_pem(
        b"-----BEGIN PRIVATE KEY-----\nAAAA\n-----END PRIVATE KEY-----\n",
        &fixture("lab.pem"),
        at(),
    )
    .unwrap_err();
    assert!(matches!(e, KeyError::Unreadable(_)), "{e}");
}

#[test]
fn a_certificate_is_used_only_within_its_validity() {
    let (key, cert) = (fixture("lab.key"), fixture("lab.pem"));
    let after = Timestamp::parse("2080-01-01T00:00:00Z").unwrap();
    let e = Signer::from_pem(&key, &cert, after).unwrap_err();
    assert!(
        matches!(e, KeyError::Expired(ref t) if t.starts_with("2076-")),
        "{e}"
    );
    assert!(e.is_certificate());
    let before = Timestamp::parse("2020-01-01T00:00:00Z").unwrap();
    let e = Signer::from_pem(&key, &cert, before).unwrap_err();
    assert!(
        matches!(e, KeyError::NotYetValid(ref t) if t.starts_with("2026-")),
        "{e}"
    );
    // Signed (by a clock gone wrong) outside the validity: refused.
    let s = Signer::from_pem(&key, &cert, at()).unwrap();
    let signed = s
        .sign(DCC, Timestamp::parse("2019-06-01T00:00:00Z").unwrap())
        .unwrap();
    let v = verify(&signed, &Trust::Embedded).unwrap();
    assert!(!v.valid);
    assert!(
        v.reason
            .unwrap()
            .contains("outside its certificate's validity")
    );
}

#[test]
fn its_debug_never_shows_the_key() {
    let s = signer("lab.key", "lab.pem").unwrap();
    let shown = format!("{s:?}");
    assert!(shown.contains("DCC signing 2026"));
    assert!(!shown.to_lowercase().contains("private"), "{shown}");
}

#[test]
fn a_trusted_file_trusts_its_first_certificate_not_its_chain() {
    // Signed by the test CA's key, under the CA's own certificate: trusting
    // the laboratory's file (its leaf, then the CA) does not trust the CA
    // to sign.
    let ca = Signer::from_pem(&fixture("ca.key"), &fixture("ca.pem"), at()).unwrap();
    let signed = ca.sign(DCC, at()).unwrap();
    let v = verify(&signed, &Trust::Certificates(&trusted(&["lab.pem"]))).unwrap();
    assert!(!v.valid, "{v:?}");
    let v = verify(&signed, &Trust::Certificates(&trusted(&["ca.pem"]))).unwrap();
    assert!(v.valid, "{v:?}");
}
