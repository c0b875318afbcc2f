//! `accelcal audit verify`: the chain, and every row the service serves or
//! acts on, against it (issue 42 item 4).
//!
//! **The chain** is checked entry by entry ([`crate::domain::audit::Chain`]):
//! an edited, inserted or deleted entry breaks it, and is named.
//!
//! **The rows.** The entries are replayed ([`expected`]) into what each
//! protected row must be, and every row is read back and compared:
//!
//! | table | covered by |
//! |---|---|
//! | calibrations | its `calibration.submitted`: the SHA-256 of its submission, its result and its served columns (coefficients, standard errors, expanded uncertainties, a triad's elements, verdict, due date, sensor, station, unit, model, times, type) in canonical form; an entry from before that recorded no columns' digest, every served column recomputed from the result and compared bit for bit; its submitter and media type |
//! | signatures (approvals, holds, dispositions, …) | each calibration's signature entries, in order: act, state, meaning, comment, replacement, signer, time |
//! | issued certificates | the digests the approval's or the amendment's entry recorded, and the stored documents against them |
//! | standards (and their certificates), customers, items, sensor types | the definition of the object's last `{kind}.put` |
//! | tokens | `token.create` (role, station, label, holder, the SHA-256 of the secret's hash) and `token.revoke` |
//! | nonconformities and the calibrations they hold | `standard.nonconformity` (dates, reason, the calibrations concerned) and the holds placed as calibrations were stored |
//! | sensors | recomputed from the calibrations and their states (count, first and latest, the latest's verdict and due date), and the type from the entries that assigned one |
//!
//! A row the trail holds nothing of is reported as *unaudited*: inserted
//! behind the service's back — or stored before the trail existed (a
//! database older than its migration 13/10), which `accelcal audit adopt`
//! records once, by its operator ([`adoption`]). Sessions and idempotency
//! keys are not covered: they serve nothing a certificate or a control
//! system reads.

mod calibrations;
pub mod expected;
pub mod rows;

use std::collections::HashSet;

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;
use sha2::{Digest, Sha256};
use uuid::Uuid;

use super::{AuditQuery, Store, StoreError};
use crate::domain::audit::{self, Actor, Event};
use crate::domain::review::State;
use crate::domain::timestamp::Timestamp;
use expected::Expected;
pub use rows::Finding;

/// What [`verify`] found in an intact trail.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Verified {
    /// Entries checked.
    pub entries: i64,
    /// The last entry's sequence number (0 for an empty trail).
    pub head_seq: i64,
    /// The last entry's hash: what to keep elsewhere, so that a trail cut
    /// short can be told from this one.
    pub head_hash: String,
    /// Calibrations whose stored submission and result were checked
    /// against the SHA-256 their `calibration.submitted` entry recorded.
    pub calibrations: i64,
    /// The rows checked against the trail, by table.
    pub rows: std::collections::BTreeMap<&'static str, usize>,
    /// Entries of acts committed while the check ran, not yet sealed into
    /// the chain (PostgreSQL: [`crate::store::Audit::unsealed`]); the check
    /// sealed everything committed before it began.
    pub unsealed: i64,
}

/// Why [`verify`] failed.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// The database could not be read.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The chain does not hold at an entry.
    #[error(transparent)]
    Broken(#[from] audit::Broken),
    /// Rows that do not hold: edited, inserted or deleted behind the
    /// service's back (or never audited).
    #[error("{} row(s) do not hold: {}", .0.len(), summary(.0))]
    Rows(Vec<Finding>),
}

fn summary(findings: &[Finding]) -> String {
    let mut parts: Vec<String> = findings
        .iter()
        .take(20)
        .map(|f| format!("{} {}: {}", f.table, f.object, f.why))
        .collect();
    if findings.len() > 20 {
        parts.push(format!("… and {} more", findings.len() - 20));
    }
    parts.join("; ")
}

/// Entries read per round trip.
const PAGE: usize = 1000;

fn sha256(bytes: &[u8]) -> String {
    hex::encode(Sha256::digest(bytes))
}

/// Checks the chain, then every protected row against it.
pub async fn verify(store: &dyn Store) -> Result<Verified, VerifyError> {
    let (verified, expected) = chain(store).await?;
    let mut c = Check {
        store,
        expected,
        findings: Vec::new(),
        rows: Default::default(),
    };
    c.calibrations().await?;
    c.definitions().await?;
    c.tokens().await?;
    c.nonconformities().await?;
    if c.findings.is_empty() {
        Ok(Verified {
            rows: c.rows,
            unsealed: store.unsealed().await?,
            ..verified
        })
    } else {
        Err(VerifyError::Rows(c.findings))
    }
}

