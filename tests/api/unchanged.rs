//! Every answer and document, pinned (issue 44 item 4): one laboratory's
//! day — standards, a sensor type, a customer and an item; the paper
//! identified, submitted, reviewed, certified, recalibrated, superseded and
//! withdrawn; a triad stored, exported, compensated and certified; a triad
//! found from the gravity magnitude judged and certified; a
//! standard's nonconformity; the pages; a few refusals — each answer's
//! status, media type and body compared with the snapshot the build before
//! the application layer answered, byte for byte after the only things that
//! differ between runs are replaced in order of appearance: ids
//! (`<id-1>`, …) and the run's own clock (`<now>`, `<today>`: an instant as RFC 3339 or
//! as printed, `2026-11-27 18:33 UTC`, of today or yesterday). Both engines
//! answer against the same snapshots.

use std::collections::HashMap;

use regex::{Captures, Regex};
use reqwest::{Method, StatusCode};
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

use crate::triad::{gravity_positions, known_body};
use crate::triads::guarded_type;
use crate::ui::sign_in;

/// Replaces what differs between runs, consistently across one run.
struct Normaliser {
    ids: HashMap<String, usize>,
    uuid: Regex,
    instant: Regex,
    clock: Regex,
    digest: Regex,
    session: Regex,
    short: Regex,
    today: Vec<String>,
}

impl Normaliser {
    fn new() -> Self {
        let now = time::OffsetDateTime::now_utc();
        // Today and yesterday, for a run across midnight.
        let today = [now, now - time::Duration::days(1)]
            .map(|t| t.date().to_string())
            .to_vec();
        Normaliser {
            ids: HashMap::new(),
            // An id hyphenated, or a token's id in 32 hex digits.
            uuid: Regex::new(
                r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}|\b[0-9a-f]{32}\b",
            )
            .unwrap(),
            instant: Regex::new(
                r"(\d{4}-\d{2}-\d{2})T\d{2}:\d{2}:\d{2}(\.\d+)?(Z|[+-]\d{2}:\d{2})",
            )
            .unwrap(),
            clock: Regex::new(r"(\d{4}-\d{2}-\d{2}) \d{2}:\d{2}(:\d{2})?").unwrap(),
            digest: Regex::new(r#"("(?:html|dcc)_sha256":"|id="dcc-sha256">)[0-9a-f]{64}"#)
                .unwrap(),
            session: Regex::new(r#"(name="csrf" value=")[^"]*(")"#).unwrap(),
            short: Regex::new(r"<code>[0-9a-f]{8}(?:-[0-9a-f]{4}…)?</code>").unwrap(),
            today,
        }
    }

    fn apply(&mut self, text: &str) -> String {
        let ids = &mut self.ids;
        let text = self.uuid.replace_all(text, |c: &Captures| {
            let n = ids.len() + 1;
            format!("<id-{}>", ids.entry(c[0].to_owned()).or_insert(n))
        });
        let today = &self.today;
        let text = self.instant.replace_all(&text, |c: &Captures| {
            if today.iter().any(|d| d == &c[1]) {
                "<now>".to_owned()
            } else {
                c[0].to_owned()
            }
        });
        let text = self.clock.replace_all(&text, |c: &Captures| {
            if today.iter().any(|d| d == &c[1]) {
                "<now>".to_owned()
            } else {
                c[0].to_owned()
            }
        });
        // A document's digest covers its ids and instants; the document is
        // compared itself.
        let text = self.digest.replace_all(&text, "$1<sha256>");
        // A page's session (its form token), and ids shown cut short (a
        // token's first eight hex digits, a calibration's first twelve).
        let text = self.session.replace_all(&text, "$1<session>$2");
        let text = self.short.replace_all(&text, "<code><short-id></code>");
        let mut text = text.into_owned();
        for d in today {
            text = text.replace(d.as_str(), "<today>");
        }
        text
    }
}

/// The day's requests, each answer snapshotted under its label.
struct Day<'a> {
    app: &'a TestApp,
    norm: Normaliser,
    session: String,
}

