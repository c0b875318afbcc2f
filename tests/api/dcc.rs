//! The Digital Calibration Certificate (issue 29 item 6): PTB's DCC 3.3.0
//! answered to `Accept: application/xml`, its structure checked here
//! element by element against the schema's required sequence, its numbers
//! against the stored result rounded independently, and its refusals.
//!
//! With `DCC_XSD` naming a local copy of PTB's `dcc.xsd` 3.3.0 (beside its
//! `si/SI_Format.xsd` and `d-sig/` imports), each document is also
//! validated by `xmllint --schema`; CI has no copy (PTB's servers are out
//! of its reach, and the schema is not the project's to commit).

use reqwest::StatusCode;
use reqwest::header::{ACCEPT, CONTENT_TYPE};
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

const DCC: &str = "https://ptb.de/dcc";
const SI: &str = "https://ptb.de/si";

pub(crate) fn lab(c: &mut accelcal::startup::Config) {
    c.web.laboratory = accelcal::startup::Laboratory {
        name: Some("Inertial Test Lab".into()),
        address: Some("Bahnhofstrasse 1, 8001 Zürich".into()),
        country: Some("CH".into()),
        accreditation: Some("SAS SCS 0999".into()),
        logo: None,
    };
}

/// The children of `node` in the DCC namespace, by local name.
fn kids<'a>(node: roxmltree::Node<'a, 'a>) -> Vec<roxmltree::Node<'a, 'a>> {
    node.children().filter(|n| n.is_element()).collect()
}

fn names(node: roxmltree::Node) -> Vec<String> {
    kids(node)
        .iter()
        .map(|n| n.tag_name().name().to_owned())
        .collect()
}

fn child<'a>(node: roxmltree::Node<'a, 'a>, name: &str) -> roxmltree::Node<'a, 'a> {
    kids(node)
        .into_iter()
        .find(|n| n.tag_name().name() == name)
        .unwrap_or_else(|| panic!("no <{name}> in <{}>", node.tag_name().name()))
}

/// A quantity's conformity: the `dcc:conformity` of its metadata that has
/// one (beside the coverage metadata).
fn conformity_of(quantity: roxmltree::Node) -> String {
    kids(child(quantity, "measurementMetaData"))
        .into_iter()
        .find(|m| kids(*m).iter().any(|n| n.tag_name().name() == "conformity"))
        .map(|m| text_of(m, &["conformity"]))
        .unwrap_or_else(|| panic!("no conformity"))
}

fn text_of<'a>(node: roxmltree::Node<'a, 'a>, path: &[&str]) -> String {
    let mut n = node;
    for p in path {
        n = child(n, p);
    }
    n.text().unwrap_or("").to_owned()
}

/// The document's root and administrative data in the schema's sequence,
/// every element in the DCC's or D-SI's namespace; answers the
/// administrative data.
fn assert_shape<'a>(root: roxmltree::Node<'a, 'a>) -> roxmltree::Node<'a, 'a> {
    assert_eq!(
        (root.tag_name().namespace(), root.tag_name().name()),
        (Some(DCC), "digitalCalibrationCertificate")
    );
    assert_eq!(root.attribute("schemaVersion"), Some("3.3.0"));
    for n in root.descendants().filter(|n| n.is_element()) {
        let ns = n.tag_name().namespace();
        assert!(ns == Some(DCC) || ns == Some(SI), "{:?}", n.tag_name());
    }
    assert_eq!(names(root), ["administrativeData", "measurementResults"]);
    let admin = child(root, "administrativeData");
    assert_eq!(
        names(admin),
        [
            "dccSoftware",
            "coreData",
            "items",
            "calibrationLaboratory",
            "respPersons",
            "customer",
            "statements"
        ]
    );
    admin
}

/// The statements of a judged calibration whose customer agreed to a due
/// date: traceability, scope, conformity and the due date, in order.
fn assert_all_statements(admin: roxmltree::Node) {
    let statements: Vec<String> = kids(child(admin, "statements"))
        .into_iter()
        .map(|s| text_of(s, &["name", "content"]))
        .collect();
    assert_eq!(
        statements,
        [
            "Metrological traceability",
            "Scope of the results",
            "Statement of conformity",
            "Recalibration due"
        ]
    );
}