/// The chain checked, the calibrations' stored bytes against their
/// entries, and what the entries vouch for.
async fn chain(store: &dyn Store) -> Result<(Verified, Expected), VerifyError> {
    let mut chain = audit::Chain::default();
    let mut expected = Expected::default();
    let mut calibrations = 0;
    loop {
        let page = store
            .audit(AuditQuery {
                after: chain.head.0,
                limit: PAGE,
                ..AuditQuery::default()
            })
            .await?;
        if page.is_empty() {
            break;
        }
        for e in &page {
            chain.check(e)?;
            expected.take(e);
            if e.action == "calibration.submitted" {
                check_stored(store, e).await?;
                calibrations += 1;
            }
        }
    }
    let verified = Verified {
        entries: chain.head.0,
        head_seq: chain.head.0,
        head_hash: chain.head.1,
        calibrations,
        rows: Default::default(),
        unsealed: 0,
    };
    Ok((verified, expected))
}

/// Checks the calibration of a `calibration.submitted` entry against the
/// digests it recorded.
async fn check_stored(store: &dyn Store, e: &audit::Entry) -> Result<(), VerifyError> {
    let broken = |why: String| audit::Broken { seq: e.seq, why };
    let id = e
        .object
        .strip_prefix("calibrations/")
        .and_then(|id| Uuid::try_parse(id).ok())
        .ok_or_else(|| broken(format!("its object {} is not a calibration", e.object)))?;
    let change: Value =
        serde_json::from_str(&e.change).map_err(|_| broken("its change is not JSON".into()))?;
    let recorded = |field: &str| change.get(field).and_then(Value::as_str).map(str::to_owned);
    let submission = store.submission(id).await?;
    let result = store.calibration_result(id).await?;
    let (Some(submission), Some(result)) = (submission, result) else {
        return Err(broken(format!("calibration {id} is no longer stored (deleted)")).into());
    };
    if recorded("submission_sha256") != Some(sha256(&submission.body)) {
        return Err(broken(format!(
            "calibration {id}'s stored submission is not the one recorded (edited)"
        ))
        .into());
    }
    if recorded("result_sha256") != Some(sha256(&result)) {
        return Err(broken(format!(
            "calibration {id}'s stored result is not the one recorded (edited)"
        ))
        .into());
    }
    Ok(())
}

/// One calibration of a sensor, as its sensor's row is recomputed from.
struct Counted {
    id: Uuid,
    performed_at: Timestamp,
    state: State,
    verdict: Option<accelcal_core::decision::Verdict>,
    due_at: Option<Timestamp>,
}

/// The row checks, collecting findings.
struct Check<'a> {
    store: &'a dyn Store,
    expected: Expected,
    findings: Vec<Finding>,
    rows: std::collections::BTreeMap<&'static str, usize>,
}

