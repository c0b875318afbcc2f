//! Customers and items (issue 29 item 4): written by admins, read by
//! everyone, checked field by field, kept by both engines, and printed on
//! the certificate — the due date only when the customer agreed to one.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

fn acme(agreed: bool) -> Value {
    json!({"name": "Acme Navigation GmbH", "address": "1 Gyro Way, 80331 Munich",
           "contact": "Dr. K. Lee", "due_date_agreed": agreed})
}

#[rstest]
#[tokio::test]
async fn customers_and_items_are_recorded_and_certified(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let reader = app.token("reader", None).await;
    let station = app.token("station", None).await;

    // Customers: admin writes (201, then 200), everyone reads.
    let res = app.put("/v1/customers/ACME", ADMIN, &acme(false)).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let created: Value = res.json().await.unwrap();
    assert_eq!(created["customer_id"], "ACME");
    assert_eq!(created["due_date_agreed"], false);
    assert_eq!(app.get_json("/v1/customers/ACME", &reader).await, created);
    problem(
        app.put("/v1/customers/X", &station, &acme(true)).await,
        StatusCode::FORBIDDEN,
    )
    .await;
    let p = problem(
        app.put(
            "/v1/customers/ACME",
            ADMIN,
            &json!({"name": "", "address": "a\u{7}"}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/name", "/address"]);
    problem(
        app.get("/v1/customers/NOPE", &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;

    // An item may be recorded before the sensor is calibrated; its
    // customer must exist.
    let p = problem(
        app.put(
            "/v1/sensors/PAPER-2005/item",
            ADMIN,
            &json!({"serial": "QA-1", "customer": "NOPE"}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/customer"]);
    let item = json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": "QA-12345", "customer": "ACME"});
    let res = app.put("/v1/sensors/PAPER-2005/item", ADMIN, &item).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let got = app.get_json("/v1/sensors/PAPER-2005/item", &reader).await;
    assert_eq!(
        (got["serial"].clone(), got["customer"].clone()),
        (json!("QA-12345"), json!("ACME"))
    );
    problem(
        app.get("/v1/sensors/OTHER/item", &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;

    // The certificate names the customer and the item; with no due date
    // agreed it states none, though the calibration has one.
    app.put(
        "/v1/sensor-types/NAV",
        ADMIN,
        &serde_json::from_str::<Value>(include_str!("../../examples/sensor-type-nav.json"))
            .unwrap(),
    )
    .await;
    let mut body = paper();
    body["sensor_type"] = json!("NAV");
    let r = app.submit(ADMIN, &body).await;
    assert!(
        r["due_at"].is_string(),
        "typed: the calibration has a due date"
    );
    let cert_of = |id: &Value| format!("/v1/calibrations/{}/certificate", id.as_str().unwrap());
    let cert = app
        .get(&cert_of(&r["id"]), &reader)
        .await
        .text()
        .await
        .unwrap();
    assert!(
        cert.contains("Acme Navigation GmbH, 1 Gyro Way, 80331 Munich"),
        "customer"
    );
    assert!(
        cert.contains("Honeywell QA-3000, serial number QA-12345"),
        "item"
    );
    assert!(cert.contains("no due date was agreed with the customer"));
    // Agreed: the due date is printed.
    assert_eq!(
        app.put("/v1/customers/ACME", ADMIN, &acme(true))
            .await
            .status(),
        StatusCode::OK
    );
    let cert = app
        .get(&cert_of(&r["id"]), &reader)
        .await
        .text()
        .await
        .unwrap();
    assert!(!cert.contains("no due date was agreed"));
    let listed = app.get_json("/v1/customers", &reader).await;
    assert_eq!(listed["items"][0]["due_date_agreed"], true);
}