/// Validates `xml` with xmllint against `$DCC_XSD`, when set.
fn validate_if_asked(xml: &str) {
    let Ok(xsd) = std::env::var("DCC_XSD") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("dcc.xml");
    std::fs::write(&file, xml).unwrap();
    let out = std::process::Command::new("xmllint")
        .args(["--noout", "--schema", &xsd])
        .arg(&file)
        .output()
        .expect("xmllint runs");
    assert!(
        out.status.success(),
        "the DCC does not validate against {xsd}:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

pub(crate) async fn dcc(app: &TestApp, id: &str, token: &str) -> reqwest::Response {
    app.client
        .get(app.url(&format!("/v1/calibrations/{id}/certificate")))
        .bearer_auth(token)
        .header(ACCEPT, "application/xml")
        .send()
        .await
        .unwrap()
}

#[rstest]
#[tokio::test]
async fn an_approved_calibration_has_a_dcc(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, lab).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let reader = app.token("reader", None).await;
    app.put(
        "/v1/customers/ACME",
        ADMIN,
        &json!({"name": "Acme Navigation GmbH", "address": "1 Gyro Way, 80331 Munich", "due_date_agreed": true}),
    )
    .await;
    app.put(
        "/v1/sensors/DCC-1/item",
        ADMIN,
        &json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": "QA-12345", "customer": "ACME"}),
    )
    .await;
    for (id, body) in [
        (
            "STAND-1",
            serde_json::from_str::<Value>(include_str!("../../examples/standard-stand.json"))
                .unwrap(),
        ),
        (
            "G-BENCH",
            json!({
                "kind": "gravity", "description": "Absolute gravity at the bench",
                "certificate": {"number": "GRAV-2025-03", "issued_by": "Geodetic Survey", "calibrated_at": "2025-03-01T00:00:00Z"},
                "due_at": "2030-03-01T00:00:00Z", "gravity_m_s2": 9.80424, "gravity_rel_std": 2e-7,
                "traceability": "Absolute gravimeter FG5 #215."
            }),
        ),
    ] {
        app.put(&format!("/v1/standards/{id}"), ADMIN, &body).await;
    }
    app.put(
        "/v1/sensor-types/NAV",
        ADMIN,
        &json!({"label": "Navigation grade", "unit": "mA",
                "limits": {"k0": {"min": -0.001, "max": 0.001}, "ki": {"min": -1.217, "max": -1.215}},
                "decision_rule": "guarded", "coverage_factor": 2, "interval_days": 365}),
    )
    .await;
    let mut body = submission("DCC-1", "2026-06-01T08:00:00Z", 4);
    body["sensor_type"] = json!("NAV");
    body["standards"] = json!({"stand": "STAND-1", "gravity": "G-BENCH"});
    body["item_received_at"] = json!("2026-05-28T09:00:00Z");
    body["item_condition"] = json!("sealed in its shipping case");
    for (run, t) in body["runs"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .zip([20.5, 21.0, 22.5, 21.5])
    {
        run["temperature_c"] = json!(t);
    }
    let stored = app.submit(ADMIN, &body).await;
    let id = stored["id"].as_str().unwrap().to_owned();

    // Not approved yet: refused, naming the state.
    let res = dcc(&app, &id, &reader).await;
    let p = problem(res, StatusCode::CONFLICT).await;
    assert!(
        p["type"].as_str().unwrap().ends_with("state-conflict"),
        "{p}"
    );
    assert!(p["detail"].as_str().unwrap().contains("submitted"), "{p}");
    // The HTML certificate is unchanged for browsers and plain clients.
    let res = app
        .client
        .get(app.url(&format!("/v1/calibrations/{id}/certificate")))
        .bearer_auth(&reader)
        .header(ACCEPT, "text/html,application/xml;q=0.9,*/*;q=0.8")
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()[CONTENT_TYPE], "text/html; charset=utf-8");

    let approved = app
        .post(
            &format!("/v1/calibrations/{id}/review"),
            &rita,
            &json!({"decision": "approve", "comment": "Residuals checked."}),
        )
        .await;
    assert_eq!(approved.status(), StatusCode::OK);
    let signed: Value = approved.json().await.unwrap();
    let res = dcc(&app, &id, &reader).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(
        res.headers()[CONTENT_TYPE],
        "application/xml; charset=utf-8"
    );
    let xml = res.text().await.unwrap();
    validate_if_asked(&xml);
    let doc = roxmltree::Document::parse(&xml).expect("well-formed XML");
    let root = doc.root_element();
    let admin = assert_shape(root);
    assert_eq!(
        text_of(admin, &["dccSoftware", "software", "release"]),
        env!("CARGO_PKG_VERSION")
    );
    // coreData in the schema's sequence.
    let core = child(admin, "coreData");
    assert_eq!(
        names(core),
        [
            "countryCodeISO3166_1",
            "usedLangCodeISO639_1",
            "mandatoryLangCodeISO639_1",
            "uniqueIdentifier",
            "identifications",
            "receiptDate",
            "beginPerformanceDate",
            "endPerformanceDate",
            "performanceLocation",
            "issueDate"
        ]
    );
    assert_eq!(text_of(core, &["countryCodeISO3166_1"]), "CH");
    assert_eq!(text_of(core, &["uniqueIdentifier"]), id);
    assert_eq!(text_of(core, &["receiptDate"]), "2026-05-28");
    assert_eq!(text_of(core, &["beginPerformanceDate"]), "2026-06-01");
    assert_eq!(
        text_of(core, &["issueDate"]),
        signed["signature"]["signed_at"].as_str().unwrap()[..10]
    );
    // The item, the laboratory, the persons responsible, the customer.
    let item = child(child(admin, "items"), "item");
    assert_eq!(
        text_of(item, &["manufacturer", "name", "content"]),
        "Honeywell"
    );
    assert_eq!(text_of(item, &["model"]), "QA-3000");
    let ids: Vec<(String, String)> = kids(child(item, "identifications"))
        .into_iter()
        .map(|i| (text_of(i, &["issuer"]), text_of(i, &["value"])))
        .collect();
    assert_eq!(
        ids,
        [
            ("manufacturer".into(), "QA-12345".into()),
            ("calibrationLaboratory".into(), "DCC-1".into())
        ]
    );
    assert!(text_of(item, &["description", "content"]).contains("sealed in its shipping case"));
    let labo = child(admin, "calibrationLaboratory");
    assert_eq!(
        text_of(labo, &["calibrationLaboratoryCode"]),
        "SAS SCS 0999"
    );
    assert_eq!(
        text_of(labo, &["contact", "name", "content"]),
        "Inertial Test Lab"
    );
    assert_eq!(text_of(labo, &["contact", "location", "countryCode"]), "CH");
    let person = child(child(admin, "respPersons"), "respPerson");
    assert_eq!(
        text_of(person, &["person", "name", "content"]),
        "Rita Reviewer"
    );
    assert_eq!(text_of(person, &["mainSigner"]), "true");
    assert_eq!(
        text_of(admin, &["customer", "name", "content"]),
        "Acme Navigation GmbH"
    );
    // Statements: traceability, scope, conformity, the agreed due date.
    assert_all_statements(admin);
    let verdict = stored["decision"]["verdict"].as_str().unwrap();
    let conformity = kids(child(admin, "statements"))[2];
    assert_eq!(
        text_of(conformity, &["conformity"]),
        match verdict {
            "pass" => "pass",
            "fail" => "fail",
            other => panic!("this calibration's verdict is {other}"),
        }
    );

    // Results: every fused coefficient as si:real in the output's D-SI
    // unit, rounded to its expanded uncertainty's second significant digit
    // (computed here), with k and its coverage probability.
    let result = child(root, "measurementResults");
    let mr = child(result, "measurementResult");
    assert_eq!(
        names(mr),
        [
            "name",
            "description",
            "usedMethods",
            "measuringEquipments",
            "influenceConditions",
            "results"
        ]
    );
    let equipment: Vec<String> = kids(child(mr, "measuringEquipments"))
        .into_iter()
        .map(|e| text_of(e, &["identifications", "identification", "value"]))
        .collect();
    assert_eq!(equipment, ["STAND-1", "G-BENCH"]);
    let conditions: Vec<Vec<String>> = kids(child(mr, "influenceConditions"))
        .into_iter()
        .map(|c| {
            kids(child(c, "data"))
                .into_iter()
                .map(|q| {
                    format!(
                        "{} {}",
                        text_of(q, &["real", "value"]),
                        text_of(q, &["real", "unit"])
                    )
                })
                .collect()
        })
        .collect();
    assert_eq!(
        conditions,
        [
            vec![r"20.5 \degreecelsius", r"22.5 \degreecelsius"],
            vec![r"9.80424 \metre\second\tothe{-2}"]
        ]
    );
    let quantities = kids(child(child(child(mr, "results"), "result"), "data"));
    let fused = stored["fused"]["coefficients"].as_object().unwrap();
    assert_eq!(quantities.len(), fused.len());
    for (q, (term, value)) in quantities.iter().zip(fused) {
        let real = child(*q, "real");
        assert_eq!(text_of(real, &["label"]), *term);
        assert_eq!(text_of(real, &["unit"]), r"\milli\ampere");
        let u = stored["uncertainty"]["terms"][term]["expanded"]
            .as_f64()
            .unwrap();
        let decimals = (1 - u.log10().floor() as i32).max(0) as usize;
        let v = value.as_f64().unwrap();
        assert_eq!(
            text_of(real, &["value"]),
            format!("{v:.decimals$}"),
            "{term}"
        );
        let mu = child(
            child(real, "measurementUncertaintyUnivariate"),
            "expandedMU",
        );
        assert_eq!(text_of(mu, &["valueExpandedMU"]), format!("{u:.decimals$}"));
        // Each coefficient's own k (Student's t at its ν_eff) and p, as the
        // result states them; u_c and ν_eff in its metadata.
        let b = &stored["uncertainty"]["terms"][term];
        let k = b["coverage_factor"].as_f64().unwrap();
        let p = b["coverage_probability"].as_f64().unwrap();
        assert_eq!(text_of(mu, &["coverageFactor"]), format!("{k}"));
        assert_eq!(text_of(mu, &["coverageProbability"]), format!("{p:.4}"));
        let declared = kids(child(*q, "measurementMetaData"))
            .into_iter()
            .map(|m| text_of(m, &["declaration", "content"]))
            .find(|d| d.starts_with("u_c = "))
            .unwrap_or_else(|| panic!("{term}: no coverage metadata"));
        let nu = b["effective_dof"].as_u64().unwrap();
        assert!(
            declared.contains(&format!("ν_eff = {nu} "))
                && declared.contains(&format!("p = {p:.4}")),
            "{term}: {declared}"
        );
    }
    // A limited term carries its own conformity.
    let ki = quantities
        .iter()
        .find(|q| text_of(**q, &["real", "label"]) == "ki")
        .unwrap();
    assert_eq!(
        conformity_of(*ki),
        stored["decision"]["terms"]["ki"]["verdict"]
            .as_str()
            .unwrap()
    );

    // The page links it; the link serves the same document.
    let (session, _) = super::ui::sign_in(&app, &reader).await;
    let page = super::ui::page(&app, &format!("/ui/calibrations/{id}"), &session)
        .await
        .text()
        .await
        .unwrap();
    assert!(page.contains(&format!("/ui/calibrations/{id}/certificate.xml")));
    let linked = super::ui::page(
        &app,
        &format!("/ui/calibrations/{id}/certificate.xml"),
        &session,
    )
    .await;
    assert_eq!(linked.status(), StatusCode::OK);
    let linked = linked.text().await.unwrap();
    assert_eq!(linked, xml);
}

#[rstest]
#[tokio::test]
async fn a_dcc_needs_the_laboratory_and_the_customer(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let stored = app
        .submit(ADMIN, &submission("DCC-2", "2026-06-01T08:00:00Z", 4))
        .await;
    let id = stored["id"].as_str().unwrap();
    app.post(
        &format!("/v1/calibrations/{id}/review"),
        &rita,
        &json!({"decision": "approve"}),
    )
    .await;
    let p = problem(dcc(&app, id, ADMIN).await, StatusCode::CONFLICT).await;
    assert!(
        p["type"].as_str().unwrap().ends_with("incomplete-record"),
        "{p}"
    );
    let detail = p["detail"].as_str().unwrap();
    for what in ["--lab-name", "--lab-country", "customer"] {
        assert!(detail.contains(what), "{detail} names {what}");
    }
}

/// The conformity a DCC states for a verdict (a guarded `conditional`
/// split by whether the value lies within the limits).
fn dcc_conformity(e: &Value) -> &'static str {
    let v = e["value"].as_f64().unwrap();
    let within =
        e["min"].as_f64().is_none_or(|m| v >= m) && e["max"].as_f64().is_none_or(|m| v <= m);
    match e["verdict"].as_str().unwrap() {
        "pass" => "pass",
        "fail" => "fail",
        _ if within => "conditionalPass",
        _ => "conditionalFail",
    }
}

