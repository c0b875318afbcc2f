//! The calibrations' rows against the trail: each calibration (its
//! submission, result and served columns), its signatures in order, its
//! issued certificates' documents, and each sensor's row recomputed from
//! its calibrations ([`super`]).

use std::collections::{HashMap, HashSet};

use uuid::Uuid;

use serde_json::Value;

use super::{Check, Counted, rows};
use crate::domain::review::State;
use crate::domain::timestamp::Timestamp;
use crate::store::{SensorQuery, StoreError};

impl Check<'_> {
    /// Calibrations, their signatures and certificates, and the sensors'
    /// rows recomputed from them.
    pub(super) async fn calibrations(&mut self) -> Result<(), StoreError> {
        let mut by_sensor: HashMap<String, Vec<Counted>> = HashMap::new();
        let mut after = None;
        loop {
            let page = self.store.export_calibrations(after, 500).await?;
            let Some(last) = page.last() else { break };
            after = Some(last.id);
            for n in page {
                let object = format!("calibrations/{}", n.id);
                let signatures = self.store.signatures(n.id).await?;
                self.count("calibrations");
                match self.expected.calibrations.get(&n.id).cloned() {
                    Some(e) => {
                        // Its columns' digest, as recorded; an entry from
                        // before recorded none: the columns recomputed from
                        // its result document instead.
                        match e.change.get("row_sha256").and_then(Value::as_str) {
                            Some(d) if d != rows::columns_digest(&n) => self.find(
                                "calibrations",
                                object.clone(),
                                "its served columns are not the ones its audit entry recorded \
                                 (edited)",
                            ),
                            Some(_) => {}
                            None => {
                                let off = rows::columns_against_result(&n);
                                if !off.is_empty() {
                                    self.find(
                                        "calibrations",
                                        object.clone(),
                                        format!(
                                            "served columns {} are not what its result says (edited)",
                                            off.join(", ")
                                        ),
                                    );
                                }
                            }
                        }
                        if e.by.token_id != n.submitted_by {
                            self.find(
                                "calibrations",
                                object.clone(),
                                "its submitter is not the one recorded (edited)",
                            );
                        }
                        if let Some(ct) = e.change.get("content_type").and_then(Value::as_str)
                            && ct != n.content_type
                        {
                            self.find(
                                "calibrations",
                                object.clone(),
                                "its media type is not the one recorded (edited)",
                            );
                        }
                        self.signatures(&n.id, &object, &signatures);
                    }
                    None => match self.adopted(
                        &object,
                        &rows::digest(&rows::calibration_form(&n, &signatures)),
                    ) {
                        Some(true) => {}
                        Some(false) => self.find(
                            "calibrations",
                            object.clone(),
                            "not the row adopted (edited)",
                        ),
                        None => self.unaudited("calibrations", object.clone()),
                    },
                }
                self.certificates(n.id).await?;
                by_sensor
                    .entry(n.sensor_id.clone())
                    .or_default()
                    .push(Counted {
                        id: n.id,
                        performed_at: n.performed_at,
                        state: signatures.last().map_or(State::Submitted, |s| s.state),
                        verdict: n.verdict,
                        due_at: n.due_at,
                    });
            }
        }
        self.sensors(by_sensor).await
    }

    /// Calibration `id`'s signatures against its signature entries, in
    /// order.
    pub(super) fn signatures(
        &mut self,
        id: &Uuid,
        object: &str,
        found: &[crate::domain::review::Signature],
    ) {
        let recorded = self
            .expected
            .signatures
            .get(id)
            .cloned()
            .unwrap_or_default();
        for k in 0..found.len().max(recorded.len()) {
            self.count("signatures");
            let at = format!("{object}/signatures/{}", k + 1);
            match (found.get(k), recorded.get(k)) {
                (Some(s), Some(e)) => {
                    let off = rows::signature_against_entry(s, e);
                    if !off.is_empty() {
                        self.find(
                            "signatures",
                            at,
                            format!(
                                "{} differ from audit entry {} (edited)",
                                off.join(", "),
                                e.seq
                            ),
                        );
                    }
                }
                (Some(_), None) => self.find(
                    "signatures",
                    at,
                    "no audit entry: a signature inserted behind the service's back",
                ),
                (None, Some(e)) => self.find(
                    "signatures",
                    at,
                    format!("recorded by audit entry {}, not stored (deleted)", e.seq),
                ),
                (None, None) => {}
            }
        }
    }

    /// Calibration `id`'s issued revisions: each document against the
    /// digests stored with it and those its entry recorded.
    pub(super) async fn certificates(&mut self, id: Uuid) -> Result<(), StoreError> {
        let revisions = self.store.revisions(id).await?;
        let stored: HashSet<u32> = revisions.iter().map(|r| r.revision).collect();
        for r in revisions {
            self.count("certificates");
            let object = format!("calibrations/{id}/certificate/{}", r.revision);
            let Some(c) = self.store.certificate(id, Some(r.revision)).await? else {
                continue;
            };
            if !c.intact() {
                self.find(
                    "certificates",
                    object.clone(),
                    "its documents are not their stored digests (edited)",
                );
            }
            match self.expected.certificates.get(&(id, r.revision)) {
                Some(e)
                    if e.html_sha256.as_deref() == Some(c.html_sha256.as_str())
                        && e.dcc_sha256 == c.dcc_sha256 => {}
                Some(e) => self.find(
                    "certificates",
                    object,
                    format!(
                        "its digests are not those audit entry {} recorded (edited)",
                        e.seq
                    ),
                ),
                None => {
                    match self.adopted(&object, &rows::digest(&crate::store::Revision::from(&c))) {
                        Some(true) => {}
                        Some(false) => {
                            self.find("certificates", object, "not the row adopted (edited)")
                        }
                        None => self.unaudited("certificates", object),
                    }
                }
            }
        }
        let missing: Vec<(u32, i64)> = self
            .expected
            .certificates
            .iter()
            .filter(|((c, n), _)| *c == id && !stored.contains(n))
            .map(|((_, n), e)| (*n, e.seq))
            .collect();
        for (n, seq) in missing {
            self.find(
                "certificates",
                format!("calibrations/{id}/certificate/{n}"),
                format!("recorded by audit entry {seq}, not stored (deleted)"),
            );
        }
        Ok(())
    }

    /// Every sensor's row against its calibrations, and its type against
    /// the entries that assigned one.
    pub(super) async fn sensors(
        &mut self,
        by_sensor: HashMap<String, Vec<Counted>>,
    ) -> Result<(), StoreError> {
        let mut seen = HashSet::new();
        let mut after = None;
        loop {
            let page = self
                .store
                .sensors(SensorQuery {
                    after: after.clone(),
                    status: None,
                    search: None,
                    now: Timestamp::now(),
                    limit: 500,
                })
                .await?;
            let Some(last) = page.last() else { break };
            after = Some(last.sensor_id.clone());
            for s in page {
                self.count("sensors");
                let object = format!("sensors/{}", s.sensor_id);
                seen.insert(s.sensor_id.clone());
                let counted: Vec<&Counted> = by_sensor
                    .get(&s.sensor_id)
                    .map(|c| {
                        c.iter()
                            .filter(|c| c.state.counts(crate::domain::review::Basis::NotRejected))
                            .collect()
                    })
                    .unwrap_or_default();
                let latest = counted.iter().max_by_key(|c| (c.performed_at, c.id));
                let first = counted.iter().map(|c| c.performed_at).min();
                let mut off = Vec::new();
                if s.calibration_count != counted.len() as u64 {
                    off.push("calibration_count");
                }
                if Some(s.first_performed_at) != first {
                    off.push("first_performed_at");
                }
                if latest.map(|c| (c.id, c.performed_at, c.verdict, c.due_at))
                    != Some((
                        s.latest.id,
                        s.latest_performed_at,
                        s.latest_verdict,
                        s.due_at,
                    ))
                {
                    off.push("latest calibration");
                }
                match self.expected.sensor_types.get(&s.sensor_id) {
                    Some(Some(t)) if s.sensor_type.as_deref() != Some(t.as_str()) => {
                        off.push("sensor_type")
                    }
                    None if s.sensor_type.is_some() => off.push("sensor_type"),
                    _ => {}
                }
                if !off.is_empty() {
                    self.find(
                        "sensors",
                        object,
                        format!(
                            "{} not what its calibrations and the trail say (edited)",
                            off.join(", ")
                        ),
                    );
                }
            }
        }
        for (sensor, counted) in &by_sensor {
            let counts = counted
                .iter()
                .any(|c| c.state.counts(crate::domain::review::Basis::NotRejected));
            if counts && !seen.contains(sensor) {
                self.find(
                    "sensors",
                    format!("sensors/{sensor}"),
                    "its row is missing (deleted)",
                );
            }
        }
        Ok(())
    }
}
