//! The bad-input corpus (`tests/corpus/bad_inputs.json`): every case gets its
//! expected 4xx, problem document and pointer (or parameter), and after all
//! of them the stored data is exactly what it was.

use reqwest::{Method, StatusCode};
use rusqlite::{Connection, OpenFlags};
use serde_json::Value;

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

/// Sets (creating object members) or removes the value at a JSON pointer.
fn patch(doc: &mut Value, pointer: &str, value: Option<Value>) {
    let (parent, last) = pointer.rsplit_once('/').unwrap();
    let last = last.replace("~1", "/").replace("~0", "~");
    let parent = doc
        .pointer_mut(parent)
        .unwrap_or_else(|| panic!("no parent for {pointer}"));
    match (parent, value) {
        (Value::Object(m), Some(v)) => {
            m.insert(last, v);
        }
        (Value::Object(m), None) => {
            m.remove(&last);
        }
        (Value::Array(a), Some(v)) => a[last.parse::<usize>().unwrap()] = v,
        (Value::Array(a), None) => {
            a.remove(last.parse::<usize>().unwrap());
        }
        _ => panic!("cannot patch {pointer}"),
    }
}

fn body_of(case: &Value) -> Vec<u8> {
    if let Some(raw) = case.get("raw") {
        return raw.as_str().unwrap().as_bytes().to_vec();
    }
    if let Some(hex) = case.get("raw_hex") {
        return hex::decode(hex.as_str().unwrap()).unwrap();
    }
    if let Some(rep) = case.get("raw_repeat") {
        return rep[0]
            .as_str()
            .unwrap()
            .repeat(rep[1].as_u64().unwrap() as usize)
            .into_bytes();
    }
    if let Some(body) = case.get("body") {
        return serde_json::to_vec(body).unwrap();
    }
    match case.get("base").and_then(Value::as_str) {
        Some("paper") => {
            let mut doc = paper();
            if let Some(set) = case.get("set").and_then(Value::as_object) {
                for (p, v) in set {
                    patch(&mut doc, p, Some(v.clone()));
                }
            }
            for p in case
                .get("remove")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
            {
                patch(&mut doc, p.as_str().unwrap(), None);
            }
            serde_json::to_vec(&doc).unwrap()
        }
        None => Vec::new(),
        Some(other) => panic!("unknown base {other}"),
    }
}

/// Everything stored, as text: the data must not change under bad input.
fn snapshot(db: &std::path::Path) -> String {
    let c = Connection::open_with_flags(db, OpenFlags::SQLITE_OPEN_READ_ONLY).unwrap();
    let mut out = String::new();
    for sql in [
        "SELECT id || result || hex(submission) FROM calibrations ORDER BY id",
        "SELECT sensor_id || calibration_count || latest_calibration_id FROM sensors ORDER BY sensor_id",
        "SELECT id || role || coalesce(revoked_at, '-') FROM tokens ORDER BY id",
        "SELECT principal || key || coalesce(calibration_id, '-') FROM idempotency_keys ORDER BY principal, key",
        "SELECT type_id || definition FROM sensor_types ORDER BY type_id",
        "SELECT sensor_id || coalesce(sensor_type, '-') FROM sensors ORDER BY sensor_id",
    ] {
        let mut stmt = c.prepare(sql).unwrap();
        let rows = stmt.query_map([], |r| r.get::<_, String>(0)).unwrap();
        for r in rows {
            out.push_str(&r.unwrap());
            out.push('\n');
        }
        out.push_str("--\n");
    }
    out
}

#[tokio::test]
async fn every_bad_input_gets_a_precise_4xx_and_changes_nothing() {
    let cases: Vec<Value> =
        serde_json::from_str(include_str!("../corpus/bad_inputs.json")).unwrap();
    assert!(cases.len() >= 60, "the corpus must hold at least 60 cases");
    let app = TestApp::spawn(Sqlite).await;
    app.submit(ADMIN, &paper()).await;
    let reader = app.token("reader", None).await;
    let before = snapshot(&app.db_path());

    let mut failures = Vec::new();
    for case in &cases {
        let name = case["name"].as_str().unwrap();
        let method = Method::from_bytes(
            case.get("method")
                .and_then(Value::as_str)
                .unwrap_or("POST")
                .as_bytes(),
        )
        .unwrap();
        let mut req = app
            .client
            .request(method, app.url(case["path"].as_str().unwrap()));
        match case.get("token").and_then(Value::as_str).unwrap_or("admin") {
            "admin" => req = req.bearer_auth(ADMIN),
            "reader" => req = req.bearer_auth(&reader),
            "garbage" => req = req.bearer_auth("acc_garbage"),
            "none" => {}
            other => panic!("unknown token kind {other}"),
        }
        match case.get("content_type") {
            None => req = req.header("content-type", "application/json"),
            Some(Value::Null) => {}
            Some(ct) => req = req.header("content-type", ct.as_str().unwrap()),
        }
        for (k, v) in case
            .get("headers")
            .and_then(Value::as_object)
            .into_iter()
            .flatten()
        {
            req = req.header(k.as_str(), v.as_str().unwrap());
        }
        let body = body_of(case);
        if !body.is_empty() || case.get("raw").is_some() {
            req = req.body(body);
        }
        let res = req.send().await.unwrap();
        let status = res.status();
        let want = StatusCode::from_u16(case["status"].as_u64().unwrap() as u16).unwrap();
        let ct = res
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_owned());
        let text = res.text().await.unwrap();
        if status != want {
            failures.push(format!("{name}: {status} (want {want}): {text}"));
            continue;
        }
        if ct.as_deref() != Some("application/problem+json") {
            failures.push(format!("{name}: content type {ct:?}"));
            continue;
        }
        let p: Value = serde_json::from_str(&text).unwrap();
        if p.get("request_id").is_none() || p["status"] != case["status"] {
            failures.push(format!("{name}: malformed problem {p}"));
        }
        if let Some(pointer) = case.get("pointer").and_then(Value::as_str)
            && !pointers(&p).iter().any(|x| x == pointer)
        {
            failures.push(format!("{name}: no error at {pointer:?}: {p}"));
        }
        if let Some(param) = case.get("parameter")
            && p.get("parameter") != Some(param)
        {
            failures.push(format!(
                "{name}: parameter {:?}, want {param}: {p}",
                p.get("parameter")
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    assert_eq!(
        snapshot(&app.db_path()),
        before,
        "bad input changed the stored data"
    );
}
