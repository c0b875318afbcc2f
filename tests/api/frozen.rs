//! Issued certificates are frozen (issue 42 item 3): the certificate issued
//! with the approval — HTML and DCC — is answered as issued, byte for byte,
//! after the item, the customer and the laboratory's flags change; the
//! approval's audit entry carries both documents' SHA-256; changing what it
//! says is an amendment, a new revision, and every revision is retrievable.

use reqwest::StatusCode;
use reqwest::header::ACCEPT;
use rstest::rstest;
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

fn lab(name: &str) -> impl FnOnce(&mut accelcal::startup::Config) {
    let name = name.to_owned();
    move |c| {
        c.web.laboratory = accelcal::startup::Laboratory {
            name: Some(name),
            address: Some("Bahnhofstrasse 1, 8001 Zürich".into()),
            country: Some("CH".into()),
            accreditation: Some("SAS SCS 0999".into()),
            logo: None,
        };
        c.web.public_url = Some("https://calibration.example".into());
    }
}

fn sha(bytes: &[u8]) -> String {
    hex::encode(Sha256::digest(bytes))
}

/// The certificate (HTML or DCC) of `id`, at `query`: status, revision
/// header, body.
pub(crate) async fn fetch(
    app: &TestApp,
    id: &str,
    query: &str,
    xml: bool,
) -> (StatusCode, String, String) {
    let mut req = app
        .client
        .get(app.url(&format!("/v1/calibrations/{id}/certificate{query}")))
        .bearer_auth(ADMIN);
    if xml {
        req = req.header(ACCEPT, "application/xml");
    }
    let res = req.send().await.unwrap();
    let status = res.status();
    let revision = res
        .headers()
        .get("certificate-revision")
        .map(|v| v.to_str().unwrap().to_owned())
        .unwrap_or_default();
    (status, revision, res.text().await.unwrap())
}

