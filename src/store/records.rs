//! What the store reads and writes: plain, typed records.

use accelcal_core::decision::Verdict;
use accelcal_core::{Model, TermMap};
use bytes::Bytes;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use uuid::Uuid;

use super::StoreError;
use crate::domain::nonconformity::{
    Affected, Bearing, Nonconformity, Outcome, Replacement, bearing,
};
use crate::domain::review::{Basis, Refusal, Signature, State};
use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;

/// Everything stored for one calibration, written in one transaction.
#[derive(Debug, Clone)]
pub struct NewCalibration {
    /// UUIDv7.
    pub id: Uuid,
    /// The sensor.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// Output unit.
    pub unit: String,
    /// The model's terms.
    pub model: Model,
    /// Number of runs.
    pub runs: usize,
    /// Fused coefficients.
    pub coefficients: TermMap<f64>,
    /// Fused standard errors.
    pub std_errors: TermMap<f64>,
    /// The whole result document (what `GET /v1/calibrations/{id}` returns).
    pub result: Bytes,
    /// The submitted body (decompressed), byte for byte.
    pub submission: Bytes,
    /// The submitted body's media type.
    pub content_type: String,
    /// The principal that submitted it.
    pub submitted_by: String,
    /// The sensor type in force, if any.
    pub sensor_type: Option<String>,
    /// Whether the submission named that type (it then becomes the sensor's).
    pub assigns_type: bool,
    /// The decision's verdict (typed sensors).
    pub verdict: Option<Verdict>,
    /// When the sensor is due again (typed sensors).
    pub due_at: Option<Timestamp>,
    /// The expanded uncertainty of every fused coefficient (none only for
    /// calibrations stored before uncertainty budgets, when copied).
    pub expanded: Option<TermMap<f64>>,
    /// A triad's elements (none for a single-axis calibration).
    pub triad: Option<TriadElements>,
    /// The reference standards the test used, each with the calibration
    /// date of its certificate in force when it was performed: what the
    /// store judges against the standards' nonconformities in the
    /// transaction that stores it, holding it when one bears on it
    /// ([`crate::domain::nonconformity::bearing`]). Not a column: the
    /// result document names them; empty for a record copied or exported.
    pub standards: Vec<StandardUse>,
}

/// A reference standard as a calibration used it, for the store's judgement
/// of its nonconformities.
#[derive(Debug, Clone, PartialEq)]
pub struct StandardUse {
    /// The standard.
    pub standard_id: String,
    /// When its certificate in force at the test was calibrated.
    pub calibrated_at: Timestamp,
}

impl NewCalibration {
    /// The nonconformities that hold this record when it is stored: those
    /// of `found` (its standards' nonconformities) inside whose window it
    /// was performed or whose standard is out of service for it, and those
    /// `inherited` from the held calibration it supersedes whose standard
    /// it still uses; each once.
    pub fn held_by<'a>(
        &self,
        found: &'a [Nonconformity],
        inherited: &'a [Nonconformity],
    ) -> Vec<&'a Nonconformity> {
        let mut held: Vec<&Nonconformity> = found
            .iter()
            .filter(|nc| {
                self.standards.iter().any(|u| {
                    u.standard_id == nc.standard_id
                        && bearing(nc, u.calibrated_at, self.performed_at) != Bearing::Clear
                })
            })
            .collect();
        for nc in inherited {
            let uses = self
                .standards
                .iter()
                .any(|u| u.standard_id == nc.standard_id);
            if uses && !held.iter().any(|h| h.id == nc.id) {
                held.push(nc);
            }
        }
        held
    }

    /// Refuses a record whose fused coefficients or standard errors hold a
    /// non-finite number: whatever reaches the store, nothing NaN or infinite
    /// is ever written (every engine calls this, and the schema checks again).
    pub fn check(&self) -> Result<(), StoreError> {
        let none = TermMap(Vec::new());
        for (what, map) in [
            ("coefficient", &self.coefficients),
            ("standard error", &self.std_errors),
            (
                "expanded uncertainty",
                self.expanded.as_ref().unwrap_or(&none),
            ),
        ] {
            if let Some((term, v)) = map.iter().find(|(_, v)| !v.is_finite()) {
                return Err(StoreError::Refused(format!(
                    "the fused {what} of `{term}` is {v}"
                )));
            }
        }
        if let Some((name, v)) = self
            .triad
            .iter()
            .flat_map(TriadElements::numbers)
            .find(|(_, v)| !v.is_finite())
        {
            return Err(StoreError::Refused(format!("the triad's `{name}` is {v}")));
        }
        Ok(())
    }
}

impl From<&NewCalibration> for CalibrationSummary {
    /// The summary every engine reads back for this record once stored.
    fn from(n: &NewCalibration) -> Self {
        CalibrationSummary {
            id: n.id,
            sensor_id: n.sensor_id.clone(),
            station_id: n.station_id.clone(),
            performed_at: n.performed_at,
            received_at: n.received_at,
            unit: n.unit.clone(),
            model: n.model.clone(),
            runs: n.runs,
            coefficients: n.coefficients.clone(),
            std_errors: n.std_errors.clone(),
            sensor_type: n.sensor_type.clone(),
            verdict: n.verdict,
            due_at: n.due_at,
            expanded: n.expanded.clone(),
            triad: n.triad.clone(),
            state: State::Submitted,
        }
    }
}