/// The DCC of an approved triad, from known orientations and from the
/// gravity magnitude: the administrative data of any calibration's, and
/// every measured element of b and S as si:real in the output's D-SI unit,
/// rounded to its expanded uncertainty (computed here), with each limited
/// element's conformity as the decision gives it.
#[rstest]
#[tokio::test]
async fn an_approved_triad_has_a_dcc(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, lab).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    app.put(
        "/v1/customers/ACME",
        ADMIN,
        &json!({"name": "Acme Navigation GmbH", "due_date_agreed": true}),
    )
    .await;
    for sensor in ["IMU-7", "IMU-G"] {
        app.put(
            &format!("/v1/sensors/{sensor}/item"),
            ADMIN,
            &json!({"manufacturer": "Bosch", "model": "BMI088", "serial": format!("SN-{sensor}"), "customer": "ACME"}),
        )
        .await;
    }
    let stand: Value =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    app.put("/v1/standards/STAND-1", ADMIN, &stand).await;
    for (id, unit, limits) in [
        (
            "IMU-NAV",
            "m/s2",
            json!({"k0": {"min": -0.15, "max": 0.15}, "ki": {"min": 9.7, "max": 9.9}}),
        ),
        (
            "IMU-G",
            "g",
            json!({"k0": {"min": -0.05, "max": 0.05}, "kp": {"min": -0.02, "max": 0.02}}),
        ),
    ] {
        super::triads::guarded_type(&app, id, unit, &limits).await;
    }
    let mut known = super::triad::known_body();
    known["sensor_type"] = json!("IMU-NAV");
    known["performed_at"] = json!("2026-10-01T08:00:00Z");
    known["standards"] = json!({"stand": "STAND-1"});
    let gravity = json!({"sensor_id": "IMU-G", "unit": "g", "sensor_type": "IMU-G",
        "performed_at": "2026-10-02T08:00:00Z", "stand": {"gravity_rel_std": 2e-5},
        "static_positions": super::triad::gravity_positions(20, 0x5eed_0000_dcc0_0001)});
    for (body, unit, elements) in [
        (
            known,
            r"\metre\second\tothe{-2}",
            vec![
                "b_x", "b_y", "b_z", "S_xx", "S_xy", "S_xz", "S_yx", "S_yy", "S_yz", "S_zx",
                "S_zy", "S_zz",
            ],
        ),
        (
            gravity,
            "|g",
            vec![
                "b_x", "b_y", "b_z", "S_xx", "S_yx", "S_yy", "S_zx", "S_zy", "S_zz",
            ],
        ),
    ] {
        let res = app.post("/v1/calibrations/triad", ADMIN, &body).await;
        assert_eq!(res.status(), StatusCode::CREATED);
        let stored: Value = res.json().await.unwrap();
        let id = stored["id"].as_str().unwrap().to_owned();
        let sensor = stored["sensor_id"].as_str().unwrap();
        // Submitted: refused, naming the state; approved: issued.
        let p = problem(dcc(&app, &id, ADMIN).await, StatusCode::CONFLICT).await;
        assert!(p["detail"].as_str().unwrap().contains("submitted"), "{p}");
        let res = app
            .post(
                &format!("/v1/calibrations/{id}/review"),
                &rita,
                &json!({"decision": "approve"}),
            )
            .await;
        assert_eq!(res.status(), StatusCode::OK);
        let res = dcc(&app, &id, ADMIN).await;
        assert_eq!(res.status(), StatusCode::OK);
        assert_eq!(
            res.headers()["content-disposition"],
            format!("inline; filename=\"dcc-{id}.xml\"").as_str()
        );
        let xml = res.text().await.unwrap();
        validate_if_asked(&xml);
        let doc = roxmltree::Document::parse(&xml).expect("well-formed XML");
        let root = doc.root_element();
        let admin = assert_shape(root);
        let core = child(admin, "coreData");
        assert_eq!(text_of(core, &["uniqueIdentifier"]), id);
        assert_eq!(
            text_of(core, &["beginPerformanceDate"]),
            stored["performed_at"].as_str().unwrap()[..10]
        );
        let item = child(child(admin, "items"), "item");
        assert!(
            text_of(item, &["name", "content"]).starts_with("Accelerometer triad Bosch BMI088"),
            "{}",
            text_of(item, &["name", "content"])
        );
        assert_all_statements(admin);
        let due = kids(child(admin, "statements"))[3];
        assert_eq!(
            text_of(due, &["date"]),
            stored["due_at"].as_str().unwrap()[..10]
        );
        let decided = stored["decision"]["elements"].as_object().unwrap();
        let worst = decided
            .values()
            .map(dcc_conformity)
            .max_by_key(|c| {
                ["pass", "conditionalPass", "conditionalFail", "fail"]
                    .iter()
                    .position(|x| x == c)
            })
            .unwrap();
        assert_eq!(
            text_of(kids(child(admin, "statements"))[2], &["conformity"]),
            worst
        );

        let mr = child(child(root, "measurementResults"), "measurementResult");
        assert_eq!(
            text_of(mr, &["name", "content"]),
            "Static model of the accelerometer triad"
        );
        let quantities = kids(child(child(child(mr, "results"), "result"), "data"));
        let labels: Vec<String> = quantities
            .iter()
            .map(|q| text_of(*q, &["real", "label"]))
            .collect();
        assert_eq!(labels, elements, "{sensor}");
        for q in &quantities {
            let real = child(*q, "real");
            let name = text_of(real, &["label"]);
            let (matrix, at) = name.split_once('_').unwrap();
            let index = |c: char| "xyz".find(c).unwrap();
            let mut chars = at.chars();
            let m = index(chars.next().unwrap());
            let (v, u) = match chars.next() {
                None => (&stored[matrix][m], &stored[format!("{matrix}_expanded")][m]),
                Some(c) => (
                    &stored[matrix][m][index(c)],
                    &stored[format!("{matrix}_expanded")][m][index(c)],
                ),
            };
            let (v, u) = (v.as_f64().unwrap(), u.as_f64().unwrap());
            assert!(u > 0.0, "{name}");
            let decimals = (1 - u.log10().floor() as i32).max(0) as usize;
            assert_eq!(text_of(real, &["unit"]), unit);
            assert_eq!(
                text_of(real, &["value"]),
                format!("{v:.decimals$}"),
                "{name}"
            );
            let mu = child(
                child(real, "measurementUncertaintyUnivariate"),
                "expandedMU",
            );
            assert_eq!(
                text_of(mu, &["valueExpandedMU"]),
                format!("{u:.decimals$}"),
                "{name}"
            );
            // The element's own k and p, as the stored triad states them.
            let c = &stored["coverage"][&name];
            assert_eq!(
                text_of(mu, &["coverageFactor"]),
                format!("{}", c["coverage_factor"].as_f64().unwrap()),
                "{name}"
            );
            assert_eq!(
                text_of(mu, &["coverageProbability"]),
                format!("{:.4}", c["coverage_probability"].as_f64().unwrap()),
                "{name}"
            );
            // A judged element carries its conformity beside its coverage.
            let metas = kids(child(*q, "measurementMetaData"));
            assert!(
                text_of(metas[0], &["declaration", "content"]).contains(&format!(
                    "ν_eff = {} ",
                    c["effective_dof"].as_u64().unwrap()
                )),
                "{name}"
            );
            match decided.get(&name) {
                Some(e) => assert_eq!(conformity_of(*q), dcc_conformity(e), "{name}"),
                None => assert_eq!(metas.len(), 1, "{name}: no conformity"),
            }
        }
        // Known orientations name the stand among the equipment.
        let equipment = kids(mr)
            .into_iter()
            .any(|n| n.tag_name().name() == "measuringEquipments");
        assert_eq!(equipment, sensor == "IMU-7");
    }
}
