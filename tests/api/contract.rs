//! One source of truth for the contract: the committed `openapi.yaml` is what
//! `accelcal openapi` generates from the code, and what the server serves.

use reqwest::StatusCode;

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

const COMMITTED: &str = include_str!("../../openapi.yaml");

#[test]
fn the_committed_contract_is_what_the_code_generates() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .arg("openapi")
        .output()
        .unwrap();
    assert!(out.status.success());
    let generated = String::from_utf8(out.stdout).unwrap();
    assert!(
        generated == COMMITTED,
        "openapi.yaml differs from `accelcal openapi`; regenerate it with \
         `cargo run -- openapi > openapi.yaml` and review the diff"
    );
}

/// Every `$ref` in the contract names a component it defines (schemathesis
/// refuses an operation whose reference does not resolve).
#[test]
fn every_reference_resolves() {
    let doc: serde_json::Value = serde_norway::from_str(COMMITTED).unwrap();
    fn refs<'a>(v: &'a serde_json::Value, out: &mut Vec<&'a str>) {
        match v {
            serde_json::Value::Object(m) => {
                if let Some(serde_json::Value::String(r)) = m.get("$ref") {
                    out.push(r);
                }
                m.values().for_each(|x| refs(x, out));
            }
            serde_json::Value::Array(a) => a.iter().for_each(|x| refs(x, out)),
            _ => {}
        }
    }
    let mut all = Vec::new();
    refs(&doc, &mut all);
    assert!(all.len() > 100, "{} references", all.len());
    let unresolved: std::collections::BTreeSet<&str> = all
        .into_iter()
        .filter(|r| {
            let path = r.strip_prefix('#').unwrap_or("/not-local");
            doc.pointer(path).is_none()
        })
        .collect();
    assert!(unresolved.is_empty(), "unresolved: {unresolved:?}");
}

#[rstest]
#[tokio::test]
async fn the_server_serves_the_committed_contract(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let res = app
        .client
        .get(app.url("/openapi.yaml"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.text().await.unwrap(), COMMITTED);
}

/// The contract keeps the constraints the checks enforce (a sample of them,
/// read from the document as a client would).
#[test]
fn the_contract_carries_the_limits() {
    let doc: serde_json::Value = serde_norway::from_str(COMMITTED).unwrap();
    let schemas = &doc["components"]["schemas"];
    assert_eq!(schemas["Submission"]["additionalProperties"], false);
    assert_eq!(
        schemas["Submission"]["properties"]["positions"]["maxItems"],
        360
    );
    assert_eq!(
        schemas["Submission"]["properties"]["runs"]["maxItems"],
        1000
    );
    assert_eq!(
        schemas["ReadingIn"]["anyOf"][0]["maxItems"], 100_000,
        "a real static window of 1 000 s at 100 Hz fits"
    );
    assert_eq!(
        schemas["ReadingIn"]["anyOf"][1]["required"],
        serde_json::json!(["mean", "std", "count"])
    );
    assert_eq!(schemas["Identifier"]["maxLength"], 64);
    assert_eq!(
        schemas["Identifier"]["pattern"],
        "^[A-Za-z0-9][A-Za-z0-9._:-]*$"
    );
    assert_eq!(schemas["TokenRequest"]["additionalProperties"], false);
    assert_eq!(
        schemas["TokenRequest"]["then"]["properties"]["station_id"]["type"],
        "null"
    );
    assert_eq!(schemas["FuseRequest"]["additionalProperties"], false);
    // Outputs: numbers for a single-axis sensor, triples for a triad.
    let outputs = &schemas["CompensateRequest"]["properties"]["outputs"]["oneOf"];
    assert_eq!(outputs[0]["maxItems"], 10000);
    assert_eq!(outputs[1]["maxItems"], 10000);
    assert_eq!(outputs[1]["items"]["minItems"], 3);
    assert_eq!(outputs[1]["items"]["maxItems"], 3);
    assert!(schemas["Submission"]["examples"].is_array());
    let submit = &doc["paths"]["/v1/calibrations"]["post"];
    assert_eq!(submit["operationId"], "submitCalibration");
    assert_eq!(
        submit["responses"]["422"]["$ref"],
        "#/components/responses/Invalid"
    );
    assert!(submit["responses"]["201"]["links"]["GetCalibration"].is_object());
}