/// A triad calibration's elements (issue 30): `u = b + S g` with bias `b`
/// (the outputs' unit) and scale-and-misalignment `S` (the outputs' unit
/// per g, rows by axis), and `T = S⁻¹`, with the standard errors its
/// method gives. Row `m` of `S` is axis `m`'s `(ki, kp, ko)` and `b_m` its
/// `k0` in the single-axis model, which is why a triad's stored `model` is
/// `k0, ki, kp, ko`; its single-axis `coefficients` stay empty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TriadElements {
    /// `known_orientations` or `gravity_magnitude`.
    pub method: String,
    /// `b`.
    pub b: [f64; 3],
    /// Its standard errors (none with exactly nine static positions).
    pub b_std_errors: Option<[f64; 3]>,
    /// `S`, rows by axis.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Its standard errors (known orientations).
    #[serde(rename = "S_std_errors")]
    pub s_std_errors: Option<[[f64; 3]; 3]>,
    /// `T = S⁻¹`.
    #[serde(rename = "T")]
    pub t: [[f64; 3]; 3],
    /// Its standard errors (unknown orientations, more than nine positions).
    #[serde(rename = "T_std_errors")]
    pub t_std_errors: Option<[[f64; 3]; 3]>,
    /// `b`'s expanded uncertainties (known orientations: each axis's `k0`
    /// budget).
    #[serde(default)]
    pub b_expanded: Option<[f64; 3]>,
    /// `S`'s expanded uncertainties (known orientations).
    #[serde(rename = "S_expanded", default)]
    pub s_expanded: Option<[[f64; 3]; 3]>,
    /// Each axis's second-order coefficient `S2_m` (its `kii`), when the
    /// model has them.
    #[serde(rename = "S2", default, skip_serializing_if = "Option::is_none")]
    pub s2: Option<[f64; 3]>,
    /// Their standard errors.
    #[serde(
        rename = "S2_std_errors",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub s2_std_errors: Option<[f64; 3]>,
    /// Their expanded uncertainties.
    #[serde(
        rename = "S2_expanded",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub s2_expanded: Option<[f64; 3]>,
}

impl TriadElements {
    /// The model `b`, `S` and `S2` describe (compensation inverts it).
    pub fn model(&self) -> accelcal_core::triad::Triad {
        accelcal_core::triad::Triad {
            bias: self.b,
            matrix: self.s,
            square: self.s2.unwrap_or([0.0; 3]),
        }
    }
}

/// The axes' names, in the order of `b`'s elements and `S`'s rows.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// One element of a stored triad ([`TriadElements::elements`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TriadElement {
    /// `b_x`, `S_xy`, `S2_z`, `T_zz`.
    pub name: String,
    /// Its value.
    pub value: f64,
    /// Its standard error, when the method gives one.
    pub std_error: Option<f64>,
    /// Its expanded uncertainty, when the method gives one.
    pub expanded: Option<f64>,
    /// Whether the calibration measured it: `T`, derived from `S`, is not,
    /// nor are the elements of `S` zero by a gravity-magnitude triad's
    /// frame convention.
    pub measured: bool,
}

impl TriadElements {
    /// The elements of `b`, `S`, `S2` and `T` by name (`b_x`, `S_xy`,
    /// `S2_z`, `T_zz`), each with its standard error and expanded
    /// uncertainty when the method gives them: what stability is judged on,
    /// element by element, and what the sensor's page charts (those
    /// [`TriadElement::measured`]).
    pub fn elements(&self) -> Vec<TriadElement> {
        let convention = self.method == crate::domain::triad::GRAVITY_MAGNITUDE;
        let mut out = Vec::with_capacity(24);
        let vector = |out: &mut Vec<TriadElement>,
                      name,
                      v: &[f64; 3],
                      se: Option<[f64; 3]>,
                      u: Option<[f64; 3]>| {
            for (m, axis) in AXES.iter().enumerate() {
                out.push(TriadElement {
                    name: format!("{name}_{axis}"),
                    value: v[m],
                    std_error: se.map(|e| e[m]),
                    expanded: u.map(|e| e[m]),
                    measured: true,
                });
            }
        };
        vector(&mut out, "b", &self.b, self.b_std_errors, self.b_expanded);
        for (name, matrix, se, u) in [
            ("S", &self.s, self.s_std_errors, self.s_expanded),
            ("T", &self.t, self.t_std_errors, None),
        ] {
            for (m, row) in AXES.iter().enumerate() {
                for (k, column) in AXES.iter().enumerate() {
                    out.push(TriadElement {
                        name: format!("{name}_{row}{column}"),
                        value: matrix[m][k],
                        std_error: se.map(|e| e[m][k]),
                        expanded: u.map(|e| e[m][k]),
                        measured: name == "S" && !(convention && k > m),
                    });
                }
            }
        }
        if let Some(s2) = &self.s2 {
            vector(&mut out, "S2", s2, self.s2_std_errors, self.s2_expanded);
        }
        out
    }

