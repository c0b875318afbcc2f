//! Triad submissions (issue 30): three outputs at once, `u = b + S g`.
//!
//! One body, three forms, exactly one of which is given:
//!
//! * **known orientations** — `orientations` (gravity vectors in the body
//!   frame, in g, or a named set: `six_faces`, `cube24`) and `runs`, each
//!   run's samples of `(u_x, u_y, u_z)` per position: each axis is
//!   identified and fused by the single-axis method over the shared
//!   positions ([`accelcal_core::triad`]);
//! * **unknown orientations** — `static_positions`, each position's samples:
//!   `b` and `T = S⁻¹` from the gravity magnitude
//!   ([`accelcal_core::gravity_fit`]);
//! * **a recording** — `recording` (`rate_hz`, samples, optional `detector`
//!   parameters): its static intervals ([`accelcal_core::static_intervals`])
//!   become the static positions.
//!
//! [`TriadBody::check`] names every fault by JSON pointer; [`compute`]
//! answers a [`TriadResult`], whose `b`, `S` and `T` also feed the exports
//! ([`super::triad_export`]).

use accelcal_core::gravity_budget::{self, GravityBudget};
use accelcal_core::gravity_fit::{self, GravityFit, GravityFitError, MIN_POSITIONS};
use accelcal_core::static_intervals::{self, DetectError, Detection, Detector, Rejection};
use accelcal_core::triad::{AXES, Triad, TriadError, TriadRun, TriadTest, six_faces};
use std::collections::BTreeMap;

use accelcal_core::adequacy::model_uncertainty;
use accelcal_core::coverage::Coverage;
use accelcal_core::decision::{Limit, Rule, TermDecision, Verdict, decide};
use accelcal_core::quality;
use accelcal_core::uncertainty::{ARCSEC, Stand, TermBudget, budget};
use accelcal_core::{Term, TermMap};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::field::{Errors, Invalid, Loc};
use super::limits::{
    MAX_ANGLE_STD_ARCSEC, MAX_BATCHES, MAX_GRAVITY_REL_STD, MAX_ID_CHARS, MAX_POSITIONS,
    MAX_READING, MAX_RUNS, MAX_TOTAL_SAMPLES, MAX_UNIT_CHARS,
};
use super::standards::UsedStandard;
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// Largest sampling rate, Hz.
const MAX_RATE_HZ: f64 = 1e6;
/// Largest detector time, s.
const MAX_DETECTOR_S: f64 = 3600.0;
/// Largest detector threshold multiple.
const MAX_THRESHOLD: f64 = 1e6;
/// The detector's smallest settings: a still period and a shortest
/// interval of 0.5 s, a window of 0.1 s and of at least
/// [`MIN_WINDOW_SAMPLES`] samples, and a threshold of 2 — at a threshold near
/// 1 the still noise's own variance crosses it half the time, and one held
/// orientation falls apart into many short "intervals".
pub const MIN_DETECTOR: Detector = Detector {
    still_s: 0.5,
    window_s: 0.1,
    threshold: 2.0,
    min_static_s: 0.5,
};
/// Fewest samples in the detector's moving window.
pub const MIN_WINDOW_SAMPLES: f64 = 10.0;

/// The body of `POST /v1/identify/triad`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadBody {
    /// The triad's id: echoed by `POST /v1/identify/triad`, required to
    /// store it (`POST /v1/calibrations/triad`); letters, digits and
    /// `. _ : -`, at most 64 characters.
    #[serde(default)]
    pub sensor_id: Option<String>,
    /// The submitting station (stored; a station-bound token's own).
    #[serde(default)]
    pub station_id: Option<String>,
    /// When the test was performed, RFC 3339 (stored; default: when
    /// received).
    #[serde(default)]
    pub performed_at: Option<String>,
    /// The outputs' unit (default `output`): `m/s2` or `g` for the PX4 and
    /// ArduPilot exports.
    #[serde(default)]
    pub unit: Option<String>,
    /// Known orientations: specific force in the body frame, in g, per
    /// position (each of magnitude 1), or `six_faces` (+x, −x, +y, −y, +z,
    /// −z up) or `cube24` (the 24 orientations of a cube: each face up,
    /// turned four times about the vertical).
    #[serde(default)]
    pub orientations: Option<OrientationsBody>,
    /// With `orientations`: each run's samples per position.
    #[serde(default)]
    pub runs: Option<Vec<TriadRunBody>>,
    /// With `orientations`: batches for the fusion (default 1).
    #[serde(default)]
    pub batches: Option<usize>,
    /// Unknown orientations: each static position's samples of
    /// `(u_x, u_y, u_z)` (at least nine positions).
    #[serde(default)]
    pub static_positions: Option<Vec<Vec<[f64; 3]>>>,
    /// Unknown orientations from one continuous recording.
    #[serde(default)]
    pub recording: Option<RecordingBody>,
    /// The uncertainty budget's stand: with `orientations`, the dividing
    /// head's indexing error and the local gravity's relative uncertainty
    /// (each default 0); without, only `gravity_rel_std` (the fit uses no
    /// orientation, so no indexing error enters it).
    #[serde(default)]
    pub stand: Option<TriadStandBody>,
    /// Stored triads: the sensor type whose limits judge the elements (the
    /// sensor's own by default; as for a single-axis submission).
    #[serde(default)]
    pub sensor_type: Option<String>,
    /// Reference standards from the registry, by id: the `stand` (its
    /// indexing error enters the budget instead of `stand`'s) and the local
    /// `gravity` value; each must be in calibration when the test was
    /// performed. Stored triads only.
    #[serde(default)]
    pub standards: Option<TriadStandardsBody>,
    /// With `orientations`: give each axis its second-order term `kii`
    /// (`S2_m g_m²`); compensation then solves the model by Newton's
    /// iteration.
    #[serde(default)]
    pub second_order: Option<bool>,
}

/// The reference standards a triad names (`standards`).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadStandardsBody {
    /// The tumble stand or dividing head.
    #[serde(default)]
    pub stand: Option<String>,
    /// The local gravity value.
    #[serde(default)]
    pub gravity: Option<String>,
}

/// A triad's stand (`stand`): at least one of the two.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadStandBody {
    /// Indexing error of the dividing head, arcseconds (1σ, 0 to 3600;
    /// default 0). Known orientations only.
    #[serde(default)]
    pub angle_std_arcsec: Option<f64>,
    /// Relative uncertainty of the local gravity magnitude (0 to 0.1;
    /// default 0).
    #[serde(default)]
    pub gravity_rel_std: Option<f64>,
}