#[rstest]
#[tokio::test]
async fn an_issued_certificate_stays_as_issued_until_amended(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let mut app = TestApp::configured(engine, lab("Inertial Test Lab")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let customer =
        |name: &str| json!({"name": name, "address": "1 Gyro Way", "due_date_agreed": true});
    let item = |serial: &str| json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": serial, "customer": "ACME"});
    assert!(
        app.put(
            "/v1/customers/ACME",
            ADMIN,
            &customer("Acme Navigation GmbH")
        )
        .await
        .status()
        .is_success()
    );
    assert!(
        app.put("/v1/sensors/FRZ-1/item", ADMIN, &item("QA-12345"))
            .await
            .status()
            .is_success()
    );
    let c = app
        .submit(ADMIN, &submission("FRZ-1", "2026-06-01T08:00:00Z", 4))
        .await;
    let id = c["id"].as_str().unwrap().to_owned();

    // Before approval: a draft, and no DCC.
    let (status, revision, draft) = fetch(&app, &id, "", false).await;
    assert_eq!((status, revision.as_str()), (StatusCode::OK, "draft"));
    assert!(draft.contains("Not reviewed"));
    assert_eq!(fetch(&app, &id, "", true).await.0, StatusCode::CONFLICT);

    // Approved: issued, revision 1, and the approval's entry vouches for it.
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/review"),
            &rita,
            &json!({"decision": "approve"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let (status, revision, html) = fetch(&app, &id, "", false).await;
    assert_eq!((status, revision.as_str()), (StatusCode::OK, "1"));
    let (status, _, dcc) = fetch(&app, &id, "", true).await;
    assert_eq!(status, StatusCode::OK);
    for text in [
        "QA-12345",
        "Acme Navigation GmbH",
        "Inertial Test Lab",
        "Rita Reviewer",
    ] {
        assert!(html.contains(text) && dcc.contains(text), "{text}");
    }
    let approve = app
        .trail_entry(&format!("calibrations/{id}"), "calibration.approve")
        .await;
    let change = &approve["change"];
    assert_eq!(change["certificate"]["revision"], 1);
    assert_eq!(change["certificate"]["html_sha256"], sha(html.as_bytes()));
    assert_eq!(change["certificate"]["dcc_sha256"], sha(dcc.as_bytes()));

    // The item and the customer change: the issued certificate does not.
    assert_eq!(
        app.put("/v1/sensors/FRZ-1/item", ADMIN, &item("QA-99999"))
            .await
            .status(),
        StatusCode::OK
    );
    assert_eq!(
        app.put("/v1/customers/ACME", ADMIN, &customer("Acme Renamed AG"))
            .await
            .status(),
        StatusCode::OK
    );
    assert_eq!(fetch(&app, &id, "", false).await.2, html);
    assert_eq!(fetch(&app, &id, "", true).await.2, dcc);

    // A restart with another laboratory name: the same, and the trail says
    // the laboratory changed.
    app.stop().await;
    let db = app.take_database().unwrap();
    let mut config = accelcal::startup::Config::for_tests(&db.url, ADMIN);
    lab("Inertial Test Lab Renamed")(&mut config);
    let mut app = TestApp::spawn_with(config).await;
    assert_eq!(fetch(&app, &id, "", false).await.2, html);
    assert_eq!(fetch(&app, &id, "", true).await.2, dcc);
    let configured = app.get_json("/v1/audit?object=service", ADMIN).await;
    let last = configured["items"]
        .as_array()
        .unwrap()
        .last()
        .unwrap()
        .clone();
    assert_eq!(last["action"], "service.configure");
    assert!(
        last["change"]
            .to_string()
            .contains("Inertial Test Lab Renamed"),
        "{last}"
    );

    // Amended: revision 2 with today's facts, marked, its reason; both
    // revisions retrievable, revision 1 unchanged.
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/amend"),
            &rita,
            &json!({"reason": "The item's serial number was corrected."}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    assert_eq!(
        res.headers()["location"],
        format!("/v1/calibrations/{id}/certificate?revision=2").as_str()
    );
    let amended: Value = res.json().await.unwrap();
    assert_eq!(amended["revision"], 2);
    let (_, revision, html2) = fetch(&app, &id, "", false).await;
    assert_eq!(revision, "2");
    assert!(html2.contains(&format!("Amendment 1 to certificate No. <code>{id}</code>")));
    assert!(
        html2.contains("The item&#x27;s serial number was corrected.")
            || html2.contains("The item's serial number was corrected.")
    );
    for text in ["QA-99999", "Acme Renamed AG", "Inertial Test Lab Renamed"] {
        assert!(html2.contains(text), "{text}");
    }
    let (_, _, dcc2) = fetch(&app, &id, "?revision=2", true).await;
    assert_eq!(amended["html_sha256"], sha(html2.as_bytes()));
    assert_eq!(amended["dcc_sha256"], sha(dcc2.as_bytes()));
    assert!(
        dcc2.contains("<dcc:typeOfChange>amended</dcc:typeOfChange>"),
        "{dcc2}"
    );
    assert!(dcc2.contains(&format!(
        "<dcc:uniqueIdentifier>{id}-A1</dcc:uniqueIdentifier>"
    )));
    assert_eq!(fetch(&app, &id, "?revision=1", false).await.2, html);
    assert_eq!(fetch(&app, &id, "?revision=1", true).await.2, dcc);
    assert_eq!(
        fetch(&app, &id, "?revision=3", false).await.0,
        StatusCode::NOT_FOUND
    );
    assert_eq!(
        fetch(&app, &id, "?revision=0", false).await.0,
        StatusCode::BAD_REQUEST
    );
    let trail = app
        .get_json(&format!("/v1/audit?object=calibrations/{id}"), ADMIN)
        .await;
    assert!(
        trail["items"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["action"] == "certificate.amend"),
        "{trail}"
    );

    // Withdrawn: the issued document, with the notice before it.
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/withdraw"),
            &rita,
            &json!({"reason": "the stand was misaligned"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let (_, _, withdrawn) = fetch(&app, &id, "?revision=1", false).await;
    assert!(withdrawn.contains("WITHDRAWN"), "the notice");
    let start = withdrawn
        .find("<div class=\"cert-withdrawn\" role=\"status\" data-added")
        .unwrap();
    let end = start + withdrawn[start..].find("</div>").unwrap() + 6;
    let header =
        &withdrawn[withdrawn.find("<thead>").unwrap()..withdrawn.find("</thead>").unwrap()];
    assert!(
        header.contains("the stand was misaligned"),
        "on every printed page"
    );
    assert_eq!(
        format!("{}{}", &withdrawn[..start], &withdrawn[end..]),
        html
    );
    // No amendment of a withdrawn calibration's certificate.
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/amend"),
            &rita,
            &json!({"reason": "again"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CONFLICT);
    app.stop().await;
}

/// A calibration approved before certificates were issued at approval (its
/// approval signed directly in the store): issued at its first request, once,
/// and recorded in the trail.
#[rstest]
#[tokio::test]
async fn an_approval_from_before_is_issued_at_the_first_request(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::configured(engine, lab("Inertial Test Lab")).await;
    let c = app
        .submit(ADMIN, &submission("OLD-1", "2026-06-01T08:00:00Z", 4))
        .await;
    let id = c["id"].as_str().unwrap().to_owned();
    let store = accelcal::store::open(&app.db().url).await.unwrap();
    let act = accelcal::domain::review::Act {
        action: accelcal::domain::review::Action::Approve,
        signer: accelcal::domain::auth::Principal {
            id: "old-reviewer".into(),
            role: accelcal::domain::auth::Role::Reviewer,
            station_id: None,
            holder: Some("Olga Old".into()),
        },
        at: accelcal::domain::timestamp::Timestamp::now(),
        comment: None,
        superseded_by: None,
    };
    store
        .sign(uuid::Uuid::parse_str(&id).unwrap(), act)
        .await
        .unwrap();
    store.close().await;
    let first = fetch(&app, &id, "", false).await;
    assert_eq!((first.0, first.1.as_str()), (StatusCode::OK, "1"));
    assert!(first.2.contains("Olga Old"));
    let again = fetch(&app, &id, "", false).await;
    assert_eq!(again.2, first.2);
    let trail = app
        .get_json(&format!("/v1/audit?object=calibrations/{id}"), ADMIN)
        .await;
    let issued: Vec<&Value> = trail["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["action"] == "certificate.issue")
        .collect();
    assert_eq!(issued.len(), 1);
    assert_eq!(issued[0]["change"]["html_sha256"], sha(first.2.as_bytes()));
}