    /// Every stored number with its name (`b_x`, `S_xy`, `T_zz`,
    /// `b_x_std_error`, …): what must be finite, and what stability is
    /// judged on element by element.
    pub fn numbers(&self) -> Vec<(String, f64)> {
        let mut out = Vec::with_capacity(54);
        let vector = |out: &mut Vec<(String, f64)>, name: &str, suffix: &str, v: &[f64; 3]| {
            for (axis, x) in AXES.iter().zip(v) {
                out.push((format!("{name}_{axis}{suffix}"), *x));
            }
        };
        let matrix = |out: &mut Vec<(String, f64)>, name: &str, suffix: &str, m: &[[f64; 3]; 3]| {
            for (row, r) in AXES.iter().zip(m) {
                for (column, x) in AXES.iter().zip(r) {
                    out.push((format!("{name}_{row}{column}{suffix}"), *x));
                }
            }
        };
        vector(&mut out, "b", "", &self.b);
        matrix(&mut out, "S", "", &self.s);
        matrix(&mut out, "T", "", &self.t);
        for (suffix, v) in [
            ("", &self.s2),
            ("_std_error", &self.s2_std_errors),
            ("_expanded", &self.s2_expanded),
        ] {
            if let Some(v) = v {
                for (axis, x) in AXES.iter().zip(v) {
                    out.push((format!("S2_{axis}{suffix}"), *x));
                }
            }
        }
        const E: &str = "_std_error";
        if let Some(e) = &self.b_std_errors {
            vector(&mut out, "b", E, e);
        }
        if let Some(e) = &self.s_std_errors {
            matrix(&mut out, "S", E, e);
        }
        if let Some(e) = &self.t_std_errors {
            matrix(&mut out, "T", E, e);
        }
        const U: &str = "_expanded";
        if let Some(e) = &self.b_expanded {
            vector(&mut out, "b", U, e);
        }
        if let Some(e) = &self.s_expanded {
            matrix(&mut out, "S", U, e);
        }
        out
    }
}

/// A submitted body as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredSubmission {
    /// Media type it was sent with.
    pub content_type: String,
    /// The bytes.
    pub body: Bytes,
}

/// A calibration without its per-run detail: what lists and control systems need.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct CalibrationSummary {
    /// Calibration id.
    pub id: Uuid,
    /// The sensor.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// Unit of the outputs and of every coefficient.
    pub unit: String,
    /// Model terms.
    #[schema(value_type = crate::domain::schema::ModelSchema)]
    pub model: Model,
    /// Number of runs.
    #[schema(minimum = 1)]
    pub runs: usize,
    /// Fused coefficients.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    pub coefficients: TermMap<f64>,
    /// Fused standard errors.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    pub std_errors: TermMap<f64>,
    /// The sensor type in force at the calibration, if any.
    pub sensor_type: Option<String>,
    /// Its verdict against that type's limits, if typed.
    #[schema(value_type = Option<crate::domain::schema::VerdictSchema>)]
    pub verdict: Option<Verdict>,
    /// When the sensor was next due, if typed.
    pub due_at: Option<Timestamp>,
    /// The expanded uncertainty of every fused coefficient (null for
    /// calibrations stored before uncertainty budgets).
    #[schema(value_type = Option<crate::domain::schema::CoefficientMap>)]
    pub expanded: Option<TermMap<f64>>,
    /// A triad's elements (absent for a single-axis calibration, whose
    /// `coefficients` are its result; a triad's `coefficients` are empty).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub triad: Option<TriadElements>,
    /// Where it stands: `submitted`, `approved`, `rejected` or `withdrawn`
    /// (only the first two count).
    pub state: State,
}

#[cfg(test)]
impl CalibrationSummary {
    /// A minimal summary for tests: sensor `sensor`, model `k0 + ki`, one
    /// run, performed and received at 2026-01-01, standard errors zero.
    pub(crate) fn for_test(id: u128, sensor: &str, k0: f64, ki: f64) -> Self {
        use accelcal_core::Term;
        let at = Timestamp::parse("2026-01-01T00:00:00Z").expect("a valid timestamp");
        Self {
            id: Uuid::from_u128(id),
            sensor_id: sensor.into(),
            station_id: None,
            performed_at: at,
            received_at: at,
            unit: "mA".into(),
            model: Model::new(vec![Term::K0, Term::Ki]).expect("a valid model"),
            runs: 1,
            coefficients: TermMap(vec![(Term::K0, k0), (Term::Ki, ki)]),
            std_errors: TermMap(vec![(Term::K0, 0.0), (Term::Ki, 0.0)]),
            sensor_type: None,
            verdict: None,
            due_at: None,
            expanded: None,
            triad: None,
            state: State::Submitted,
        }
    }
}