impl Check<'_> {
    fn find(&mut self, table: &'static str, object: String, why: impl Into<String>) {
        self.findings.push(Finding {
            table,
            object,
            why: why.into(),
            unaudited: false,
        });
    }

    fn unaudited(&mut self, table: &'static str, object: String) {
        self.findings.push(Finding {
            table,
            object,
            why: "no audit entry: inserted behind the service's back, or stored before the \
                  trail (accelcal audit adopt)"
                .into(),
            unaudited: true,
        });
    }

    fn count(&mut self, table: &'static str) {
        *self.rows.entry(table).or_default() += 1;
    }

    /// Whether the adopted digest of `object` is `d`; `None` when it was
    /// not adopted.
    fn adopted(&self, object: &str, d: &str) -> Option<bool> {
        self.expected.adopted.get(object).map(|a| a == d)
    }

    /// Every definition against its last `{kind}.put`.
    async fn definitions(&mut self) -> Result<(), StoreError> {
        let standards = self.store.standards().await?;
        self.each("standards", "standards/", standards, |s| {
            s.standard_id.clone()
        });
        let customers = self.store.customers().await?;
        self.each("customers", "customers/", customers, |c| {
            c.customer_id.clone()
        });
        let items = self.store.items().await?;
        self.each("items", "items/", items, |i| i.sensor_id.clone());
        let types = self.store.sensor_types().await?;
        self.each("sensor_types", "sensor-types/", types, |t| {
            t.type_id.clone()
        });
        Ok(())
    }

    fn each<T: Serialize + DeserializeOwned + PartialEq>(
        &mut self,
        table: &'static str,
        prefix: &str,
        found: Vec<T>,
        id: impl Fn(&T) -> String,
    ) {
        let mut seen = HashSet::new();
        for r in found {
            self.count(table);
            let object = format!("{prefix}{}", id(&r));
            seen.insert(object.clone());
            match self.expected.definitions.get(&object) {
                Some(d) => {
                    if serde_json::from_value::<T>(d.clone()).ok().as_ref() != Some(&r) {
                        self.find(
                            table,
                            object,
                            "not the definition its last audit entry recorded (edited)",
                        );
                    }
                }
                None => match self.adopted(&object, &rows::digest(&r)) {
                    Some(true) => {}
                    Some(false) => self.find(table, object, "not the row adopted (edited)"),
                    None => self.unaudited(table, object),
                },
            }
        }
        let missing: Vec<String> = self
            .expected
            .definitions
            .keys()
            .filter(|k| k.starts_with(prefix) && !seen.contains(*k))
            .cloned()
            .collect();
        for object in missing {
            self.find(table, object, "recorded in the trail, not stored (deleted)");
        }
    }

    /// Every token against `token.create` and `token.revoke`.
    async fn tokens(&mut self) -> Result<(), StoreError> {
        for t in self.store.tokens().await? {
            self.count("tokens");
            let id = t.id.to_string();
            let object = format!("tokens/{id}");
            let Some(e) = self.expected.tokens.get(&id).cloned() else {
                match self.adopted(&object, &rows::digest(&token_form(&t))) {
                    Some(true) => {}
                    Some(false) => self.find("tokens", object, "not the row adopted (edited)"),
                    None => self.unaudited("tokens", object),
                }
                continue;
            };
            let Some(c) = e.created else {
                self.unaudited("tokens", object);
                continue;
            };
            let text = |k: &str| c.get(k).and_then(Value::as_str).map(str::to_owned);
            let mut off = Vec::new();
            if text("role").as_deref() != Some(t.role.as_str()) {
                off.push("role");
            }
            if text("station_id") != t.station_id {
                off.push("station_id");
            }
            if text("label") != t.label {
                off.push("label");
            }
            if text("holder") != t.holder {
                off.push("holder");
            }
            if let Some(h) = text("secret_hash_sha256")
                && h != sha256(&t.secret_hash)
            {
                off.push("secret");
            }
            if e.revoked_at != t.revoked_at {
                off.push("revoked_at");
            }
            if !off.is_empty() {
                self.find(
                    "tokens",
                    object,
                    format!(
                        "{} not what its audit entries recorded (edited)",
                        off.join(", ")
                    ),
                );
            }
        }
        Ok(())
    }

    /// Every nonconformity, and the calibrations it holds, against its
    /// entry and the holds placed as calibrations were stored.
    async fn nonconformities(&mut self) -> Result<(), StoreError> {
        let mut seen = HashSet::new();
        for standard in self.store.standards().await? {
            for t in self
                .store
                .nonconformities(standard.standard_id.clone())
                .await?
            {
                self.count("nonconformities");
                let nc = &t.nonconformity;
                seen.insert(nc.id);
                let object = format!("standards/{}/nonconformities/{}", nc.standard_id, nc.id);
                let Some((std_id, c)) = self.expected.nonconformities.get(&nc.id).cloned() else {
                    match self.adopted(&object, &rows::digest(&t)) {
                        Some(true) => {}
                        Some(false) => {
                            self.find("nonconformities", object, "not the row adopted (edited)")
                        }
                        None => self.unaudited("nonconformities", object),
                    }
                    continue;
                };
                let text = |k: &str| c.get(k).and_then(Value::as_str);
                let when = |k: &str| text(k).and_then(|t| Timestamp::parse(t).ok());
                let mut off = Vec::new();
                if std_id != nc.standard_id {
                    off.push("standard");
                }
                if when("found_at") != Some(nc.found_at) {
                    off.push("found_at");
                }
                if when("last_known_good_at") != nc.last_known_good_at {
                    off.push("last_known_good_at");
                }
                if when("window_from") != Some(nc.window_from) {
                    off.push("window_from");
                }
                if text("reason") != Some(nc.reason.as_str()) {
                    off.push("reason");
                }
                let mut rows: Vec<(String, String)> = t
                    .calibrations
                    .iter()
                    .map(|a| {
                        (
                            a.calibration_id.to_string(),
                            a.state_found.as_str().to_owned(),
                        )
                    })
                    .collect();
                rows.sort();
                let held = self
                    .expected
                    .held_on_storing
                    .get(&nc.id)
                    .cloned()
                    .unwrap_or_default();
                match c.get("concerned").and_then(Value::as_array) {
                    Some(listed) => {
                        let mut want: Vec<(String, String)> = listed
                            .iter()
                            .filter_map(|x| {
                                Some((
                                    x.get("calibration_id")?.as_str()?.to_owned(),
                                    x.get("state_found")?.as_str()?.to_owned(),
                                ))
                            })
                            .chain(
                                held.iter()
                                    .map(|id| (id.to_string(), "submitted".to_owned())),
                            )
                            .collect();
                        want.sort();
                        if want != rows {
                            off.push("calibrations held");
                        }
                    }
                    // Recorded before the entry listed them: their number.
                    None => {
                        let n = c.get("calibrations").and_then(Value::as_u64).unwrap_or(0) as usize;
                        if n + held.len() != rows.len() {
                            off.push("calibrations held");
                        }
                    }
                }
                if !off.is_empty() {
                    self.find(
                        "nonconformities",
                        object,
                        format!(
                            "{} not what its audit entry recorded (edited)",
                            off.join(", ")
                        ),
                    );
                }
            }
        }
        let missing: Vec<(Uuid, String)> = self
            .expected
            .nonconformities
            .iter()
            .filter(|(id, _)| !seen.contains(*id))
            .map(|(id, (s, _))| (*id, s.clone()))
            .collect();
        for (id, standard) in missing {
            self.find(
                "nonconformities",
                format!("standards/{standard}/nonconformities/{id}"),
                "recorded in the trail, not stored (deleted)",
            );
        }
        Ok(())
    }
}