/// Orientations: given, or a named set.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum OrientationsBody {
    /// `six_faces` or `cube24`.
    Named(NamedSet),
    /// Gravity vectors in the body frame, in g.
    Vectors(Vec<[f64; 3]>),
}

/// A named set of orientations.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, ToSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum NamedSet {
    /// +x, −x, +y, −y, +z, −z up.
    SixFaces,
    /// Each face up, turned 0°, 90°, 180°, 270° about the vertical: the body
    /// sees each face's gravity vector four times.
    Cube24,
}

/// One run of a triad with known orientations.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadRunBody {
    /// Per position, its samples of `(u_x, u_y, u_z)`.
    pub samples: Vec<Vec<[f64; 3]>>,
}

/// A continuous recording. Its static intervals count against the same
/// limit as explicit positions (360).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RecordingBody {
    /// Samples per second.
    pub rate_hz: f64,
    /// The samples of `(u_x, u_y, u_z)`, in time order.
    pub samples: Vec<[f64; 3]>,
    /// The detector's parameters (each defaulted).
    #[serde(default)]
    pub detector: Option<DetectorBody>,
}

/// The static-interval detector's parameters.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DetectorBody {
    /// The initial still period, s (default 3, at least 0.5).
    #[serde(default)]
    pub still_s: Option<f64>,
    /// The moving-variance window, s (default 1, at least 0.1 s and 10
    /// samples).
    #[serde(default)]
    pub window_s: Option<f64>,
    /// Static where the window's variance is at most this multiple of the
    /// still period's (default 6, at least 2).
    #[serde(default)]
    pub threshold: Option<f64>,
    /// The shortest interval used, s (default 2, at least 0.5).
    #[serde(default)]
    pub min_static_s: Option<f64>,
}

impl DetectorBody {
    fn detector(self) -> Detector {
        let d = Detector::default();
        Detector {
            still_s: self.still_s.unwrap_or(d.still_s),
            window_s: self.window_s.unwrap_or(d.window_s),
            threshold: self.threshold.unwrap_or(d.threshold),
            min_static_s: self.min_static_s.unwrap_or(d.min_static_s),
        }
    }
}

/// A checked triad submission.
#[derive(Debug, Clone)]
pub struct TriadSubmission {
    /// The triad's id.
    pub sensor_id: Option<String>,
    /// The submitting station.
    pub station_id: Option<String>,
    /// When the test was performed, as stated.
    pub performed_at: Option<Timestamp>,
    /// The outputs' unit.
    pub unit: String,
    /// What to compute.
    pub form: Form,
    /// The stand (known orientations).
    pub stand: Stand,
    /// The sensor type named, if any.
    pub sensor_type: Option<String>,
    /// What the expanded uncertainties hold fixed: the sensor type's when
    /// one judges the triad (set by the caller), else the default
    /// probability.
    pub coverage: Coverage,
    /// The reference standards named, by role (`stand`, `gravity`).
    pub standards: Vec<(&'static str, String)>,
}

/// The three forms.
#[derive(Debug, Clone)]
pub enum Form {
    /// Known orientations.
    Known {
        /// Gravity vectors.
        positions: Vec<[f64; 3]>,
        /// Runs.
        runs: Vec<TriadRun>,
        /// Batches.
        batches: usize,
        /// Each axis with its `kii`.
        second_order: bool,
    },
    /// The static positions' mean outputs.
    Unknown {
        /// Per position, the mean of its samples.
        means: Vec<[f64; 3]>,
    },
    /// A recording.
    Recording {
        /// Samples per second.
        rate_hz: f64,
        /// The samples.
        samples: Vec<[f64; 3]>,
        /// The detector.
        detector: Detector,
    },
}

/// A one-line label of at most `max` characters.
fn label(at: Loc<'_>, text: Option<String>, max: usize, errors: &mut Errors) -> Option<String> {
    let t = text?;
    if let Err(why) = check_str(&t, max, Chars::Line) {
        errors.add(at, why);
    }
    Some(t)
}

/// Three outputs, each finite and within ±[`MAX_READING`].
fn reading(at: Loc<'_>, u: &[f64; 3], errors: &mut Errors) {
    if u.iter().any(|x| !(x.is_finite() && x.abs() <= MAX_READING)) {
        errors.add(
            at,
            format!("must be three finite numbers within ±{MAX_READING:e}"),
        );
    }
}

/// The detector's settings within [`MIN_DETECTOR`] and their largest
/// values, its window at least [`MIN_WINDOW_SAMPLES`] samples at `rate_hz`.
fn check_detector(d: &Detector, rate_hz: f64, at: Loc<'_>, errors: &mut Errors) {
    let min = MIN_DETECTOR;
    for (name, v, lo, hi) in [
        ("still_s", d.still_s, min.still_s, MAX_DETECTOR_S),
        ("window_s", d.window_s, min.window_s, MAX_DETECTOR_S),
        ("threshold", d.threshold, min.threshold, MAX_THRESHOLD),
        (
            "min_static_s",
            d.min_static_s,
            min.min_static_s,
            MAX_DETECTOR_S,
        ),
    ] {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            errors.add(at.key(name), format!("must be a number from {lo} to {hi}"));
        }
    }
    // The window's length in samples, once the window itself is in range.
    let samples = d.window_s * rate_hz;
    if rate_hz.is_finite()
        && rate_hz > 0.0
        && (min.window_s..=MAX_DETECTOR_S).contains(&d.window_s)
        && samples < MIN_WINDOW_SAMPLES
    {
        errors.add(
            at.key("window_s"),
            format!(
                "holds {samples} samples at {rate_hz} Hz: the moving window needs at least \
                 {MIN_WINDOW_SAMPLES} (at least {} s)",
                MIN_WINDOW_SAMPLES / rate_hz
            ),
        );
    }
}

/// At most `max` items.
fn at_most(at: Loc<'_>, n: usize, max: usize, what: &str, errors: &mut Errors) -> bool {
    if n > max {
        errors.add(at, format!("{n} {what}: at most {max}"));
        return false;
    }
    true
}