/// A sensor with its calibration count and latest calibration.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SensorSummary {
    /// The sensor.
    pub sensor_id: String,
    /// Number of stored calibrations.
    #[schema(minimum = 1)]
    pub calibration_count: u64,
    /// Earliest `performed_at`.
    pub first_performed_at: Timestamp,
    /// Latest `performed_at`.
    pub latest_performed_at: Timestamp,
    /// The sensor type assigned to it, if any.
    pub sensor_type: Option<String>,
    /// The latest calibration's verdict, if it was typed.
    #[schema(value_type = Option<crate::domain::schema::VerdictSchema>)]
    pub latest_verdict: Option<Verdict>,
    /// When the sensor is due, from its latest calibration.
    pub due_at: Option<Timestamp>,
    /// Its status now: failed, overdue, due_soon, ok or unknown.
    pub status: Status,
    /// The calibration with the latest `performed_at` (ties: the later id).
    pub latest: CalibrationSummary,
}

/// A sensor's calibrations newest first: by `performed_at`, a tie going to
/// the larger id (UUIDv7, so the later stored). The one order both engines'
/// queries of the latest, the previous and the history use; the sensors'
/// merge ([`SENSOR_MERGE`]) keeps the latest by the same rule.
pub const NEWEST_FIRST: &str = "ORDER BY c.performed_at DESC, c.id DESC";

/// A calibration's state, in SQL over its row `c`: the state its last
/// signature left it in, `submitted` before any
/// ([`crate::domain::review`]). A macro, to be spliced into the engines'
/// column lists at compile time.
#[macro_export]
macro_rules! state_sql {
    () => {
        "coalesce((SELECT s.state FROM signatures s WHERE s.calibration_id = c.id \
         ORDER BY s.seq DESC LIMIT 1), 'submitted')"
    };
}

/// How many calibrations `window` (a condition on `c`) selects, in SQL over
/// the CTE `page` (its newest, at most `limit`): the page's own count when
/// it is not full, so that a series costs the same for a sensor with 40
/// calibrations as with 100 000 until the page is full; the window counted
/// again only then (a count, not a window function over every row's
/// columns: 1.1 s → 47 ms for 100 000, BENCHMARKS.md "History") — unless
/// the window is the sensor's whole history on [`Basis::NotRejected`]
/// (`sensor` names the placeholder of its id), whose count its row keeps
/// ([`SENSOR_MERGE`], [`sensor_recompute`]; `audit verify` checks it): then
/// read there, so that the count costs the same for 10 calibrations as for
/// 100 000 (BENCHMARKS.md "A sensor's history").
pub fn in_window_sql(limit: &str, window: &str, sensor: Option<&str>) -> String {
    let all = match sensor {
        Some(p) => format!("(SELECT s.calibration_count FROM sensors s WHERE s.sensor_id = {p})"),
        None => format!("(SELECT count(*) FROM calibrations c WHERE {window})"),
    };
    format!(
        "CASE WHEN (SELECT count(*) FROM page) < {limit} THEN (SELECT count(*) FROM page) \
         ELSE {all} END"
    )
}

/// Whether a series of `from..=to` on `basis` is the sensor's whole history
/// as its row counts it ([`in_window_sql`]).
pub fn whole_history(from: Option<Timestamp>, to: Option<Timestamp>, basis: Basis) -> bool {
    from.is_none() && to.is_none() && basis == Basis::NotRejected
}

/// Whether calibration `c` counts on `basis`, in SQL: its state
/// ([`state_sql!`]) is one [`State::counts`] admits — the one statement of
/// the rule for every engine's query.
pub fn counts(basis: Basis) -> &'static str {
    match basis {
        Basis::NotRejected => concat!(
            state_sql!(),
            " IN ('submitted', 'approved', 'under_review')"
        ),
        Basis::ApprovedOnly => concat!(state_sql!(), " = 'approved'"),
    }
}

/// A sensor's row computed again from the calibrations that count
/// ([`Basis::NotRejected`]), after one stopped counting or changed state;
/// `p` is the engine's placeholder for the sensor's id (`?1`, `$1`). The
/// same answer [`SENSOR_MERGE`] keeps incrementally: count, earliest,
/// latest by [`NEWEST_FIRST`] with its verdict and due date. A sensor
/// none of whose calibrations counts keeps its row with a count of 0 until
/// [`sensor_forget`] removes it.
pub fn sensor_recompute(p: &str) -> String {
    let of = |column: &str| {
        format!(
            "(SELECT c.{column} FROM calibrations c WHERE c.sensor_id = sensors.sensor_id \
             AND {} {NEWEST_FIRST} LIMIT 1)",
            counts(Basis::NotRejected)
        )
    };
    format!(
        "UPDATE sensors SET \
         calibration_count = (SELECT count(*) FROM calibrations c \
           WHERE c.sensor_id = sensors.sensor_id AND {counting}), \
         first_performed_at = coalesce((SELECT min(c.performed_at) FROM calibrations c \
           WHERE c.sensor_id = sensors.sensor_id AND {counting}), first_performed_at), \
         latest_calibration_id = coalesce({id}, latest_calibration_id), \
         latest_performed_at = coalesce({performed}, latest_performed_at), \
         latest_verdict = {verdict}, latest_due_at = {due} \
         WHERE sensor_id = {p}",
        counting = counts(Basis::NotRejected),
        id = of("id"),
        performed = of("performed_at"),
        verdict = of("verdict"),
        due = of("due_at"),
    )
}

