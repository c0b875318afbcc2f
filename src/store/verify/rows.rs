//! Each protected table's rows against what the trail vouches for
//! ([`super::expected`]): what a finding says, and the canonical form a row
//! is adopted in.

use serde::Serialize;
use serde_json::Value;
use sha2::{Digest, Sha256};

use crate::domain::review::Signature;
use crate::store::{NewCalibration, TriadElements};

/// One row that does not hold.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Finding {
    /// The table.
    pub table: &'static str,
    /// The row's object (`calibrations/…`, `standards/DH-1`, …).
    pub object: String,
    /// What does not hold.
    pub why: String,
    /// Whether the row has no audit entry at all (what `accelcal audit
    /// adopt` may adopt), rather than differing from one.
    pub unaudited: bool,
}

/// The SHA-256, hex, of a value's canonical JSON (serde_json's: keys in
/// order, no white space).
pub fn digest<T: Serialize>(v: &T) -> String {
    let text = serde_json::to_string(v).unwrap_or_default();
    hex::encode(Sha256::digest(text.as_bytes()))
}

/// A calibration as adopted: its served columns, the SHA-256 of its result
/// and submission, and its signatures.
pub fn calibration_form(n: &NewCalibration, signatures: &[Signature]) -> Value {
    serde_json::json!({
        "columns": columns(n),
        "result_sha256": hex::encode(Sha256::digest(&n.result)),
        "submission_sha256": hex::encode(Sha256::digest(&n.submission)),
        "signatures": signatures,
    })
}

/// The SHA-256 of a calibration's served columns in their canonical JSON
/// form: what its `calibration.submitted` entry records as `row_sha256`.
pub fn columns_digest(n: &NewCalibration) -> String {
    digest(&columns(n))
}

/// A calibration's served columns, as JSON (every map's keys in order).
fn columns(n: &NewCalibration) -> Value {
    let mut v = serde_json::json!({
        "id": n.id,
        "sensor_id": n.sensor_id,
        "station_id": n.station_id,
        "performed_at": n.performed_at.to_string(),
        "received_at": n.received_at.to_string(),
        "unit": n.unit,
        "model": n.model.terms().iter().map(|t| t.name()).collect::<Vec<_>>(),
        "runs": n.runs,
        "coefficients": n.coefficients,
        "std_errors": n.std_errors,
        "expanded": n.expanded,
        "triad": n.triad,
        "content_type": n.content_type,
        "submitted_by": n.submitted_by,
        "sensor_type": n.sensor_type,
        "verdict": n.verdict.map(|v| v.as_str()),
        "due_at": n.due_at.map(|t| t.to_string()),
    });
    // A temperature model is one more served column, named only where
    // there is one: every digest recorded before it stays the same.
    if let (Some(t), Some(map)) = (&n.thermal, v.as_object_mut()) {
        map.insert("thermal".to_owned(), serde_json::json!(t));
    } else if let (Some(t), Some(map)) = (&n.thermal_triad, v.as_object_mut()) {
        map.insert("thermal".to_owned(), serde_json::json!(t));
    }
    v
}

fn f64s(v: Option<&Value>) -> Option<Vec<(String, f64)>> {
    let m = v?.as_object()?;
    m.iter()
        .map(|(k, x)| x.as_f64().map(|x| (k.clone(), x)))
        .collect()
}

fn same_numbers(stored: &accelcal_core::TermMap<f64>, doc: Option<&Value>) -> bool {
    let Some(mut doc) = f64s(doc) else {
        return stored.is_empty();
    };
    let mut mine: Vec<(String, f64)> = stored
        .iter()
        .map(|(t, x)| (t.name().to_owned(), *x))
        .collect();
    doc.sort_by(|a, b| a.0.cmp(&b.0));
    mine.sort_by(|a, b| a.0.cmp(&b.0));
    doc.len() == mine.len()
        && doc
            .iter()
            .zip(&mine)
            .all(|(a, b)| a.0 == b.0 && a.1.to_bits() == b.1.to_bits())
}