impl TriadBody {
    /// Checks the body: exactly one form, its shape, finite numbers.
    pub fn check(self) -> Result<TriadSubmission, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        let mut identifier = |name: &str, value: &Option<String>| {
            let v = value.as_ref()?;
            match check_str(v, MAX_ID_CHARS, Chars::Identifier) {
                Ok(()) => Some(v.clone()),
                Err(why) => {
                    errors.add(root.key(name), why);
                    None
                }
            }
        };
        let sensor_id = identifier("sensor_id", &self.sensor_id);
        let station_id = identifier("station_id", &self.station_id);
        let sensor_type = identifier("sensor_type", &self.sensor_type);
        let mut standards = Vec::new();
        if let Some(named) = &self.standards {
            let standards_at = root.key("standards");
            for (role, id) in [("stand", &named.stand), ("gravity", &named.gravity)] {
                if let Some(id) = id {
                    match check_str(id, MAX_ID_CHARS, Chars::Identifier) {
                        Ok(()) => standards.push((role, id.clone())),
                        Err(why) => errors.add(standards_at.key(role), why),
                    }
                }
            }
            if named.stand.is_some() && self.orientations.is_none() {
                errors.add(
                    standards_at.key("stand"),
                    "is for known orientations: a fit from the gravity magnitude uses no \
                     orientation, so its result does not depend on a stand (name the `gravity` \
                     standard alone)",
                );
            }
            if named.stand.is_none() && named.gravity.is_none() {
                errors.add(
                    root.key("standards"),
                    "must name a `stand`, a `gravity` or both",
                );
            }
            if self.stand.is_some() {
                errors.add(
                    root.key("stand"),
                    "is given with `standards`: the registered standards' values (the stand's indexing error, the gravity's uncertainty) are the ones used",
                );
            }
        }
        let performed_at = self
            .performed_at
            .as_deref()
            .and_then(|t| match Timestamp::parse(t) {
                Ok(t) => Some(t),
                Err(e) => {
                    errors.add(root.key("performed_at"), e.to_string());
                    None
                }
            });
        let unit = label(
            root.key("unit"),
            self.unit.clone(),
            MAX_UNIT_CHARS,
            &mut errors,
        )
        .unwrap_or_else(|| "output".into());
        let given = [
            self.orientations.is_some(),
            self.static_positions.is_some(),
            self.recording.is_some(),
        ];
        if self.second_order == Some(true) && self.orientations.is_none() {
            errors.add(
                root.key("second_order"),
                "is for known orientations: the gravity magnitude fits b and T only",
            );
        }
        let stand = match self.stand {
            None => Stand::default(),
            Some(st) => {
                let at = root.key("stand");
                if st.angle_std_arcsec.is_none() && st.gravity_rel_std.is_none() {
                    errors.add(
                        at,
                        "must give `angle_std_arcsec`, `gravity_rel_std` or both",
                    );
                }
                if st.angle_std_arcsec.is_some() && self.orientations.is_none() {
                    errors.add(
                        at.key("angle_std_arcsec"),
                        "is for known orientations: a fit from the gravity magnitude uses no \
                         orientation, so no indexing error enters its budget (give \
                         `gravity_rel_std` alone)",
                    );
                }
                for (name, v, max) in [
                    (
                        "angle_std_arcsec",
                        st.angle_std_arcsec,
                        MAX_ANGLE_STD_ARCSEC,
                    ),
                    ("gravity_rel_std", st.gravity_rel_std, MAX_GRAVITY_REL_STD),
                ] {
                    if v.is_some_and(|v| !(v.is_finite() && (0.0..=max).contains(&v))) {
                        errors.add(at.key(name), format!("must be a number from 0 to {max}"));
                    }
                }
                Stand {
                    angle_std_rad: st.angle_std_arcsec.unwrap_or(0.0) * ARCSEC,
                    gravity_rel_std: st.gravity_rel_std.unwrap_or(0.0),
                    ..Stand::default()
                }
            }
        };
        let form = match given {
            [true, false, false] => self.known(&mut errors),
            [false, true, false] => {
                let positions = self.static_positions.unwrap_or_default();
                let at = root.key("static_positions");
                if positions.len() < MIN_POSITIONS {
                    errors.add(
                        at,
                        format!(
                            "{} positions: at least {MIN_POSITIONS} are needed to find b and T \
                             without known orientations",
                            positions.len()
                        ),
                    );
                }
                let total: usize = positions.iter().map(Vec::len).sum();
                let means = if at_most(at, positions.len(), MAX_POSITIONS, "positions", &mut errors)
                    && at_most(at, total, MAX_TOTAL_SAMPLES, "samples", &mut errors)
                {
                    positions
                        .iter()
                        .enumerate()
                        .map(|(r, samples)| {
                            if samples.is_empty() {
                                errors.add(at.index(r), "must hold at least one sample");
                            }
                            for (k, u) in samples.iter().enumerate() {
                                reading(at.index(r).index(k), u, &mut errors);
                            }
                            mean(samples)
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                Some(Form::Unknown { means })
            }
            [false, false, true] => {
                let r = self.recording.expect("given");
                let at = root.key("recording");
                if !(r.rate_hz.is_finite() && r.rate_hz > 0.0 && r.rate_hz <= MAX_RATE_HZ) {
                    errors.add(
                        at.key("rate_hz"),
                        format!("must be a positive number of samples per second, at most {MAX_RATE_HZ:e}"),
                    );
                }
                let samples_at = at.key("samples");
                if at_most(
                    samples_at,
                    r.samples.len(),
                    MAX_TOTAL_SAMPLES,
                    "samples",
                    &mut errors,
                ) {
                    for (k, u) in r.samples.iter().enumerate() {
                        reading(samples_at.index(k), u, &mut errors);
                    }
                }
                let detector = r.detector.unwrap_or_default().detector();
                check_detector(&detector, r.rate_hz, at.key("detector"), &mut errors);
                Some(Form::Recording {
                    rate_hz: r.rate_hz,
                    samples: r.samples,
                    detector,
                })
            }
            _ => {
                errors.add(
                    root,
                    "give exactly one of `orientations` (with `runs`), `static_positions` or \
                     `recording`",
                );
                None
            }
        };
        errors.finish(|| TriadSubmission {
            sensor_id,
            station_id,
            performed_at,
            stand,
            sensor_type,
            coverage: Coverage::default(),
            standards,
            unit,
            form: form.expect("a form when nothing is wrong"),
        })
    }

    fn known(self, errors: &mut Errors) -> Option<Form> {
        let root = Loc::Root;
        let positions = match self.orientations.expect("given") {
            OrientationsBody::Named(NamedSet::SixFaces) => six_faces(),
            OrientationsBody::Named(NamedSet::Cube24) => six_faces()
                .into_iter()
                .flat_map(|g| std::iter::repeat_n(g, 4))
                .collect(),
            OrientationsBody::Vectors(v) => {
                let all = root.key("orientations");
                for (r, g) in v.iter().enumerate() {
                    let at = all.index(r);
                    let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if !norm.is_finite() || (norm - 1.0).abs() > 0.01 {
                        errors.add(
                            at,
                            format!(
                                "a position's specific force is 1 g: this one's magnitude is {norm}"
                            ),
                        );
                    }
                }
                v
            }
        };
        let Some(runs) = self.runs else {
            errors.add(root.key("runs"), "is required with `orientations`");
            return None;
        };
        if runs.is_empty() {
            errors.add(root.key("runs"), "must hold at least one run");
        }
        let total: usize = runs
            .iter()
            .flat_map(|r| r.samples.iter().map(Vec::len))
            .sum();
        if !(at_most(
            root.key("orientations"),
            positions.len(),
            MAX_POSITIONS,
            "orientations",
            errors,
        ) && at_most(root.key("runs"), runs.len(), MAX_RUNS, "runs", errors)
            && at_most(
                root.key("runs"),
                total,
                MAX_TOTAL_SAMPLES,
                "samples",
                errors,
            ))
        {
            return None;
        }
        let all = root.key("runs");
        for (j, run) in runs.iter().enumerate() {
            let run_at = all.index(j);
            let at = run_at.key("samples");
            if run.samples.len() != positions.len() {
                errors.add(
                    at,
                    format!(
                        "has {} positions; the orientations are {}",
                        run.samples.len(),
                        positions.len()
                    ),
                );
            }
            for (r, samples) in run.samples.iter().enumerate() {
                if samples.is_empty() {
                    errors.add(at.index(r), "must hold at least one sample");
                }
                for (k, u) in samples.iter().enumerate() {
                    reading(at.index(r).index(k), u, errors);
                }
            }
        }
        let batches = self.batches.unwrap_or(1);
        if batches == 0 || batches > runs.len().max(1) || batches as u64 > MAX_BATCHES {
            errors.add(
                root.key("batches"),
                "must be between 1 and the number of runs",
            );
        }
        Some(Form::Known {
            positions,
            runs: runs
                .into_iter()
                .map(|r| TriadRun { samples: r.samples })
                .collect(),
            batches,
            second_order: self.second_order.unwrap_or(false),
        })
    }
}

fn mean(samples: &[[f64; 3]]) -> [f64; 3] {
    let n = samples.len().max(1) as f64;
    let mut m = [0.0; 3];
    for u in samples {
        for k in 0..3 {
            m[k] += u[k] / n;
        }
    }
    m
}

/// One axis's single-axis identification within a triad.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct AxisResult {
    /// `x`, `y` or `z`.
    pub axis: &'static str,
    /// The arithmetic mean across runs with eq. 8 dispersion.
    #[schema(value_type = Object)]
    pub mean: serde_json::Value,
    /// The batch-estimation fusion with eq. 8 dispersion.
    #[schema(value_type = Object)]
    pub fused: serde_json::Value,
    /// The axis's uncertainty budget, as a single-axis calibration's
    /// (standard error, stand indexing, gravity, model; expanded with
    /// `coverage_factor`).
    #[schema(value_type = Object)]
    pub uncertainty: serde_json::Value,
    /// The single-axis method's quality warnings for the axis.
    #[schema(value_type = Object)]
    pub quality: serde_json::Value,
}

/// Levenberg–Marquardt's report.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct FitReport {
    /// Residual evaluations made.
    pub evaluations: usize,
    /// Why it stopped: `converged`, `orthogonal` or `residuals_zero`.
    pub stop: &'static str,
    /// The directions' spread (reciprocal condition of the normalised
    /// Jacobian).
    pub spread: f64,
    /// The least spread accepted.
    pub min_spread: f64,
    /// Root mean square of the residuals, g.
    pub rms_g: f64,
    /// Residual degrees of freedom, positions − 9 (the standard errors rest
    /// on them; none with exactly nine).
    pub degrees_of_freedom: usize,
}