/// Whether an act moving a calibration from `before` to `after` (storing
/// a replacement with it or not) changes its sensor's row: only when the
/// set of the sensor's calibrations that count on [`Basis::NotRejected`]
/// (the row's basis) changes — the row is computed from that set and from
/// columns a calibration never changes. An approval, a hold or its release
/// leave the set as it was, and the row is not recomputed: the recompute
/// reads every calibration of the sensor (BENCHMARKS.md "A sensor's
/// history").
pub fn changes_the_sensor(before: State, after: State, replaced: bool) -> bool {
    replaced || before.counts(Basis::NotRejected) != after.counts(Basis::NotRejected)
}

/// Removes a sensor's row when none of its calibrations counts any more
/// (after [`sensor_recompute`]): it is then no sensor anyone lists or
/// serves, though its calibrations stay, each with its state.
pub fn sensor_forget(p: &str) -> String {
    format!("DELETE FROM sensors WHERE sensor_id = {p} AND calibration_count = 0")
}

/// A calibration made with a reference standard: what a nonconformity's
/// window holds ([`crate::domain::nonconformity`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MadeWith {
    /// The calibration.
    pub calibration_id: Uuid,
    /// Its sensor.
    pub sensor_id: String,
    /// When it was performed.
    pub performed_at: Timestamp,
    /// Its state when read.
    pub state: State,
}

impl MadeWith {
    /// What a nonconformity's list says of this calibration: found in
    /// `found`, in `now` now, standing for it `replaced_by` when superseded,
    /// and what became of it.
    pub fn affected(self, found: State, now: State, replaced_by: Option<Replacement>) -> Affected {
        Affected {
            calibration_id: self.calibration_id,
            sensor_id: self.sensor_id,
            performed_at: self.performed_at,
            state_found: found,
            state: now,
            outcome: Outcome::of(found, now, replaced_by.as_ref().map(|r| r.state)),
            replaced_by,
        }
    }

    /// [`MadeWith::affected`] from the stored name of the state it was
    /// found in (`state_found`), its state as read being its state now;
    /// without its replacement (see [`chain_end_sql`]).
    pub fn found_as(self, stored: &str) -> Result<Affected, StoreError> {
        let found = State::parse(stored)
            .ok_or_else(|| StoreError::corrupt("column `state_found`", stored.to_owned()))?;
        let now = self.state;
        Ok(self.affected(found, now, None))
    }
}

impl Affected {
    /// This entry, superseded, with what stands for it now.
    pub fn replaced(mut self, by: Replacement) -> Affected {
        self.outcome = Outcome::of(self.state_found, self.state, Some(by.state));
        self.replaced_by = Some(by);
        self
    }
}

/// The last of the calibrations that replaced calibration `p` through
/// supersessions (`p` itself when none did), with its state: `id`, `state`.
pub fn chain_end_sql(p: &str) -> String {
    format!(
        "WITH RECURSIVE fwd(id, depth) AS ( \
           SELECT s.superseded_by, 1 FROM signatures s \
           WHERE s.calibration_id = {p} AND s.action = 'supersede' \
           UNION ALL \
           SELECT s.superseded_by, fwd.depth + 1 FROM signatures s JOIN fwd \
             ON s.calibration_id = fwd.id WHERE s.action = 'supersede' AND fwd.depth < 1000) \
         SELECT c.id, {} AS state FROM fwd JOIN calibrations c ON c.id = fwd.id \
         ORDER BY fwd.depth DESC LIMIT 1",
        crate::state_sql!()
    )
}

/// The columns of a nonconformity's row.
pub const NONCONFORMITY_COLUMNS: &str = "id, standard_id, found_at, last_known_good_at, \
     window_from, reason, recorded_at, token_id, role, holder";

/// The calibrations performed with the standard `$1` within `$2..=$3`
/// (`?1`… in SQLite), oldest first, with their states: the one query of
/// both engines but for how each reads a result's `standards` array
/// (`standards`: a condition on `c.result` naming the standard `$1`).
pub fn made_with_sql(standards: &str, p: [&str; 3]) -> String {
    format!(
        "SELECT c.id, c.sensor_id, c.performed_at, {} AS state FROM calibrations c \
         WHERE c.performed_at >= {} AND c.performed_at <= {} AND {standards} \
         ORDER BY c.performed_at, c.id",
        state_sql!(),
        p[1],
        p[2],
    )
}

