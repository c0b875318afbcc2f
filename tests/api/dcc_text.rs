//! XML is always XML (issue 43 item 2). Every free-text field refuses the
//! characters XML 1.0 cannot carry (U+FFFE, U+FFFF and the controls) with a
//! 422 naming the field and the character, JSON and CSV alike; and random
//! Unicode that is accepted — markup characters, `]]>`, astral planes,
//! combining marks — in every free-text field a DCC prints gives a
//! well-formed DCC in the schema's structure that carries the text as sent.

use proptest::prelude::*;
use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

use super::dcc::{dcc, lab};

/// A standard of `description`, `issued_by` and `traceability`.
fn stand(description: &str, issued_by: &str, traceability: &str) -> Value {
    let mut s: Value =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    s["description"] = json!(description);
    s["certificate"]["issued_by"] = json!(issued_by);
    s["traceability"] = json!(traceability);
    s
}

#[tokio::test]
async fn every_free_text_field_refuses_what_xml_cannot_carry() {
    let app = TestApp::configured(Sqlite, lab).await;
    let reviewer = app.token("reviewer", None).await;
    let paper = || submission("TXT-1", "2026-06-01T08:00:00Z", 4);
    let with = |mut body: Value, pointer: &str, v: &str| {
        *body
            .pointer_mut(pointer)
            .unwrap_or_else(|| panic!("{pointer}")) = json!(v);
        body
    };
    let mut nav: Value =
        serde_json::from_str(include_str!("../../examples/sensor-type-nav.json")).unwrap();
    nav["label"] = json!("Navigation grade");
    nav["unit"] = json!("mA");
    let mut triad = super::triad::known_body();
    triad["unit"] = json!("mA");
    let mut labelled = paper();
    labelled["positions"][0]["label"] = json!("up");
    labelled["notes"] = json!("n");
    labelled["item_condition"] = json!("c");
    // (path, method, body, the pointer the refusal names)
    let cases: Vec<(&str, &str, Value, &str)> = vec![
        (
            "/v1/calibrations",
            "POST",
            with(labelled.clone(), "/unit", "m\u{fffe}A"),
            "/unit",
        ),
        (
            "/v1/calibrations",
            "POST",
            with(labelled.clone(), "/notes", "ok\u{ffff}"),
            "/notes",
        ),
        (
            "/v1/calibrations",
            "POST",
            with(labelled.clone(), "/item_condition", "\u{fffe}"),
            "/item_condition",
        ),
        (
            "/v1/calibrations",
            "POST",
            with(labelled, "/positions/0/label", "up\u{ffff}"),
            "/positions/0/label",
        ),
        (
            "/v1/calibrations/triad",
            "POST",
            with(triad, "/unit", "m\u{fffe}A"),
            "/unit",
        ),
        (
            "/v1/customers/C1",
            "PUT",
            json!({"name": "Acme\u{fffe}"}),
            "/name",
        ),
        (
            "/v1/customers/C1",
            "PUT",
            json!({"name": "Acme", "address": "x\u{ffff}"}),
            "/address",
        ),
        (
            "/v1/sensors/TXT-1/item",
            "PUT",
            json!({"manufacturer": "H\u{fffe}"}),
            "/manufacturer",
        ),
        (
            "/v1/sensors/TXT-1/item",
            "PUT",
            json!({"model": "Q\u{fffe}"}),
            "/model",
        ),
        (
            "/v1/sensors/TXT-1/item",
            "PUT",
            json!({"serial": "S\u{ffff}"}),
            "/serial",
        ),
        (
            "/v1/sensor-types/T1",
            "PUT",
            with(nav.clone(), "/label", "L\u{fffe}"),
            "/label",
        ),
        (
            "/v1/sensor-types/T1",
            "PUT",
            with(nav, "/unit", "m\u{ffff}A"),
            "/unit",
        ),
        (
            "/v1/standards/S1",
            "PUT",
            stand("d\u{fffe}", "NMI", "t"),
            "/description",
        ),
        (
            "/v1/standards/S1",
            "PUT",
            stand("d", "NMI\u{ffff}", "t"),
            "/certificate/issued_by",
        ),
        (
            "/v1/standards/S1",
            "PUT",
            stand("d", "NMI", "t\u{fffe}"),
            "/traceability",
        ),
        (
            "/v1/tokens",
            "POST",
            json!({"role": "reader", "holder": "Rita\u{fffe}"}),
            "/holder",
        ),
        (
            "/v1/tokens",
            "POST",
            json!({"role": "reader", "label": "l\u{ffff}"}),
            "/label",
        ),
    ];
    for (path, method, body, pointer) in cases {
        let res = match method {
            "PUT" => app.put(path, ADMIN, &body).await,
            _ => app.post(path, ADMIN, &body).await,
        };
        let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(pointers(&p), [pointer], "{path}: {p}");
        let detail = p["errors"][0]["detail"].as_str().unwrap();
        assert!(
            detail.contains("U+FFFE") || detail.contains("U+FFFF"),
            "{path}: {p}"
        );
    }
    // The CSV form: its unit and item condition lines.
    for (line, pointer) in [
        ("# unit: m\u{fffe}A", "unit"),
        ("# item_condition: ok\u{ffff}", "item_condition"),
    ] {
        let csv = format!(
            "# sensor_id: TXT-2\n{line}\nrun,angle_deg,output\n1,0,1\n1,90,2\n1,180,1\n1,270,0\n"
        );
        let res = app
            .client
            .post(app.url("/v1/calibrations"))
            .bearer_auth(ADMIN)
            .header(reqwest::header::CONTENT_TYPE, "text/csv")
            .body(csv)
            .send()
            .await
            .unwrap();
        let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
        let text = p.to_string();
        assert!(
            text.contains(pointer) && (text.contains("U+FFFE") || text.contains("U+FFFF")),
            "{p}"
        );
    }
    // A reviewer's comment.
    let stored = app.submit(ADMIN, &paper()).await;
    let review = format!("/v1/calibrations/{}/review", stored["id"].as_str().unwrap());
    let res = app
        .post(
            &review,
            &reviewer,
            &json!({"decision": "approve", "comment": "fine\u{fffe}"}),
        )
        .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(pointers(&p), ["/comment"], "{p}");
    assert!(p.to_string().contains("U+FFFE"), "{p}");
    // Nothing refused was stored.
    for path in [
        "/v1/customers/C1",
        "/v1/sensor-types/T1",
        "/v1/standards/S1",
    ] {
        let res = app.get(path, ADMIN).await;
        assert_eq!(res.status(), StatusCode::NOT_FOUND, "{path}");
    }
}