/// The elements of `S` that are zero by the frame convention of a triad
/// found from the gravity magnitude (the sensor's x axis and xy-plane
/// define the frame): `(row, column)` above the diagonal. Not measured,
/// so never judged.
pub const FIXED_BY_CONVENTION: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// `coverage` as [`accelcal_core::uncertainty::stated`] writes it, nothing
/// when there is none.
fn stated<S: serde::Serializer>(coverage: &Option<Coverage>, s: S) -> Result<S::Ok, S::Error> {
    match coverage {
        Some(c) => accelcal_core::uncertainty::stated(c, s),
        None => serde::ser::SerializeMap::end(s.serialize_map(Some(0))?),
    }
}

/// How one element's expanded uncertainty was formed: its combined
/// standard uncertainty, effective degrees of freedom, coverage factor and
/// probability (Welch–Satterthwaite and Student's t).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ElementCoverage {
    /// The combined standard uncertainty `u_c`.
    pub combined: f64,
    /// Its effective degrees of freedom; null when infinite.
    pub effective_dof: Option<u64>,
    /// `k`.
    pub coverage_factor: f64,
    /// `p`.
    pub coverage_probability: f64,
}

impl From<&TermBudget> for ElementCoverage {
    fn from(b: &TermBudget) -> Self {
        ElementCoverage {
            combined: b.combined,
            effective_dof: b.effective_dof,
            coverage_factor: b.coverage_factor,
            coverage_probability: b.coverage_probability,
        }
    }
}

/// The uncertainty budget of a triad found from the gravity magnitude,
/// element by element ([`accelcal_core::gravity_budget`]).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct GravityUncertainty {
    /// What the expanded uncertainties hold fixed.
    #[serde(flatten, serialize_with = "accelcal_core::uncertainty::stated")]
    #[schema(value_type = crate::domain::schema::CoverageStated)]
    pub coverage: Coverage,
    /// The fit's residual degrees of freedom, which the statistical
    /// components rest on.
    pub degrees_of_freedom: usize,
    /// The relative uncertainty of the gravity magnitude used (1σ).
    pub gravity_rel_std: f64,
    /// Per element of `b` and of `S` on and below the diagonal (`b_x`,
    /// `S_yx`, …): statistical (the fit's standard error), indexing (0:
    /// the fit uses no orientation), gravity, model (0: the residuals'
    /// scatter holds any misfit), combined, expanded.
    #[schema(value_type = BTreeMap<String, Object>)]
    pub elements: BTreeMap<String, TermBudget>,
    /// The elements of `S` zero by the frame convention: not measured, not
    /// judged.
    pub fixed_by_convention: Vec<String>,
}