/// Who submitted each calibration that calibration `p` replaces (directly,
/// or through earlier supersessions), nearest first: `submitted_by` — the
/// last row is the measurement's author
/// ([`crate::domain::review::Submitter::earlier`]). Each step by index
/// (`signatures_by_replacement`), each submitter by primary key: a join of
/// the steps with the calibrations let SQLite scan every calibration, an
/// approval taking 0.3 s at 100 000 (BENCHMARKS.md "A sensor's history").
pub fn earlier_submitters_sql(p: &str) -> String {
    format!(
        "WITH RECURSIVE back(id, depth) AS ( \
           SELECT s.calibration_id, 1 FROM signatures s \
           WHERE s.superseded_by = {p} AND s.action = 'supersede' \
           UNION ALL \
           SELECT s.calibration_id, back.depth + 1 FROM signatures s JOIN back \
             ON s.superseded_by = back.id WHERE s.action = 'supersede' AND back.depth < 1000) \
         SELECT (SELECT c.submitted_by FROM calibrations c WHERE c.id = back.id) AS submitted_by \
         FROM back ORDER BY back.depth"
    )
}

/// What recording a signed act came to.
#[derive(Debug, Clone, PartialEq)]
pub enum Signed {
    /// Recorded: the signature, and the calibration's sensor.
    Done(Signature, String),
    /// There is no such calibration.
    NotFound,
    /// The act is not allowed ([`crate::domain::review::Act::check`]).
    Refused(Refusal),
}

/// How a sensor's upsert merges into its stored row (`sensors`) what
/// `excluded` holds of its new calibrations (one, or several of a batch
/// folded into one row), in SQL that both engines run as it is — the one
/// statement of the rule:
///
/// * `calibration_count` adds up;
/// * `first_performed_at` is the least;
/// * the latest calibration is the greater by `(performed_at, id)`
///   ([`NEWEST_FIRST`]), and the latest verdict and due date are its;
/// * the assigned type is the new one when a write assigns one, and is
///   kept otherwise.
///
/// The sensor cache takes what the upsert answers ([`SENSOR_ROW`]) rather
/// than applying the rule again.
pub const SENSOR_MERGE: &str = "ON CONFLICT (sensor_id) DO UPDATE SET \
     calibration_count = sensors.calibration_count + excluded.calibration_count, \
     first_performed_at = CASE WHEN excluded.first_performed_at < sensors.first_performed_at \
       THEN excluded.first_performed_at ELSE sensors.first_performed_at END, \
     latest_calibration_id = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
       > (sensors.latest_performed_at, sensors.latest_calibration_id) \
       THEN excluded.latest_calibration_id ELSE sensors.latest_calibration_id END, \
     latest_verdict = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
       > (sensors.latest_performed_at, sensors.latest_calibration_id) \
       THEN excluded.latest_verdict ELSE sensors.latest_verdict END, \
     latest_due_at = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
       > (sensors.latest_performed_at, sensors.latest_calibration_id) \
       THEN excluded.latest_due_at ELSE sensors.latest_due_at END, \
     latest_performed_at = CASE WHEN excluded.latest_performed_at > sensors.latest_performed_at \
       THEN excluded.latest_performed_at ELSE sensors.latest_performed_at END, \
     sensor_type = coalesce(excluded.sensor_type, sensors.sensor_type)";

/// What the sensors' upsert answers ([`SENSOR_MERGE`] then this): the
/// sensor's row as the write left it.
pub const SENSOR_ROW: &str = "RETURNING sensor_id, calibration_count, first_performed_at, \
     latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at";

/// A sensor's stored row as a write left it ([`SENSOR_ROW`]): its summary
/// but for the latest calibration's, which the row names by id.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorRow {
    /// The sensor.
    pub sensor_id: String,
    /// How many calibrations it has.
    pub calibration_count: u64,
    /// The earliest `performed_at`.
    pub first_performed_at: Timestamp,
    /// The latest `performed_at`.
    pub latest_performed_at: Timestamp,
    /// The latest calibration, by [`NEWEST_FIRST`].
    pub latest_calibration_id: Uuid,
    /// The type assigned to it.
    pub sensor_type: Option<String>,
    /// The latest calibration's verdict.
    pub latest_verdict: Option<Verdict>,
    /// When the sensor is due, from its latest calibration.
    pub due_at: Option<Timestamp>,
}

impl SensorRow {
    /// The sensor's summary, given the calibration the row names as its
    /// latest — one of `candidates`, or `None` when it is none of them.
    /// The status is left `Unknown`: it depends on the time of a read.
    pub fn summary<'a>(
        self,
        candidates: impl IntoIterator<Item = &'a CalibrationSummary>,
    ) -> Option<SensorSummary> {
        let latest = candidates
            .into_iter()
            .find(|c| c.id == self.latest_calibration_id)?
            .clone();
        Some(SensorSummary {
            sensor_id: self.sensor_id,
            calibration_count: self.calibration_count,
            first_performed_at: self.first_performed_at,
            latest_performed_at: self.latest_performed_at,
            sensor_type: self.sensor_type,
            latest_verdict: self.latest_verdict,
            due_at: self.due_at,
            status: Status::Unknown,
            latest,
        })
    }
}