impl Day<'_> {
    /// Sends a request; snapshots status, media type and body; answers the
    /// body as JSON when it is JSON.
    async fn call(
        &mut self,
        label: &str,
        method: Method,
        path: &str,
        token: &str,
        body: Option<&Value>,
        accept: Option<&str>,
    ) -> Value {
        let mut req = self
            .app
            .client
            .request(method, self.app.url(path))
            .bearer_auth(token);
        if let Some(b) = body {
            req = req.json(b);
        }
        if let Some(a) = accept {
            req = req.header("accept", a);
        }
        self.record(label, req.send().await.unwrap()).await
    }

    async fn get(&mut self, label: &str, path: &str) -> Value {
        self.call(label, Method::GET, path, ADMIN, None, None).await
    }

    async fn post(&mut self, label: &str, path: &str, token: &str, body: &Value) -> Value {
        self.call(label, Method::POST, path, token, Some(body), None)
            .await
    }

    async fn page(&mut self, label: &str, path: &str) {
        let res = crate::ui::page(self.app, path, &self.session).await;
        self.record(label, res).await;
    }

    async fn record(&mut self, label: &str, res: reqwest::Response) -> Value {
        let status = res.status();
        let media = res
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_owned())
            .unwrap_or_default();
        let revision = res
            .headers()
            .get("certificate-revision")
            .map(|v| format!("\ncertificate-revision: {}", v.to_str().unwrap()))
            .unwrap_or_default();
        let text = res.text().await.unwrap();
        let shown = format!("{status}\n{media}{revision}\n\n{text}");
        insta::assert_snapshot!(label, self.norm.apply(&shown));
        serde_json::from_str(&text).unwrap_or(Value::Null)
    }
}

/// The DCC tests' laboratory, with a public URL for the certificates' own.
fn lab(c: &mut accelcal::startup::Config) {
    crate::dcc::lab(c);
    c.web.public_url = Some("https://calibration.example".into());
}