impl GravityUncertainty {
    fn of(budget: &GravityBudget, gravity_rel_std: f64) -> Self {
        let mut elements = BTreeMap::new();
        for m in 0..3 {
            elements.insert(element(m, Slot::B), budget.b[m]);
            for k in 0..=m {
                elements.insert(element(m, Slot::S(k)), budget.s[m][k]);
            }
        }
        GravityUncertainty {
            coverage: budget.coverage,
            degrees_of_freedom: budget.degrees_of_freedom,
            gravity_rel_std,
            elements,
            fixed_by_convention: FIXED_BY_CONVENTION
                .iter()
                .map(|(m, k)| element(*m, Slot::S(*k)))
                .collect(),
        }
    }
}

/// One static interval of a recording.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct IntervalReport {
    /// Its start, s from the recording's start.
    pub start_s: f64,
    /// Its end, s.
    pub end_s: f64,
    /// Whether it is one of the positions.
    pub used: bool,
    /// Why not: `too_short`.
    pub rejected: Option<&'static str>,
    /// Its mean outputs.
    pub mean: [f64; 3],
}

/// What the detector did with a recording.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct DetectionReport {
    /// The parameters used.
    pub still_s: f64,
    /// The window, s.
    pub window_s: f64,
    /// The threshold multiple.
    pub threshold: f64,
    /// The shortest interval used, s.
    pub min_static_s: f64,
    /// The initial still period's variance (sum over the axes).
    pub still_variance: f64,
    /// The variance threshold.
    pub threshold_variance: f64,
    /// Every static interval found.
    pub intervals: Vec<IntervalReport>,
}

/// A triad's result (`POST /v1/identify/triad`).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TriadResult {
    /// `triad`.
    pub kind: &'static str,
    /// `known_orientations` or `gravity_magnitude`.
    pub method: &'static str,
    /// The echoed id.
    pub sensor_id: Option<String>,
    /// The outputs' unit.
    pub unit: String,
    /// `u = b + S g`.
    pub model: &'static str,
    /// How to compensate.
    pub compensation: &'static str,
    /// `b`, in the outputs' unit.
    pub b: [f64; 3],
    /// Its standard errors (null with exactly nine static positions).
    pub b_std_errors: Option<[f64; 3]>,
    /// `S`, rows by axis, in the outputs' unit per g.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Its standard errors (known orientations).
    #[serde(rename = "S_std_errors", skip_serializing_if = "Option::is_none")]
    pub s_std_errors: Option<[[f64; 3]; 3]>,
    /// `T = S⁻¹`, g per output unit.
    #[serde(rename = "T")]
    pub t: [[f64; 3]; 3],
    /// Its standard errors (unknown orientations; null with exactly nine).
    #[serde(rename = "T_std_errors", skip_serializing_if = "Option::is_none")]
    pub t_std_errors: Option<[[f64; 3]; 3]>,
    /// With `second_order`: each axis's second-order coefficient `S2_m`
    /// (its `kii`), outputs' unit per g².
    #[serde(rename = "S2", skip_serializing_if = "Option::is_none")]
    pub s2: Option<[f64; 3]>,
    /// Their standard errors.
    #[serde(rename = "S2_std_errors", skip_serializing_if = "Option::is_none")]
    pub s2_std_errors: Option<[f64; 3]>,
    /// Their expanded uncertainties.
    #[serde(rename = "S2_expanded", skip_serializing_if = "Option::is_none")]
    pub s2_expanded: Option<[f64; 3]>,
    /// What the expanded uncertainties hold fixed, as two fields:
    /// `coverage_probability` (each element's coverage factor then follows
    /// from its effective degrees of freedom, `coverage`) or
    /// `coverage_factor` (a sensor type's fixed factor), the other null.
    /// Both absent without expanded uncertainties (the gravity magnitude
    /// with exactly nine positions).
    #[serde(flatten, serialize_with = "stated")]
    #[schema(value_type = crate::domain::schema::CoverageStated)]
    pub stated: Option<Coverage>,
    /// Each element's combined standard uncertainty, effective degrees of
    /// freedom, coverage factor and probability, by name (`b_x`, `S_yx`,
    /// `S2_z`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<BTreeMap<String, ElementCoverage>>)]
    pub coverage: Option<BTreeMap<String, ElementCoverage>>,
    /// `b`'s expanded uncertainties: known orientations, each axis's `k0`
    /// budget; the gravity magnitude, the fit's budget (`uncertainty`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub b_expanded: Option<[f64; 3]>,
    /// `S`'s expanded uncertainties: known orientations, each axis's `ki`,
    /// `kp`, `ko` budgets; the gravity magnitude, the fit's budget (0 above
    /// the diagonal, fixed by the frame convention).
    #[serde(rename = "S_expanded", skip_serializing_if = "Option::is_none")]
    pub s_expanded: Option<[[f64; 3]; 3]>,
    /// The gravity magnitude: the budget element by element (known
    /// orientations have theirs per axis, `axes[m].uncertainty`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<GravityUncertainty>,
    /// The nonconformities of its standards it was performed inside the
    /// windows of (a stored triad): it is stored under review.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held_by: Vec<crate::domain::nonconformity::HeldBy>,
    /// Stored triads of a typed sensor: the decision against its limits,
    /// element by element.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision: Option<TriadDecision>,
    /// Why a typed sensor's triad was not judged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision_note: Option<String>,
    /// Stored triads: as found with the sensor's previous triad
    /// ([`as_found`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub as_found: Option<TriadAsFound>,
    /// Stored triads: the reference standards named, as the registry
    /// describes them (what traceability and the reverse trace read).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    #[schema(value_type = Vec<Object>)]
    pub standards: Vec<UsedStandard>,
    /// Why there is no `as_found` although there is a previous calibration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub as_found_note: Option<String>,
    /// Each position's mean outputs (what as found compensates).
    #[serde(skip)]
    pub means: Vec<[f64; 3]>,
    /// Known orientations: each position's gravity vector.
    #[serde(skip)]
    pub gravity: Option<Vec<[f64; 3]>>,
    /// Each axis's scale factor: the norm of its row of `S`.
    pub scale_factors: [f64; 3],
    /// How far each pair of sensitive axes is from perpendicular, degrees
    /// (`xy`, `yz`, `zx`: 90° minus the angle between their rows of `S`).
    pub non_orthogonality_deg: [f64; 3],
    /// Per position, the residual: known orientations, `ū − (b + S g)` per
    /// axis in the outputs' unit; unknown, `‖T (ū − b)‖ − 1` in g.
    pub residuals: Vec<Vec<f64>>,
    /// Known orientations: each axis's single-axis identification.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axes: Option<Vec<AxisResult>>,
    /// Unknown orientations: the fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitReport>,
    /// Unknown orientations: each position's fitted gravity direction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub directions: Option<Vec<[f64; 3]>>,
    /// A recording: the static intervals.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detection: Option<DetectionReport>,
}