/// Which served columns of calibration `n` are not what its result document
/// — whose SHA-256 the trail holds — says: the columns are recomputed from
/// the document and compared, bit for bit for the numbers.
pub fn columns_against_result(n: &NewCalibration) -> Vec<&'static str> {
    let mut off = Vec::new();
    let Ok(doc) = serde_json::from_slice::<Value>(&n.result) else {
        return vec!["result"];
    };
    let text = |k: &str| doc.get(k).and_then(Value::as_str);
    let instant =
        |k: &str| text(k).and_then(|t| crate::domain::timestamp::Timestamp::parse(t).ok());
    if text("sensor_id") != Some(n.sensor_id.as_str()) {
        off.push("sensor_id");
    }
    if text("station_id") != n.station_id.as_deref() {
        off.push("station_id");
    }
    if text("unit") != Some(n.unit.as_str()) {
        off.push("unit");
    }
    if instant("performed_at") != Some(n.performed_at) {
        off.push("performed_at");
    }
    if instant("received_at") != Some(n.received_at) {
        off.push("received_at");
    }
    if instant("due_at") != n.due_at {
        off.push("due_at");
    }
    let verdict = doc
        .get("decision")
        .and_then(|d| d.get("verdict"))
        .and_then(Value::as_str);
    if verdict != n.verdict.map(|v| v.as_str()) {
        off.push("verdict");
    }
    match &n.triad {
        Some(t) => {
            if serde_json::from_value::<TriadElements>(doc.clone())
                .ok()
                .as_ref()
                != Some(t)
            {
                off.push("triad");
            }
        }
        None => {
            if text("sensor_type") != n.sensor_type.as_deref() {
                off.push("sensor_type");
            }
            let model: Option<Vec<&str>> = doc
                .get("model")
                .and_then(Value::as_array)
                .map(|m| m.iter().filter_map(Value::as_str).collect());
            let mine: Vec<&str> = n.model.terms().iter().map(|t| t.name()).collect();
            if model.as_deref() != Some(mine.as_slice()) {
                off.push("model");
            }
            if doc.get("runs").and_then(Value::as_array).map(Vec::len) != Some(n.runs) {
                off.push("runs");
            }
            let fused = doc.get("fused");
            if !same_numbers(&n.coefficients, fused.and_then(|f| f.get("coefficients"))) {
                off.push("coefficients");
            }
            if !same_numbers(&n.std_errors, fused.and_then(|f| f.get("std_errors"))) {
                off.push("std_errors");
            }
            let expanded: Option<Value> = doc
                .get("uncertainty")
                .and_then(|u| u.get("terms"))
                .and_then(Value::as_object)
                .map(|terms| {
                    terms
                        .iter()
                        .filter_map(|(k, b)| b.get("expanded").map(|x| (k.clone(), x.clone())))
                        .collect::<serde_json::Map<_, _>>()
                        .into()
                });
            let same = match (&n.expanded, expanded.as_ref()) {
                (Some(e), Some(d)) => same_numbers(e, Some(d)),
                (None, None) => true,
                _ => false,
            };
            if !same {
                off.push("expanded");
            }
        }
    }
    off
}

/// Which fields of signature `s` (the `k`-th of its calibration) are not
/// what its entry recorded.
pub fn signature_against_entry(s: &Signature, e: &super::expected::Signed) -> Vec<&'static str> {
    let mut off = Vec::new();
    let c = &e.change;
    let text = |k: &str| c.get(k).and_then(Value::as_str);
    if s.action.as_str() != e.action {
        off.push("action");
    }
    if Some(s.state.as_str()) != text("to") {
        off.push("state");
    }
    if Some(s.meaning.as_str()) != text("meaning") {
        off.push("meaning");
    }
    if s.comment.as_deref() != text("comment") {
        off.push("comment");
    }
    if s.superseded_by.map(|u| u.to_string()).as_deref() != text("superseded_by") {
        off.push("superseded_by");
    }
    if s.token_id != e.by.token_id || s.role.as_str() != e.by.role || s.holder != e.by.holder {
        off.push("signer");
    }
    if s.signed_at != e.at {
        off.push("signed_at");
    }
    off
}