/// Text a station or an admin may send: any character XML carries but
/// the controls, weighted towards markup (`<`, `&`, `]]>`, quotes), with
/// astral and combining characters; it starts and ends with a letter, so
/// that no field's trimming applies.
fn free_text() -> impl Strategy<Value = String> {
    let piece = prop_oneof![
        3 => any::<char>().prop_map(String::from),
        1 => prop::sample::select(vec!["<", ">", "&", "]]>", "\"", "'", "&amp;", "<!--", "\u{301}", "𝔤", "\u{fffd}", "\t"]).prop_map(String::from),
    ];
    prop::collection::vec(piece, 0..10).prop_map(|pieces| {
        let inner: String = pieces
            .concat()
            .chars()
            .filter(|c| !c.is_control() && !matches!(c, '\u{fffe}' | '\u{ffff}'))
            .take(20)
            .collect();
        format!("a{inner}z")
    })
}

/// The DCC's element `path` (local names) below `node`.
fn at<'a>(node: roxmltree::Node<'a, 'a>, path: &[&str]) -> roxmltree::Node<'a, 'a> {
    path.iter().fold(node, |n, p| {
        n.children()
            .find(|c| c.is_element() && c.tag_name().name() == *p)
            .unwrap_or_else(|| panic!("no <{p}> in <{}>", n.tag_name().name()))
    })
}