/// Where an axis's term sits in the triad.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// `b_m`.
    B,
    /// Row `m` of `S`, this column.
    S(usize),
    /// `S2_m`.
    S2,
}

/// Axis `m`'s terms and where each sits in the triad: `k0` in `b_m`,
/// `ki`, `kp`, `ko` in row `m` of `S` at columns `m`, `m + 1`, `m + 2`
/// (cyclically) — the single-axis model with
/// `(a_i, a_p, a_o) = (g_m, g_{m+1}, g_{m+2})` — and `kii` in `S2_m`.
pub fn row_terms(m: usize) -> [(Term, Slot); 5] {
    [
        (Term::K0, Slot::B),
        (Term::Ki, Slot::S(m)),
        (Term::Kp, Slot::S((m + 1) % 3)),
        (Term::Ko, Slot::S((m + 2) % 3)),
        (Term::Kii, Slot::S2),
    ]
}

/// A stored triad's decision against its sensor type's limits: each
/// axis's terms judged as a single-axis calibration's (its fused value and
/// expanded uncertainty), named by the element they are (`b_x` for the x
/// axis's `k0`, `S_xy` for its `kp`, …).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TriadDecision {
    /// The rule applied.
    #[schema(value_type = crate::domain::schema::RuleSchema)]
    pub rule: Rule,
    /// The worst verdict of the elements.
    #[schema(value_type = crate::domain::schema::VerdictSchema)]
    pub verdict: Verdict,
    /// Per limited element.
    #[schema(value_type = std::collections::BTreeMap<String, Object>)]
    pub elements: BTreeMap<String, TermDecision>,
}

/// The element name of axis `m`'s term in `slot` ([`row_terms`]).
fn element(m: usize, slot: Slot) -> String {
    match slot {
        Slot::B => format!("b_{}", AXES[m]),
        Slot::S(k) => format!("S_{}{}", AXES[m], AXES[k]),
        Slot::S2 => format!("S2_{}", AXES[m]),
    }
}

/// Judges a triad against `limits` (a sensor type's, per single-axis term)
/// with `rule`: each axis's `k0, ki, kp, ko` are its elements
/// ([`row_terms`]), each judged with its value and expanded uncertainty —
/// but for the elements of a triad from the gravity magnitude that are
/// zero by the frame convention ([`FIXED_BY_CONVENTION`]), which are not
/// measured. `None` without expanded uncertainties; `Err` names a limited
/// term a triad does not identify.
pub fn decide_triad(
    r: &TriadResult,
    rule: Rule,
    limits: &TermMap<Limit>,
) -> Result<Option<TriadDecision>, Term> {
    let (Some(b_u), Some(s_u)) = (r.b_expanded, r.s_expanded) else {
        return Ok(None);
    };
    let mut elements = BTreeMap::new();
    let mut verdict = Verdict::Pass;
    for m in 0..3 {
        let at = |slot: Slot, b: &[f64; 3], s: &[[f64; 3]; 3], s2: Option<&[f64; 3]>| match slot {
            Slot::B => Some(b[m]),
            Slot::S(k) => Some(s[m][k]),
            Slot::S2 => s2.map(|s2| s2[m]),
        };
        let terms = row_terms(m);
        let map = |b: &[f64; 3], s: &[[f64; 3]; 3], s2: Option<&[f64; 3]>| {
            TermMap(
                terms
                    .iter()
                    .filter_map(|(t, slot)| at(*slot, b, s, s2).map(|x| (*t, x)))
                    .collect(),
            )
        };
        let values = map(&r.b, &r.s, r.s2.as_ref());
        let expanded = map(&b_u, &s_u, r.s2_expanded.as_ref());
        let fixed = |t: Term| {
            r.method == GRAVITY_MAGNITUDE
                && terms.iter().any(|(term, slot)| {
                    *term == t
                        && matches!(slot, Slot::S(k) if FIXED_BY_CONVENTION.contains(&(m, *k)))
                })
        };
        let limits = TermMap(
            limits
                .iter()
                .filter(|(t, _)| !fixed(*t))
                .map(|(t, l)| (t, *l))
                .collect(),
        );
        let d = decide(rule, &limits, &values, &expanded)?;
        verdict = verdict.max(d.verdict);
        for (term, td) in d.terms.iter() {
            let slot = terms
                .iter()
                .find(|(t, _)| *t == term)
                .map_or(Slot::B, |(_, c)| *c);
            elements.insert(element(m, slot), *td);
        }
    }
    Ok(Some(TriadDecision {
        rule,
        verdict,
        elements,
    }))
}

/// As found: how far from the truth the previous calibration's `b` and
/// `S` put this test's positions.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TriadAsFound {
    /// The previous calibration.
    pub previous_calibration_id: uuid::Uuid,
    /// Per position, the error in g: with known orientations
    /// `S_prev⁻¹ (ū − b_prev) − g` per axis; with unknown ones
    /// `‖S_prev⁻¹ (ū − b_prev)‖ − 1`.
    pub positions: Vec<Vec<f64>>,
    /// The largest of them in magnitude, g.
    pub max_abs_error_g: f64,
}