#[cfg(test)]
impl SensorSummary {
    /// A sensor for tests: one calibration,
    /// [`CalibrationSummary::for_test`]`(7, sensor, 0.0, 1.0)`, untyped.
    pub(crate) fn for_test(sensor: &str) -> Self {
        let latest = CalibrationSummary::for_test(7, sensor, 0.0, 1.0);
        SensorSummary {
            sensor_id: sensor.into(),
            calibration_count: 1,
            first_performed_at: latest.performed_at,
            latest_performed_at: latest.performed_at,
            sensor_type: None,
            latest_verdict: None,
            due_at: None,
            status: Status::Unknown,
            latest,
        }
    }
}

/// Which sensors to list, in id order.
#[derive(Debug, Clone)]
pub struct SensorQuery {
    /// Only those after this id.
    pub after: Option<String>,
    /// Only those with this status.
    pub status: Option<Status>,
    /// Only those whose id contains this text (ASCII case-insensitive).
    pub search: Option<String>,
    /// The time statuses are computed at.
    pub now: Timestamp,
    /// Page size.
    pub limit: usize,
}

/// Which calibrations of a sensor to list, newest first.
#[derive(Debug, Clone, Default)]
pub struct HistoryQuery {
    /// Only those performed at or after this instant.
    pub from: Option<Timestamp>,
    /// Only those performed at or before this instant.
    pub to: Option<Timestamp>,
    /// Keyset cursor: only calibrations after this one in the list's order
    /// (older `performed_at`, or equal and smaller id).
    pub before: Option<Uuid>,
    /// Page size.
    pub limit: usize,
}

/// An idempotency key as scoped and fingerprinted by the server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdempotencyKey {
    /// The principal (token id) that sent it.
    pub principal: String,
    /// The client's key.
    pub key: String,
    /// `SHA-256` of the request's media type and body.
    pub request_hash: [u8; 32],
    /// The request holding the key's lease (a fresh id per request): only
    /// it may release the key, and only while it holds the lease.
    pub holder: Uuid,
}

/// The latest calibrations of a sensor within a window, oldest first, and
/// how many the window holds (more than `items` when the limit cut it).
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// The calibrations, oldest first.
    pub items: Vec<CalibrationSummary>,
    /// Calibrations in the window.
    pub in_window: usize,
}

/// A completed idempotency key, as copied from one database to another.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DoneKey {
    /// The principal that sent it.
    pub principal: String,
    /// The client's key.
    pub key: String,
    /// `SHA-256` of the request's media type and body.
    pub request_hash: [u8; 32],
    /// The calibration its request stored.
    pub calibration_id: Uuid,
    /// When it was first claimed.
    pub created_at: Timestamp,
}

/// What claiming an idempotency key found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Claim {
    /// The key is new (or its previous holder's lease expired): go ahead.
    Fresh,
    /// The same request is being processed under this key right now.
    InFlight,
    /// The key was used with a different request.
    Mismatch,
    /// The same request already stored this calibration.
    Done(Uuid),
}