fn example(name: &str) -> Value {
    let path = format!("{}/examples/{name}", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Puts a record an admin keeps, asserting it was written.
async fn put(app: &TestApp, path: &str, body: Value) {
    let res = app.put(path, ADMIN, &body).await;
    assert!(res.status().is_success(), "{path}: {}", res.status());
}

#[rstest]
#[tokio::test]
async fn every_answer_and_document_is_as_before(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, lab).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let station = app
        .held_token("station", "Sam Station", Some("LAB-1"))
        .await;
    let reader = app.held_token("reader", "Rudi Reader", None).await;
    let (session, _) = sign_in(&app, &reader).await;
    let mut day = Day {
        app: &app,
        norm: Normaliser::new(),
        session,
    };

    // The records an admin keeps.
    put(
        &app,
        "/v1/standards/STAND-1",
        example("standard-stand.json"),
    )
    .await;
    put(
        &app,
        "/v1/standards/G-BENCH",
        json!({
            "kind": "gravity",
            "description": "Absolute gravity at the calibration bench",
            "certificate": {"number": "GRAV-2025-03", "issued_by": "Geodetic Survey",
                            "calibrated_at": "2025-03-01T00:00:00Z"},
            "due_at": "2030-03-01T00:00:00Z",
            "gravity_m_s2": 9.80424,
            "gravity_rel_std": 2e-7,
            "traceability": "Absolute gravimeter FG5 #215, compared at ICAG-2023."
        }),
    )
    .await;
    put(
        &app,
        "/v1/sensor-types/NAV",
        example("sensor-type-nav.json"),
    )
    .await;
    put(
        &app,
        "/v1/customers/ACME",
        json!({"name": "Acme Navigation GmbH", "address": "1 Gyro Way", "due_date_agreed": true}),
    )
    .await;
    for sensor in ["PAPER-1", "IMU-7"] {
        put(
            &app,
            &format!("/v1/sensors/{sensor}/item"),
            json!({"manufacturer": "Honeywell", "model": "QA-3000",
                   "serial": format!("SN-{sensor}"), "customer": "ACME"}),
        )
        .await;
    }

    // The paper: identified, then stored against the registry's standards.
    let mut paper = example("paper-table1.json");
    paper["sensor_id"] = json!("PAPER-1");
    paper["sensor_type"] = json!("NAV");
    paper["performed_at"] = json!("2026-06-01T08:00:00Z");
    paper["standards"] = json!({"stand": "STAND-1", "gravity": "G-BENCH"});
    day.post("identify", "/v1/identify", &station, &paper).await;
    let first = day
        .post("submit", "/v1/calibrations", &station, &paper)
        .await;
    let first = first["id"].as_str().unwrap().to_owned();
    day.get("calibration", &format!("/v1/calibrations/{first}"))
        .await;
    day.get(
        "submission",
        &format!("/v1/calibrations/{first}/submission"),
    )
    .await;
    day.get(
        "certificate_draft",
        &format!("/v1/calibrations/{first}/certificate"),
    )
    .await;
    day.post(
        "review_approve",
        &format!("/v1/calibrations/{first}/review"),
        &rita,
        &json!({"decision": "approve", "comment": "Checked against the paper."}),
    )
    .await;
    day.get(
        "certificate_html",
        &format!("/v1/calibrations/{first}/certificate"),
    )
    .await;
    day.call(
        "certificate_dcc",
        Method::GET,
        &format!("/v1/calibrations/{first}/certificate"),
        ADMIN,
        None,
        Some("application/xml"),
    )
    .await;
    day.get(
        "signatures",
        &format!("/v1/calibrations/{first}/signatures"),
    )
    .await;

    // A recalibration three months on: as found against the first.
    let mut again = example("paper-recalibration.json");
    again["sensor_id"] = json!("PAPER-1");
    again["performed_at"] = json!("2026-09-01T08:00:00Z");
    again.as_object_mut().unwrap().remove("stand");
    again["standards"] = json!({"stand": "STAND-1", "gravity": "G-BENCH"});
    let second = day
        .post("submit_recalibration", "/v1/calibrations", &station, &again)
        .await;
    let second = second["id"].as_str().unwrap().to_owned();
    day.get("sensor", "/v1/sensors/PAPER-1").await;
    day.get("history", "/v1/sensors/PAPER-1/calibrations").await;
    day.get("coefficients", "/v1/sensors/PAPER-1/coefficients")
        .await;
    day.get("stability", "/v1/sensors/PAPER-1/stability").await;
    day.post(
        "compensate",
        "/v1/sensors/PAPER-1/compensate",
        ADMIN,
        &json!({"outputs": [0.5, -0.25, 1.0], "a_p": [0.0, 0.1, -0.1]}),
    )
    .await;
    // Corrected by a third, which is then withdrawn.
    again["notes"] = json!("Corrected: the run order.");
    let third = day
        .post(
            "supersede",
            &format!("/v1/calibrations/{second}/supersede?reason=wrong%20notes"),
            &station,
            &again,
        )
        .await;
    let third = third["id"].as_str().unwrap().to_owned();
    day.post(
        "withdraw",
        &format!("/v1/calibrations/{third}/withdraw"),
        &rita,
        &json!({"reason": "The stand was found loose."}),
    )
    .await;
    day.post(
        "reprocess",
        &format!("/v1/calibrations/{first}/reprocess"),
        ADMIN,
        &json!({}),
    )
    .await;
    day.post(
        "amend",
        &format!("/v1/calibrations/{first}/amend"),
        &rita,
        &json!({"reason": "The customer's address was corrected."}),
    )
    .await;
    day.get(
        "certificate_amended",
        &format!("/v1/calibrations/{first}/certificate?revision=2"),
    )
    .await;
    day.call(
        "certificate_amended_dcc",
        Method::GET,
        &format!("/v1/calibrations/{first}/certificate?revision=2"),
        ADMIN,
        None,
        Some("application/xml"),
    )
    .await;

    // A triad: identified, stored, read, exported, compensated, certified.
    let mut triad = known_body();
    triad["sensor_id"] = json!("IMU-7");
    triad["performed_at"] = json!("2026-06-02T08:00:00Z");
    day.post("triad_identify", "/v1/identify/triad", &station, &triad)
        .await;
    let t = day
        .post("triad_submit", "/v1/calibrations/triad", &station, &triad)
        .await;
    let t = t["id"].as_str().unwrap().to_owned();
    day.get("triad_calibration", &format!("/v1/calibrations/{t}"))
        .await;
    day.get("triad_sensor", "/v1/sensors/IMU-7").await;
    day.get("triad_coefficients", "/v1/sensors/IMU-7/coefficients")
        .await;
    day.get("triad_stability", "/v1/sensors/IMU-7/stability")
        .await;
    day.post(
        "triad_compensate",
        "/v1/sensors/IMU-7/compensate",
        ADMIN,
        &json!({"outputs": [[0.1, 0.2, 9.8], [9.7, -0.1, 0.3]]}),
    )
    .await;
    for format in ["json", "c", "px4", "ardupilot"] {
        day.get(
            &format!("triad_export_{format}"),
            &format!("/v1/calibrations/{t}/export?format={format}"),
        )
        .await;
    }
    day.post(
        "triad_review",
        &format!("/v1/calibrations/{t}/review"),
        &rita,
        &json!({"decision": "approve"}),
    )
    .await;
    day.get(
        "triad_certificate_html",
        &format!("/v1/calibrations/{t}/certificate"),
    )
    .await;
    day.call(
        "triad_certificate_dcc",
        Method::GET,
        &format!("/v1/calibrations/{t}/certificate"),
        ADMIN,
        None,
        Some("application/xml"),
    )
    .await;

    // The pages.
    day.page("page_fleet", "/ui/sensors").await;
    day.page("page_sensor", "/ui/sensors/PAPER-1").await;
    day.page("page_calibration", &format!("/ui/calibrations/{first}"))
        .await;
    day.page("page_superseded", &format!("/ui/calibrations/{second}"))
        .await;
    day.page("page_triad_sensor", "/ui/sensors/IMU-7").await;
    day.page("page_triad", &format!("/ui/calibrations/{t}"))
        .await;
    day.page(
        "page_certificate",
        &format!("/ui/calibrations/{first}/certificate"),
    )
    .await;
    day.page(
        "page_triad_certificate",
        &format!("/ui/calibrations/{t}/certificate"),
    )
    .await;

    // A triad found from the gravity magnitude, judged: its certificate
    // lists S_xy, S_xz and S_yz as fixed by the frame convention.
    guarded_type(
        &app,
        "IMU-G",
        "g",
        &json!({"k0": {"min": -0.05, "max": 0.05}, "ki": {"min": 0.97, "max": 1.03},
                "kp": {"min": -0.02, "max": 0.02}}),
    )
    .await;
    put(
        &app,
        "/v1/sensors/IMU-G/item",
        json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": "SN-IMU-G",
               "customer": "ACME"}),
    )
    .await;
    let gravity = json!({"sensor_id": "IMU-G", "unit": "g", "sensor_type": "IMU-G",
        "performed_at": "2026-06-03T08:00:00Z", "stand": {"gravity_rel_std": 2e-5},
        "static_positions": gravity_positions(20, 0x5eed_1234_abcd_0001)});
    let g = day
        .post(
            "gravity_submit",
            "/v1/calibrations/triad",
            &station,
            &gravity,
        )
        .await;
    let g = g["id"].as_str().unwrap().to_owned();
    day.post(
        "gravity_review",
        &format!("/v1/calibrations/{g}/review"),
        &rita,
        &json!({"decision": "approve"}),
    )
    .await;
    day.get(
        "gravity_certificate_html",
        &format!("/v1/calibrations/{g}/certificate"),
    )
    .await;
    day.call(
        "gravity_certificate_dcc",
        Method::GET,
        &format!("/v1/calibrations/{g}/certificate"),
        ADMIN,
        None,
        Some("application/xml"),
    )
    .await;
    day.page("page_gravity", &format!("/ui/calibrations/{g}"))
        .await;

    // A standard found faulty: the tests it bears on are held.
    day.post(
        "nonconformity",
        "/v1/standards/STAND-1/nonconformity",
        ADMIN,
        &json!({"found_at": "2026-07-01T00:00:00Z", "last_known_good_at": "2026-05-01T00:00:00Z",
                "reason": "Indexing error of 9″ at the 90° stop."}),
    )
    .await;
    day.get("affected", "/v1/standards/STAND-1/affected").await;
    day.get("held_coefficients", "/v1/sensors/PAPER-1/coefficients")
        .await;
    day.get(
        "held_certificate",
        &format!("/v1/calibrations/{first}/certificate"),
    )
    .await;

    // Refusals.
    let mut bad = example("paper-table1.json");
    bad["runs"] = json!([]);
    day.post("refused_empty_runs", "/v1/calibrations", &station, &bad)
        .await;
    let mut single = example("paper-table1.json");
    single["sensor_id"] = json!("IMU-7");
    day.post("refused_wrong_kind", "/v1/calibrations", &station, &single)
        .await;
    day.post(
        "refused_review_twice",
        &format!("/v1/calibrations/{t}/review"),
        &rita,
        &json!({"decision": "approve"}),
    )
    .await;
    assert_eq!(
        app.get(
            "/v1/calibrations/01890000-0000-7000-8000-000000000000",
            ADMIN
        )
        .await
        .status(),
        StatusCode::NOT_FOUND
    );
}