/// As found of `r` with the previous triad `(b, S)` (calibration
/// `previous`): each position's mean outputs compensated with the previous
/// `b`, `S` (and `S2`), against the known gravity vector, or against a magnitude
/// of 1 g when the orientations were not known:
///
/// ```text
/// e_p = S_prev⁻¹ (ū_p − b_prev) − g_p            known orientations (3 components)
/// e_p = ‖S_prev⁻¹ (ū_p − b_prev)‖ − 1            unknown orientations
/// max_abs_error_g = max over p and components of |e_p|
/// ```
///
/// `None` when the previous `S` is singular.
pub fn as_found(r: &TriadResult, previous: uuid::Uuid, prev: &Triad) -> Option<TriadAsFound> {
    let positions: Vec<Vec<f64>> = r
        .means
        .iter()
        .enumerate()
        .map(|(p, u)| {
            let g = prev.compensate(*u).ok()?;
            Some(match &r.gravity {
                Some(known) => (0..3).map(|k| g[k] - known[p][k]).collect(),
                None => vec![g.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.0],
            })
        })
        .collect::<Option<_>>()?;
    let max_abs_error_g = positions
        .iter()
        .flatten()
        .fold(0.0_f64, |m, e| m.max(e.abs()));
    Some(TriadAsFound {
        previous_calibration_id: previous,
        positions,
        max_abs_error_g,
    })
}

/// The method of a triad with known orientations.
pub const KNOWN_ORIENTATIONS: &str = "known_orientations";
/// The method of a triad found from the gravity magnitude.
pub const GRAVITY_MAGNITUDE: &str = "gravity_magnitude";

/// The model equation.
pub const MODEL: &str = "u = b + S g";
/// The compensation.
pub const COMPENSATION: &str = "g = T (u - b), T = S^-1";
/// The model with second-order terms.
pub const MODEL_SECOND_ORDER: &str = "u = b + S g + S2 * g^2 (S2_m g_m^2 on axis m)";
/// Its compensation.
pub const COMPENSATION_SECOND_ORDER: &str =
    "solve u = b + S g + S2 * g^2 for g by Newton's iteration from g = T (u - b), T = S^-1";

/// 90° minus the angle between rows `m` and `n` of `s`, degrees.
fn skew(s: &[[f64; 3]; 3], m: usize, n: usize) -> f64 {
    let dot: f64 = (0..3).map(|k| s[m][k] * s[n][k]).sum();
    let norm = |r: &[f64; 3]| r.iter().map(|x| x * x).sum::<f64>().sqrt();
    let cos = (dot / (norm(&s[m]) * norm(&s[n]))).clamp(-1.0, 1.0);
    90.0 - cos.acos().to_degrees()
}

/// `T = S⁻¹`, column `k` being the compensation of `b + e_k` (refused when
/// `S` is singular to working precision, as compensation is).
fn invert(triad: &Triad) -> Option<[[f64; 3]; 3]> {
    let triad = &Triad::linear(triad.bias, triad.matrix);
    let mut t = [[0.0; 3]; 3];
    for k in 0..3 {
        let mut u = triad.bias;
        u[k] += 1.0;
        let column = triad.compensate(u).ok()?;
        for r in 0..3 {
            t[r][k] = column[r];
        }
    }
    Some(t)
}

fn problem(at: Loc<'_>, detail: impl Into<String>) -> Invalid {
    Invalid::one(at, detail)
}

/// Computes a checked submission.
pub fn compute(sub: TriadSubmission) -> Result<TriadResult, Invalid> {
    let base = |method, b, s: [[f64; 3]; 3], t| TriadResult {
        kind: "triad",
        method,
        sensor_id: sub.sensor_id.clone(),
        unit: sub.unit.clone(),
        model: MODEL,
        compensation: COMPENSATION,
        b,
        b_std_errors: None,
        s,
        s_std_errors: None,
        t,
        t_std_errors: None,
        s2: None,
        s2_std_errors: None,
        s2_expanded: None,
        stated: None,
        coverage: None,
        b_expanded: None,
        s_expanded: None,
        uncertainty: None,
        decision: None,
        decision_note: None,
        as_found: None,
        as_found_note: None,
        standards: Vec::new(),
        held_by: Vec::new(),
        means: Vec::new(),
        gravity: None,
        scale_factors: s.map(|row| row.iter().map(|x| x * x).sum::<f64>().sqrt()),
        non_orthogonality_deg: [skew(&s, 0, 1), skew(&s, 1, 2), skew(&s, 2, 0)],
        residuals: Vec::new(),
        axes: None,
        fit: None,
        directions: None,
        detection: None,
    };
    match &sub.form {
        Form::Known {
            positions,
            runs,
            batches,
            second_order,
        } => {
            let test = TriadTest::with_order(positions, runs, *second_order)
                .map_err(|e| axis_problem(&e))?;
            let cal = test.calibrate(*batches).map_err(|e| axis_problem(&e))?;
            let Triad { bias, matrix, .. } = cal.fused;
            let t = invert(&cal.fused).ok_or_else(|| {
                problem(
                    Loc::Root.key("runs"),
                    "S is singular: the outputs do not determine the specific force",
                )
            })?;
            let mut r = base(KNOWN_ORIENTATIONS, bias, matrix, t);
            r.b_std_errors = Some(cal.std_errors.bias);
            r.s_std_errors = Some(cal.std_errors.matrix);
            if *second_order {
                r.model = MODEL_SECOND_ORDER;
                r.compensation = COMPENSATION_SECOND_ORDER;
                r.s2 = Some(cal.fused.square);
                r.s2_std_errors = Some(cal.std_errors.square);
            }
            r.means = (0..positions.len())
                .map(|p| {
                    let all: Vec<[f64; 3]> = runs
                        .iter()
                        .flat_map(|run| run.samples[p].iter().copied())
                        .collect();
                    mean(&all)
                })
                .collect();
            r.residuals = positions
                .iter()
                .zip(&r.means)
                .map(|(g, m)| {
                    let model = cal.fused.outputs(*g);
                    (0..3).map(|k| m[k] - model[k]).collect()
                })
                .collect();
            r.gravity = Some(positions.clone());
            let mut axes = Vec::with_capacity(3);
            let (mut b_expanded, mut s_expanded) = ([0.0; 3], [[0.0; 3]; 3]);
            let mut s2_expanded = [0.0; 3];
            let mut coverage = BTreeMap::new();
            for (m, (axis_test, c)) in test.axes().iter().zip(&cal.axes).enumerate() {
                let quality = quality::assess(axis_test, c);
                let u = budget(
                    axis_test,
                    &c.fused.coefficients,
                    (&c.fused.std_errors, &c.fused.dof),
                    sub.stand,
                    sub.coverage,
                    &model_uncertainty(axis_test, &quality.lack_of_fit),
                )
                .map_err(|e| problem(Loc::Root.key("stand"), e.to_string()))?;
                for (term, slot) in row_terms(m) {
                    let Some(b) = u.terms.get(term) else {
                        continue;
                    };
                    let x = b.expanded;
                    match slot {
                        Slot::B => b_expanded[m] = x,
                        Slot::S(k) => s_expanded[m][k] = x,
                        Slot::S2 => s2_expanded[m] = x,
                    }
                    coverage.insert(element(m, slot), ElementCoverage::from(b));
                }
                axes.push(AxisResult {
                    axis: AXES[m],
                    mean: serde_json::to_value(&c.mean).unwrap_or_default(),
                    fused: serde_json::to_value(&c.fused).unwrap_or_default(),
                    uncertainty: serde_json::to_value(&u).unwrap_or_default(),
                    quality: serde_json::to_value(&quality).unwrap_or_default(),
                });
            }
            r.stated = Some(sub.coverage);
            r.coverage = Some(coverage);
            r.b_expanded = Some(b_expanded);
            r.s_expanded = Some(s_expanded);
            if *second_order {
                r.s2_expanded = Some(s2_expanded);
            }
            r.axes = Some(axes);
            Ok(r)
        }
        Form::Unknown { means } => {
            let f = gravity_fit::fit(means)
                .map_err(|e| fit_problem(Loc::Root.key("static_positions"), &e))?;
            let mut r = unknown(base, f, None, &sub);
            r.means = means.clone();
            Ok(r)
        }
        Form::Recording {
            rate_hz,
            samples,
            detector,
        } => {
            let at = Loc::Root.key("recording");
            let found = static_intervals::detect(*rate_hz, samples, detector)
                .map_err(|e| detect_problem(&at, &e))?;
            let report = detection_report(&found, *rate_hz, detector);
            let positions = found.positions();
            if positions.len() > MAX_POSITIONS {
                return Err(problem(
                    at,
                    format!(
                        "{} static intervals found, at most {MAX_POSITIONS} positions: a recording \
                         counts against the same limit as explicit positions; raise \
                         `detector.min_static_s` (now {} s) above the pauses that are not \
                         orientations, or `detector.threshold` (now {}) if still noise splits \
                         held orientations",
                        positions.len(),
                        detector.min_static_s,
                        detector.threshold,
                    ),
                ));
            }
            if positions.len() < MIN_POSITIONS {
                return Err(problem(
                    at,
                    format!(
                        "only {} static intervals found ({} rejected as shorter than {} s); {MIN_POSITIONS} \
                         needed: hold each of at least {MIN_POSITIONS} orientations still for at least {} s",
                        positions.len(),
                        found.intervals.len() - positions.len(),
                        detector.min_static_s,
                        detector.min_static_s + detector.window_s,
                    ),
                ));
            }
            let f = gravity_fit::fit(&positions).map_err(|e| fit_problem(at, &e))?;
            let mut r = unknown(base, f, Some(report), &sub);
            r.means = positions;
            Ok(r)
        }
    }
}