/// What storing a calibration under an idempotency key did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stored {
    /// The calibration was stored.
    New,
    /// A concurrent request with the same key stored this one first; nothing
    /// new was stored.
    Existing(Uuid),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::status::Status;

    fn ts(s: &str) -> Timestamp {
        Timestamp::parse(s).unwrap()
    }

    /// A calibration of `S` with id `id`, performed at `at`.
    fn cal(id: u128, at: &str) -> CalibrationSummary {
        CalibrationSummary {
            performed_at: ts(at),
            ..CalibrationSummary::for_test(id, "S", 0.0, 1.0)
        }
    }

    /// The row names its latest calibration by id: the summary takes it
    /// from the candidates, or there is none.
    #[test]
    fn a_rows_latest_is_the_candidate_it_names() {
        let row = SensorRow {
            sensor_id: "S".into(),
            calibration_count: 3,
            first_performed_at: ts("2026-01-01T00:00:00Z"),
            latest_performed_at: ts("2026-03-01T00:00:00Z"),
            latest_calibration_id: Uuid::from_u128(50),
            sensor_type: Some("A".into()),
            latest_verdict: Some(Verdict::Pass),
            due_at: Some(ts("2027-03-01T00:00:00Z")),
        };
        let (a, b) = (
            cal(49, "2026-03-01T00:00:00Z"),
            cal(50, "2026-03-01T00:00:00Z"),
        );
        let got = row.clone().summary([&a, &b]).unwrap();
        assert_eq!(got.latest, b);
        assert_eq!(
            (got.calibration_count, got.sensor_type.as_deref()),
            (3, Some("A"))
        );
        assert_eq!(got.latest_verdict, Some(Verdict::Pass));
        assert_eq!(got.status, Status::Unknown);
        assert_eq!(row.summary([&a]), None);
    }

    /// A stored record's summary carries every field the record has.
    #[test]
    fn a_new_calibrations_summary_is_its_fields() {
        let c = CalibrationSummary {
            station_id: Some("LAB".into()),
            sensor_type: Some("A".into()),
            verdict: Some(Verdict::Conditional),
            due_at: Some(ts("2027-01-01T00:00:00Z")),
            expanded: Some(TermMap(vec![])),
            received_at: ts("2026-01-02T00:00:00Z"),
            triad: Some(elements()),
            ..cal(9, "2026-01-01T00:00:00Z")
        };
        let n = NewCalibration {
            id: c.id,
            sensor_id: c.sensor_id.clone(),
            station_id: c.station_id.clone(),
            performed_at: c.performed_at,
            received_at: c.received_at,
            unit: c.unit.clone(),
            model: c.model.clone(),
            runs: c.runs,
            coefficients: c.coefficients.clone(),
            std_errors: c.std_errors.clone(),
            result: Bytes::from_static(b"{}"),
            submission: Bytes::from_static(b"{}"),
            content_type: "application/json".into(),
            submitted_by: "x".into(),
            sensor_type: c.sensor_type.clone(),
            assigns_type: true,
            verdict: c.verdict,
            due_at: c.due_at,
            expanded: c.expanded.clone(),
            triad: c.triad.clone(),
            standards: Vec::new(),
        };
        assert_eq!(CalibrationSummary::from(&n), c);
        n.check().unwrap();
    }

    /// A triad with distinct numbers everywhere: `S = 2 I + small`,
    /// `T` its stand-in, standard errors for `b` and `S`.
    fn elements() -> TriadElements {
        TriadElements {
            method: "known_orientations".into(),
            b: [0.1, 0.2, 0.3],
            b_std_errors: Some([1e-3, 2e-3, 3e-3]),
            s: [[2.0, 0.01, 0.02], [0.03, 2.1, 0.04], [0.05, 0.06, 2.2]],
            s_std_errors: Some([[1e-4; 3]; 3]),
            t: [[0.5, 0.0, 0.0], [0.0, 0.47, 0.0], [0.0, 0.0, 0.45]],
            t_std_errors: None,
            b_expanded: None,
            s_expanded: None,
            s2: None,
            s2_std_errors: None,
            s2_expanded: None,
        }
    }

    /// Every stored number is named by axis, row then column, and the
    /// standard errors present; any of them non-finite refuses the record.
    #[test]
    fn a_triads_numbers_are_named_and_must_be_finite() {
        let e = elements();
        let numbers = e.numbers();
        assert_eq!(numbers.len(), 3 + 9 + 9 + 3 + 9);
        let get = |name: &str| numbers.iter().find(|(n, _)| n == name).map(|(_, v)| *v);
        assert_eq!(get("b_y"), Some(0.2));
        assert_eq!(get("S_xy"), Some(0.01));
        assert_eq!(get("S_yx"), Some(0.03));
        assert_eq!(get("S_zy"), Some(0.06));
        assert_eq!(get("T_yy"), Some(0.47));
        assert_eq!(get("b_z_std_error"), Some(3e-3));
        assert_eq!(get("T_xx_std_error"), None);
        let elements = e.elements();
        assert_eq!(elements.len(), 21);
        let at = |k: usize| {
            let x = &elements[k];
            (x.name.as_str(), x.value, x.std_error, x.measured)
        };
        assert_eq!(at(1), ("b_y", 0.2, Some(2e-3), true));
        assert_eq!(at(3 + 7), ("S_zy", 0.06, Some(1e-4), true));
        assert_eq!(at(12 + 4), ("T_yy", 0.47, None, false));
        // From the gravity magnitude, S above the diagonal is the frame
        // convention's, not measured.
        let gravity = TriadElements {
            method: "gravity_magnitude".into(),
            ..e.clone()
        }
        .elements();
        let measured: Vec<&str> = gravity
            .iter()
            .filter(|x| x.measured)
            .map(|x| x.name.as_str())
            .collect();
        assert_eq!(
            measured,
            [
                "b_x", "b_y", "b_z", "S_xx", "S_yx", "S_yy", "S_zx", "S_zy", "S_zz"
            ]
        );
        let record = |triad: TriadElements| NewCalibration {
            triad: Some(triad),
            ..NewCalibration {
                id: Uuid::from_u128(1),
                sensor_id: "S".into(),
                station_id: None,
                performed_at: ts("2026-01-01T00:00:00Z"),
                received_at: ts("2026-01-01T00:00:00Z"),
                unit: "g".into(),
                model: Model::new(vec![accelcal_core::Term::K0]).unwrap(),
                runs: 1,
                coefficients: TermMap(vec![]),
                std_errors: TermMap(vec![]),
                result: Bytes::new(),
                submission: Bytes::new(),
                content_type: "application/json".into(),
                submitted_by: "x".into(),
                sensor_type: None,
                assigns_type: false,
                verdict: None,
                due_at: None,
                expanded: None,
                triad: None,
                standards: Vec::new(),
            }
        };
        record(e.clone()).check().unwrap();
        let mut bad = e.clone();
        bad.s[2][1] = f64::NAN;
        let err = record(bad).check().unwrap_err().to_string();
        assert!(err.contains("`S_zy` is NaN"), "{err}");
        let mut bad = e;
        bad.b_std_errors = Some([0.0, f64::INFINITY, 0.0]);
        let err = record(bad).check().unwrap_err().to_string();
        assert!(err.contains("`b_y_std_error` is inf"), "{err}");
    }
}
