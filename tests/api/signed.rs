//! Signed Digital Calibration Certificates (issue 46): signed once, when
//! issued, and stored — every later request answers the same bytes; an
//! amendment signed as its own revision; the printed certificate naming the
//! signer and the DCC file's SHA-256 (or that it is unsigned); and
//! `POST /v1/dcc/verify`'s answers and refusals. Outside verifiers
//! (xmlsec1, signxml) check the same documents in tests/dcc/signed.sh.

use std::sync::Arc;

use reqwest::StatusCode;
use reqwest::header::CONTENT_TYPE;
use rstest::rstest;
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use accelcal::domain::dcc_signature::{Signer, Trust, verify};
use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(format!("tests/data/signing/{name}")).unwrap()
}

fn signing(c: &mut accelcal::startup::Config) {
    super::dcc::lab(c);
    let signer = Signer::from_pem(&fixture("lab.key"), &fixture("lab.pem"), Timestamp::now());
    c.web.dcc_signer = Some(Arc::new(signer.unwrap()));
}

/// Status and body of a certificate request (`super::frozen::fetch`).
async fn fetch(app: &TestApp, id: &str, query: &str, xml: bool) -> (StatusCode, String) {
    let (status, _, body) = super::frozen::fetch(app, id, query, xml).await;
    (status, body)
}

/// An approved calibration of sensor `SIG-1`, with its customer and item.
async fn approved(app: &TestApp) -> String {
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    app.put(
        "/v1/customers/ACME",
        ADMIN,
        &json!({"name": "Acme", "address": "1 Gyro Way", "due_date_agreed": true}),
    )
    .await;
    app.put(
        "/v1/sensors/SIG-1/item",
        ADMIN,
        &json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": "QA-12345", "customer": "ACME"}),
    )
    .await;
    let c = app
        .submit(ADMIN, &submission("SIG-1", "2026-06-01T08:00:00Z", 4))
        .await;
    let id = c["id"].as_str().unwrap().to_owned();
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/review"),
            &rita,
            &json!({"decision": "approve"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    id
}

fn sha256(text: &str) -> String {
    hex::encode(Sha256::digest(text.as_bytes()))
}

#[rstest]
#[tokio::test]
async fn a_dcc_is_signed_once_when_issued_and_an_amendment_anew(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::configured(engine, signing).await;
    let id = approved(&app).await;
    let (status, dcc) = fetch(&app, &id, "", true).await;
    assert_eq!(status, StatusCode::OK);
    let lab = [fixture("lab.pem")];
    let v = verify(&dcc, &Trust::Certificates(&lab)).unwrap();
    assert!(v.valid, "{v:?}");
    assert_eq!(
        v.signer.unwrap().subject,
        "CN=DCC signing 2026,O=Inertial Test Lab,C=CH"
    );
    let signed_at = v.signing_time.unwrap();
    // Signed once: the same bytes on every request.
    assert_eq!(fetch(&app, &id, "", true).await.1, dcc);
    // The printed certificate names the DCC file's digest and its signer.
    let (_, html) = fetch(&app, &id, "", false).await;
    assert!(html.contains(&sha256(&dcc)), "{html}");
    assert!(html.contains("Signed (XML Signature, XAdES) by CN=DCC signing 2026"));

    tokio::time::sleep(std::time::Duration::from_millis(1100)).await;
    let rita = app.held_token("reviewer", "Rita Two", None).await;
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/amend"),
            &rita,
            &json!({"reason": "The customer's address was corrected."}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let (_, amended) = fetch(&app, &id, "", true).await;
    assert_ne!(amended, dcc);
    let v2 = verify(&amended, &Trust::Certificates(&lab)).unwrap();
    assert!(v2.valid, "{v2:?}");
    assert!(v2.signing_time.unwrap() > signed_at);
    assert!(amended.contains(&format!("{id}-A1")));
    // Revision 1 stays as signed.
    assert_eq!(fetch(&app, &id, "?revision=1", true).await.1, dcc);
    let (_, html2) = fetch(&app, &id, "", false).await;
    assert!(html2.contains(&sha256(&amended)));
}

#[rstest]
#[tokio::test]
async fn an_unsigned_dcc_is_said_to_be_unsigned(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::configured(engine, super::dcc::lab).await;
    let id = approved(&app).await;
    let (_, dcc) = fetch(&app, &id, "", true).await;
    assert!(!dcc.contains("Signature"));
    let (_, html) = fetch(&app, &id, "", false).await;
    assert!(html.contains(&sha256(&dcc)));
    assert!(html.contains("Unsigned: the laboratory issued this DCC without a digital signature"));
    let res = app
        .client
        .post(app.url("/v1/dcc/verify"))
        .bearer_auth(app.token("reader", None).await)
        .header(CONTENT_TYPE, "application/xml")
        .body(dcc.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::OK);
    let v: Value = res.json().await.unwrap();
    assert_eq!(
        (v["valid"].clone(), v["signed"].clone()),
        (json!(false), json!(false))
    );
    assert_eq!(v["sha256"], sha256(&dcc));
    assert!(v["reason"].as_str().unwrap().contains("issued unsigned"));
}

#[rstest]
#[tokio::test]
async fn verify_answers_a_verdict_and_refuses_what_is_not_a_dcc(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::configured(engine, signing).await;
    let id = approved(&app).await;
    let (_, dcc) = fetch(&app, &id, "", true).await;
    let reader = app.token("reader", None).await;
    let post = |body: String, content_type: &'static str, token: Option<String>| {
        let mut req = app
            .client
            .post(app.url("/v1/dcc/verify"))
            .header(CONTENT_TYPE, content_type)
            .body(body);
        if let Some(t) = token {
            req = req.bearer_auth(t);
        }
        req.send()
    };
    let res = post(
        dcc.clone(),
        "application/xml; charset=utf-8",
        Some(reader.clone()),
    )
    .await
    .unwrap();
    assert_eq!(res.status(), StatusCode::OK);
    let v: Value = res.json().await.unwrap();
    assert_eq!(v["valid"], true, "{v}");
    assert_eq!(
        v["signer"]["issuer"],
        "CN=accelcal test CA,O=accelcal tests"
    );
    assert!(v["reason"].is_null());

    let forged = dcc.replacen("QA-12345", "QA-12346", 1);
    let v: Value = post(forged, "text/xml", Some(reader.clone()))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(v["valid"], false);
    assert!(v["reason"].as_str().unwrap().contains("igest"), "{v}");

    let p = problem(
        post(dcc.clone(), "application/json", Some(reader.clone()))
            .await
            .unwrap(),
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("application/xml"));
    for (body, why) in [
        ("hello".to_owned(), "not well-formed"),
        ("<x/>".to_owned(), "not a DCC's"),
        ("<!DOCTYPE d [<!ENTITY a \"aaaa\">]><d/>".to_owned(), "DTD"),
    ] {
        let p = problem(
            post(body, "application/xml", Some(reader.clone()))
                .await
                .unwrap(),
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(pointers(&p), vec![String::new()]);
        assert!(p["detail"].as_str().unwrap().contains(why), "{p}");
    }
    let res = post(dcc, "application/xml", None).await.unwrap();
    assert_eq!(res.status(), StatusCode::UNAUTHORIZED);
}