/// The result of a fit from the gravity magnitude, with its uncertainty
/// budget for the submission's gravity and coverage factor.
fn unknown(
    base: impl Fn(&'static str, [f64; 3], [[f64; 3]; 3], [[f64; 3]; 3]) -> TriadResult,
    f: GravityFit,
    detection: Option<DetectionReport>,
    sub: &TriadSubmission,
) -> TriadResult {
    let mut r = base(GRAVITY_MAGNITUDE, f.bias, f.s, f.t);
    r.b_std_errors = f.bias_std;
    r.s_std_errors = f.s_std;
    r.t_std_errors = f.t_std;
    let gravity = sub.stand.gravity_rel_std;
    if let Some(u) = gravity_budget::budget(&f, (gravity, sub.stand.gravity_dof), sub.coverage) {
        r.stated = Some(u.coverage);
        let mut coverage = BTreeMap::new();
        for m in 0..3 {
            coverage.insert(element(m, Slot::B), ElementCoverage::from(&u.b[m]));
            for k in 0..=m {
                coverage.insert(element(m, Slot::S(k)), ElementCoverage::from(&u.s[m][k]));
            }
        }
        r.coverage = Some(coverage);
        r.b_expanded = Some(u.b.map(|e| e.expanded));
        r.s_expanded = Some(u.s.map(|row| row.map(|e| e.expanded)));
        r.uncertainty = Some(GravityUncertainty::of(&u, gravity));
    }
    r.residuals = f.residuals_g.iter().map(|x| vec![*x]).collect();
    r.fit = Some(FitReport {
        evaluations: f.evaluations,
        stop: f.stop.as_str(),
        spread: f.spread,
        min_spread: gravity_fit::MIN_SPREAD,
        rms_g: f.rms_g,
        degrees_of_freedom: f.degrees_of_freedom,
    });
    r.directions = Some(f.directions);
    r.detection = detection;
    r
}

fn detection_report(found: &Detection, rate_hz: f64, d: &Detector) -> DetectionReport {
    DetectionReport {
        still_s: d.still_s,
        window_s: d.window_s,
        threshold: d.threshold,
        min_static_s: d.min_static_s,
        still_variance: found.still_variance,
        threshold_variance: found.threshold_variance,
        intervals: found
            .intervals
            .iter()
            .map(|i| IntervalReport {
                start_s: i.start as f64 / rate_hz,
                end_s: i.end as f64 / rate_hz,
                used: i.rejected.is_none(),
                rejected: i.rejected.map(|r| match r {
                    Rejection::TooShort => "too_short",
                }),
                mean: i.mean,
            })
            .collect(),
    }
}

fn axis_problem(e: &TriadError) -> Invalid {
    let runs = Loc::Root.key("runs");
    match e {
        TriadError::CopiedRun { run, .. } => problem(runs.index(*run), e.to_string()),
        _ => problem(runs, e.to_string()),
    }
}

fn fit_problem(at: Loc<'_>, e: &GravityFitError) -> Invalid {
    problem(at, e.to_string())
}

fn detect_problem(at: &Loc<'_>, e: &DetectError) -> Invalid {
    match e {
        DetectError::Parameter { name } if *name == "rate_hz" => {
            problem(at.key("rate_hz"), e.to_string())
        }
        DetectError::Parameter { name } => problem(at.key("detector").key(name), e.to_string()),
        DetectError::NotFinite { index } => problem(at.key("samples").index(*index), e.to_string()),
        DetectError::TooShort { .. } => problem(at.key("samples"), e.to_string()),
    }
}
