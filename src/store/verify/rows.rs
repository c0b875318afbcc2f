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
        "columns": Columns::of(n),
        "result_sha256": hex::encode(Sha256::digest(&n.result)),
        "submission_sha256": hex::encode(Sha256::digest(&n.submission)),
        "signatures": signatures,
    })
}

/// The SHA-256 of a calibration's served columns in their canonical JSON
/// form: what its `calibration.submitted` entry records as `row_sha256`.
pub fn columns_digest(n: &NewCalibration) -> String {
    digest(&Columns::of(n))
}

/// A calibration's served columns in their canonical JSON form — every
/// map's keys in byte order, as a `serde_json::Value` holds them, so that
/// every digest recorded stays the same — written straight from the record
/// rather than built as a `Value` first (every submission's entry digests
/// them; BENCHMARKS.md "The served columns' digest"). The fields are
/// declared in that order; the term maps are sorted as they are written.
#[derive(Serialize)]
struct Columns<'a> {
    coefficients: Sorted<'a>,
    content_type: &'a str,
    due_at: Option<String>,
    expanded: Option<Sorted<'a>>,
    id: uuid::Uuid,
    model: Vec<&'static str>,
    performed_at: String,
    received_at: String,
    runs: usize,
    sensor_id: &'a str,
    sensor_type: Option<&'a str>,
    station_id: Option<&'a str>,
    std_errors: Sorted<'a>,
    submitted_by: &'a str,
    /// A temperature model is one more served column, named only where
    /// there is one: every digest recorded before it stays the same.
    #[serde(skip_serializing_if = "Option::is_none")]
    thermal: Option<Value>,
    triad: Option<Value>,
    unit: &'a str,
    verdict: Option<&'static str>,
}

impl<'a> Columns<'a> {
    fn of(n: &'a NewCalibration) -> Self {
        // The triad's and the temperature models' canonical form is their
        // `Value` (keys sorted): rare kinds, written as before.
        let value = |v: Option<serde_json::Result<Value>>| v.map(|v| v.unwrap_or(Value::Null));
        let thermal = value(n.thermal.as_ref().map(serde_json::to_value))
            .or_else(|| value(n.thermal_triad.as_ref().map(serde_json::to_value)));
        Columns {
            coefficients: Sorted(&n.coefficients),
            content_type: &n.content_type,
            due_at: n.due_at.map(|t| t.to_string()),
            expanded: n.expanded.as_ref().map(Sorted),
            id: n.id,
            model: n.model.terms().iter().map(|t| t.name()).collect(),
            performed_at: n.performed_at.to_string(),
            received_at: n.received_at.to_string(),
            runs: n.runs,
            sensor_id: &n.sensor_id,
            sensor_type: n.sensor_type.as_deref(),
            station_id: n.station_id.as_deref(),
            std_errors: Sorted(&n.std_errors),
            submitted_by: &n.submitted_by,
            thermal,
            triad: value(n.triad.as_ref().map(serde_json::to_value)),
            unit: &n.unit,
            verdict: n.verdict.map(|v| v.as_str()),
        }
    }
}

/// A term map written with its keys in byte order.
struct Sorted<'a>(&'a accelcal_core::TermMap<f64>);

impl Serialize for Sorted<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut pairs: Vec<(&str, f64)> = self.0.iter().map(|(t, x)| (t.name(), *x)).collect();
        pairs.sort_unstable_by(|a, b| a.0.cmp(b.0));
        s.collect_map(pairs)
    }
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

#[cfg(test)]
pub(crate) mod tests {
    use accelcal_core::thermal::Polynomial;
    use accelcal_core::{Model, Term, TermMap};
    use bytes::Bytes;
    use uuid::Uuid;

    use super::*;
    use crate::domain::thermal::ThermalModel;
    use crate::domain::timestamp::Timestamp;
    use crate::store::TriadElements;
    use accelcal_core::decision::Verdict;

    /// The served columns as every digest before [`Columns`] was computed:
    /// a `serde_json::Value` built field by field, then written — the
    /// definition [`columns_digest`] must keep byte for byte.
    fn reference(n: &NewCalibration) -> String {
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
        let map = v.as_object_mut().expect("an object");
        if let Some(t) = &n.thermal {
            map.insert("thermal".to_owned(), serde_json::json!(t));
        } else if let Some(t) = &n.thermal_triad {
            map.insert("thermal".to_owned(), serde_json::json!(t));
        }
        serde_json::to_string(&v).expect("a value writes")
    }