/// A token as adopted: every column, its secret's hash by its SHA-256.
fn token_form(t: &crate::domain::tokens::TokenRecord) -> Value {
    serde_json::json!({
        "id": t.id,
        "secret_hash_sha256": sha256(&t.secret_hash),
        "role": t.role.as_str(),
        "station_id": t.station_id,
        "label": t.label,
        "holder": t.holder,
        "created_at": t.created_at.to_string(),
        "revoked_at": t.revoked_at.map(|r| r.to_string()),
    })
}

/// `accelcal audit adopt`: the `audit.adopt` entries recording, by `by`,
/// every row [`verify`] finds unaudited (and only those) with the SHA-256
/// of its content — for a database whose rows predate the trail. Refused
/// when the chain is broken or any row differs from its entries: an edit is
/// never adopted.
pub async fn adoption(store: &dyn Store, by: Actor) -> Result<Vec<Event>, VerifyError> {
    let findings = match verify(store).await {
        Ok(_) => return Ok(Vec::new()),
        Err(VerifyError::Rows(f)) => f,
        Err(e) => return Err(e),
    };
    if findings.iter().any(|f| !f.unaudited) {
        return Err(VerifyError::Rows(
            findings.into_iter().filter(|f| !f.unaudited).collect(),
        ));
    }
    let wanted: HashSet<String> = findings.into_iter().map(|f| f.object).collect();
    let mut digests: Vec<(String, &'static str, String)> = Vec::new();
    let mut after = None;
    loop {
        let page = store.export_calibrations(after, 500).await?;
        let Some(last) = page.last() else { break };
        after = Some(last.id);
        for n in page {
            let object = format!("calibrations/{}", n.id);
            if wanted.contains(&object) {
                let signatures = store.signatures(n.id).await?;
                digests.push((
                    object,
                    "calibrations",
                    rows::digest(&rows::calibration_form(&n, &signatures)),
                ));
            }
            for r in store.revisions(n.id).await? {
                let object = format!("calibrations/{}/certificate/{}", n.id, r.revision);
                if wanted.contains(&object) {
                    digests.push((object, "certificates", rows::digest(&r)));
                }
            }
        }
    }
    let mut put = |object: String, table: &'static str, d: String| {
        if wanted.contains(&object) {
            digests.push((object, table, d));
        }
    };
    for s in store.standards().await? {
        put(
            format!("standards/{}", s.standard_id),
            "standards",
            rows::digest(&s),
        );
        for t in store.nonconformities(s.standard_id.clone()).await? {
            let object = format!(
                "standards/{}/nonconformities/{}",
                s.standard_id, t.nonconformity.id
            );
            put(object, "nonconformities", rows::digest(&t));
        }
    }
    for c in store.customers().await? {
        put(
            format!("customers/{}", c.customer_id),
            "customers",
            rows::digest(&c),
        );
    }
    for i in store.items().await? {
        put(format!("items/{}", i.sensor_id), "items", rows::digest(&i));
    }
    for t in store.sensor_types().await? {
        put(
            format!("sensor-types/{}", t.type_id),
            "sensor_types",
            rows::digest(&t),
        );
    }
    for t in store.tokens().await? {
        put(
            format!("tokens/{}", t.id),
            "tokens",
            rows::digest(&token_form(&t)),
        );
    }
    let at = Timestamp::now();
    Ok(digests
        .into_iter()
        .map(|(object, table, d)| {
            let mut change = serde_json::Map::new();
            change.insert("table".into(), table.into());
            change.insert("sha256".into(), d.into());
            Event::new(at, by.clone(), "audit.adopt", object, change)
        })
        .collect())
}