/// The text of every element below `node` named `name`, in order.
fn texts(node: roxmltree::Node, name: &str) -> Vec<String> {
    node.descendants()
        .filter(|n| n.is_element() && n.tag_name().name() == name)
        .map(|n| n.text().unwrap_or("").to_owned())
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// Random accepted text in every free-text field the DCC prints.
    #[test]
    fn any_accepted_text_gives_a_well_formed_dcc(
        customer in free_text(), address in free_text(), manufacturer in free_text(),
        model in free_text(), serial in free_text(), condition in free_text(),
        unit in free_text(), holder in free_text(), comment in free_text(),
        description in free_text(), issued_by in free_text(), traceability in free_text(),
    ) {
        let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
        rt.block_on(async {
            let app = TestApp::configured(Sqlite, lab).await;
            let reviewer = app.held_token("reviewer", &holder, None).await;
            app.put("/v1/customers/C1", ADMIN, &json!({"name": customer, "address": address})).await;
            app.put(
                "/v1/sensors/TXT-1/item",
                ADMIN,
                &json!({"manufacturer": manufacturer, "model": model, "serial": serial, "customer": "C1"}),
            )
            .await;
            let res = app.put("/v1/standards/STAND-1", ADMIN, &stand(&description, &issued_by, &traceability)).await;
            assert!(res.status().is_success(), "{}", res.text().await.unwrap());
            let mut body = submission("TXT-1", "2026-06-01T08:00:00Z", 4);
            body["unit"] = json!(unit);
            body["item_condition"] = json!(condition);
            body["standards"] = json!({"stand": "STAND-1"});
            let stored = app.submit(ADMIN, &body).await;
            let id = stored["id"].as_str().unwrap();
            let res = app
                .post(&format!("/v1/calibrations/{id}/review"), &reviewer, &json!({"decision": "approve", "comment": comment}))
                .await;
            assert_eq!(res.status(), StatusCode::OK);
            let xml = dcc(&app, id, ADMIN).await.text().await.unwrap();
            let doc = roxmltree::Document::parse(&xml).unwrap_or_else(|e| panic!("{e}: {xml}"));
            let root = doc.root_element();
            let admin = at(root, &["administrativeData"]);
            let kids: Vec<&str> = admin.children().filter(|n| n.is_element()).map(|n| n.tag_name().name()).collect();
            assert_eq!(kids, ["dccSoftware", "coreData", "items", "calibrationLaboratory", "respPersons", "customer", "statements"]);
            // The text comes back as sent, where the DCC prints it alone.
            assert_eq!(at(admin, &["customer", "name", "content"]).text(), Some(customer.as_str()));
            assert_eq!(at(admin, &["customer", "location", "further", "content"]).text(), Some(address.as_str()));
            let item = at(admin, &["items", "item"]);
            assert_eq!(at(item, &["manufacturer", "name", "content"]).text(), Some(manufacturer.as_str()));
            assert_eq!(at(item, &["model"]).text(), Some(model.as_str()));
            assert!(texts(item, "value").contains(&serial), "{xml}");
            assert_eq!(at(item, &["description", "content"]).text(), Some(format!("Condition on receipt: {condition}").as_str()));
            assert_eq!(at(admin, &["respPersons", "respPerson", "person", "name", "content"]).text(), Some(holder.as_str()));
            let signed = at(admin, &["respPersons", "respPerson", "description", "content"]).text().unwrap();
            assert!(signed.ends_with(&format!(": {comment}")), "{signed}");
            let results = at(root, &["measurementResults", "measurementResult"]);
            let equipment = at(results, &["measuringEquipments", "measuringEquipment"]);
            assert!(at(equipment, &["name", "content"]).text().unwrap().ends_with(&format!(": {description}")));
            assert!(texts(equipment, "content").iter().any(|t| t.ends_with(&traceability)), "{xml}");
            // A unit D-SI does not know is written as `|` and the unit's
            // text without white space.
            let plain: String = unit.chars().filter(|c| !c.is_whitespace()).collect();
            for u in texts(at(results, &["results"]), "unit") {
                assert_eq!(u, format!("|{plain}"));
            }
        });
    }
}