    fn ts(s: &str) -> Timestamp {
        Timestamp::parse(s).expect("a valid timestamp")
    }

    /// A single-axis record whose model is not in the terms' byte order
    /// (`ki` before `k0`, `kpi` before `kio`), every optional column set.
    pub(crate) fn single_axis() -> NewCalibration {
        let terms = [
            Term::Ki,
            Term::K0,
            Term::Kp,
            Term::Kpi,
            Term::Kio,
            Term::Kii,
        ];
        let map = |f: f64| {
            TermMap(
                terms
                    .iter()
                    .map(|&t| (t, f * t.name().len() as f64 + 0.1))
                    .collect(),
            )
        };
        NewCalibration {
            id: Uuid::from_u128(0x0123_4567_89ab_cdef),
            sensor_id: "SN-\"7\"".into(),
            station_id: Some("DH-1".into()),
            performed_at: ts("2026-01-02T03:04:05.678901Z"),
            received_at: ts("2026-01-02T03:04:06Z"),
            unit: "mA".into(),
            model: Model::new(terms.to_vec()).expect("a valid model"),
            runs: 6,
            coefficients: map(1.0 / 3.0),
            std_errors: map(1e-7),
            result: Bytes::from_static(b"{}"),
            submission: Bytes::from_static(b"{}"),
            content_type: "application/json".into(),
            submitted_by: "env-admin".into(),
            sensor_type: Some("QA-2000".into()),
            assigns_type: true,
            verdict: Some(Verdict::Pass),
            due_at: Some(ts("2027-01-02T03:04:05Z")),
            expanded: Some(map(2e-7)),
            triad: None,
            thermal: None,
            thermal_triad: None,
            standards: Vec::new(),
            fitted_from: Vec::new(),
        }
    }

    #[test]
    fn the_columns_digest_is_the_value_forms() {
        let full = single_axis();
        let bare = NewCalibration {
            station_id: None,
            sensor_type: None,
            verdict: None,
            due_at: None,
            expanded: None,
            ..single_axis()
        };
        let triad = NewCalibration {
            triad: Some(Box::new(TriadElements {
                method: "known_orientations".into(),
                b: [0.1, 0.2, 0.3],
                b_std_errors: Some([1e-3, 2e-3, 3e-3]),
                s: [[2.0, 0.01, 0.02], [0.03, 2.1, 0.04], [0.05, 0.06, 2.2]],
                s_std_errors: None,
                t: [[0.5, 0.0, 0.0], [0.0, 0.47, 0.0], [0.0, 0.0, 0.45]],
                t_std_errors: None,
                b_expanded: Some([2e-3, 4e-3, 6e-3]),
                s_expanded: None,
                s2: Some([1e-4, 0.0, -1e-4]),
                s2_std_errors: None,
                s2_expanded: None,
            })),
            coefficients: TermMap(Vec::new()),
            std_errors: TermMap(Vec::new()),
            ..bare.clone()
        };
        let polynomial = Polynomial {
            reference_c: 20.0,
            degree: 1,
            coefficients: vec![1e-3, 2e-5],
            std_uncertainties: vec![1e-5, 1e-7],
            covariance: vec![vec![1e-10, 0.0], vec![0.0, 1e-14]],
            chi2: 1.0,
            dof: 3,
            inflation: 1.0,
            range_c: [0.0, 40.0],
            selection: Vec::new(),
        };
        let thermal = NewCalibration {
            thermal: Some(Box::new(ThermalModel {
                sensor_id: "S".into(),
                unit: "V".into(),
                tolerance_k: 0.5,
                selection: "fixed".into(),
                fitted_with: Default::default(),
                set_points: Vec::new(),
                coefficients: TermMap(vec![(Term::Ki, polynomial.clone()), (Term::K0, polynomial)]),
                thermometer_std_c: Some(0.05),
            })),
            ..single_axis()
        };
        for (name, n) in [
            ("single-axis", &full),
            ("bare", &bare),
            ("triad", &triad),
            ("thermal", &thermal),
        ] {
            let want = reference(n);
            assert_eq!(
                serde_json::to_string(&Columns::of(n)).expect("columns write"),
                want,
                "{name}"
            );
            assert_eq!(
                columns_digest(n),
                hex::encode(Sha256::digest(want.as_bytes())),
                "{name}"
            );
        }
        assert!(reference(&full).contains(r#""coefficients":{"k0":"#));
        assert!(reference(&thermal).contains(r#""thermal":{"#));
    }
}
