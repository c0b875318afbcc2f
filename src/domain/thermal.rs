//! A single axis's coefficients over temperature (issue 45), from one
//! submission whose runs were made at several temperatures: the runs
//! grouped into set points ([`accelcal_core::thermal::set_points`]), each
//! set point identified and fused exactly as a calibration is, and every
//! coefficient's polynomial fitted to the set points' fused estimates
//! weighted by their standard errors ([`accelcal_core::thermal::fit`]).
//! A refusal names what to add: how many set points, and where.

use accelcal_core::thermal::{
    self, MAX_CONDITION, MIN_SPAN_K, Options, Point, Polynomial, Selection, TOLERANCE_K,
    ThermalError,
};
use accelcal_core::{Run, TermMap, TumbleTest};
use serde::{Deserialize, Serialize};

use super::field::{Errors, Invalid};
use super::submission::Submission;
use super::triad_export::Format;

/// How the temperature model is fitted (the query of
/// `POST /v1/identify/thermal`; each has its documented default).
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize, Serialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ThermalParams {
    /// Runs within this many kelvin of a set point's coolest run form the
    /// set point (default 0.5).
    #[param(minimum = 0.0, maximum = 50.0)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance_k: Option<f64>,
    /// The reference temperature `T_ref`, °C (default: the set points'
    /// mean, rounded to 0.1 K).
    #[param(minimum = -100.0, maximum = 200.0)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_c: Option<f64>,
    /// The polynomial's degree, 0 to 3, for every coefficient (default:
    /// chosen per coefficient by `selection`).
    #[param(minimum = 0, maximum = 3)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub degree: Option<usize>,
    /// How the degree is chosen: `backward` (default) or `forward`.
    #[param(inline)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection: Option<SelectionParam>,
    /// The smallest span of set points, K (default 10).
    #[param(minimum = 0.0, maximum = 500.0)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_span_k: Option<f64>,
    /// The largest condition number of the column-scaled design
    /// (default 100).
    #[param(minimum = 1.0)]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_condition: Option<f64>,
}

/// How the degree is chosen when none is asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SelectionParam {
    /// Down from the highest degree the set points allow (the default).
    Backward,
    /// Up from degree 0 (the rule).
    Forward,
}

impl From<SelectionParam> for Selection {
    fn from(s: SelectionParam) -> Self {
        match s {
            SelectionParam::Backward => Selection::Backward,
            SelectionParam::Forward => Selection::Forward,
        }
    }
}

/// A parameter out of range: its name and why.
#[derive(Clone, Debug, PartialEq)]
pub struct BadParameter {
    /// The parameter.
    pub name: &'static str,
    /// Why.
    pub detail: String,
}

/// Checked parameters: as asked, and the tolerance and fit options they
/// make.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    /// As asked.
    pub params: ThermalParams,
    /// Runs within this many kelvin form a set point.
    pub tolerance_k: f64,
    /// How each polynomial is fitted.
    pub options: Options,
}

impl Default for Fit {
    /// Every parameter at its documented default.
    fn default() -> Self {
        Fit {
            params: ThermalParams::default(),
            tolerance_k: TOLERANCE_K,
            options: Options::default(),
        }
    }
}

impl ThermalParams {
    /// The tolerance and the fit's options, checked.
    pub fn checked(&self) -> Result<Fit, BadParameter> {
        let bad = |name, detail: &str| BadParameter {
            name,
            detail: detail.to_owned(),
        };
        let tolerance = self.tolerance_k.unwrap_or(TOLERANCE_K);
        if !(tolerance.is_finite() && (0.0..=50.0).contains(&tolerance)) {
            return Err(bad("tolerance_k", "must be from 0 to 50 K"));
        }
        if let Some(r) = self.reference_c
            && !super::limits::TEMPERATURE_C.contains(&r)
        {
            return Err(bad(
                "reference_c",
                &format!(
                    "must be a temperature from {} to {} °C",
                    super::limits::TEMPERATURE_C.start(),
                    super::limits::TEMPERATURE_C.end()
                ),
            ));
        }
        if let Some(d) = self.degree
            && d > thermal::MAX_DEGREE
        {
            return Err(bad("degree", "must be from 0 to 3"));
        }
        let min_span_k = self.min_span_k.unwrap_or(MIN_SPAN_K);
        if !(min_span_k.is_finite() && (0.0..=500.0).contains(&min_span_k)) {
            return Err(bad("min_span_k", "must be from 0 to 500 K"));
        }
        let max_condition = self.max_condition.unwrap_or(MAX_CONDITION);
        if !(max_condition.is_finite() && max_condition >= 1.0) {
            return Err(bad(
                "max_condition",
                "must be a finite number of at least 1",
            ));
        }
        Ok(Fit {
            params: *self,
            tolerance_k: tolerance,
            options: Options {
                reference_c: self.reference_c,
                degree: self.degree,
                selection: self.selection.map_or(Selection::Backward, Selection::from),
                min_span_k,
                max_condition,
            },
        })
    }
}

/// One set point, identified and fused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetPointResult {
    /// The mean of its runs' temperatures, °C.
    pub temperature_c: f64,
    /// Its runs (indices into the submission's).
    pub runs: Vec<usize>,
    /// The fusion batches used: the submission's, fewer when the set
    /// point has fewer than two runs a batch.
    pub batches: usize,
    /// Its fused coefficients.
    pub coefficients: TermMap<f64>,
    /// Their standard errors: each polynomial's weights are `1 / se²`.
    pub std_errors: TermMap<f64>,
    /// Their degrees of freedom (batch estimation's; none in a model
    /// stored before they were kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dof: Option<TermMap<f64>>,
}

/// A single axis's temperature model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThermalModel {
    /// The sensor.
    pub sensor_id: String,
    /// The outputs' unit.
    pub unit: String,
    /// The tolerance the runs were grouped with, K.
    pub tolerance_k: f64,
    /// How each degree was chosen (`backward`, `forward`), or `fixed`.
    pub selection: String,
    /// The parameters it was fitted with, as asked (what a correction or
    /// a reprocessing of a stored model fits with again).
    #[serde(default)]
    pub fitted_with: ThermalParams,
    /// The set points, coolest first.
    pub set_points: Vec<SetPointResult>,
    /// Each coefficient's polynomial `c(T) = Σ a_d (T − T_ref)^d`, its
    /// `a_d` in the coefficient's unit per K^d.
    pub coefficients: TermMap<Polynomial>,
    /// The standard uncertainty of the named thermometer's reading, K
    /// (`temperature_std_c` of its certificate in force): the model read
    /// at a temperature adds `u_T · |dc/dT|` to each coefficient's budget
    /// ([`ThermalModel::at`]). None when no thermometer was named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermometer_std_c: Option<f64>,
}

/// The temperature model of `submission` (module doc), fitted with `fit`.
pub fn model(submission: &Submission, fit: &Fit) -> Result<ThermalModel, Invalid> {
    let (tolerance_k, options) = (fit.tolerance_k, &fit.options);
    held(&submission.position_temperatures_c, tolerance_k)?;
    let (groups, at, options) =
        grouped(submission.temperatures_c.as_deref(), tolerance_k, options)?;
    let test = &submission.test;
    let mut set_points = Vec::with_capacity(groups.len());
    for g in groups {
        let runs: Vec<Run> = g.runs.iter().map(|&j| test.runs()[j].clone()).collect();
        let batches = submission.batches.min((runs.len() / 2).max(1));
        let at_set_point = TumbleTest::new(test.model().clone(), test.positions().to_vec(), runs)
            .and_then(|t| t.calibrate(batches))
            .map_err(|e| {
                Invalid::one(
                    format!("/runs/{}", g.runs[0]),
                    format!(
                        "the set point at {} °C (runs {}) cannot be identified on its own: {e}",
                        round(g.temperature_c),
                        list(&g.runs)
                    ),
                )
            })?;
        set_points.push(SetPointResult {
            temperature_c: g.temperature_c,
            runs: g.runs,
            batches,
            coefficients: at_set_point.fused.coefficients.clone(),
            std_errors: at_set_point.fused.std_errors.clone(),
            // An infinite ν (a batch variance of zero) is stated as none.
            dof: Some(TermMap(
                at_set_point
                    .fused
                    .dof
                    .iter()
                    .filter(|(_, d)| d.is_finite())
                    .map(|(t, d)| (t, *d))
                    .collect(),
            )),
        });
    }
    let coefficients = test
        .model()
        .terms()
        .iter()
        .map(|&term| {
            let points: Vec<Point> = set_points
                .iter()
                .map(|s| Point {
                    temperature_c: s.temperature_c,
                    value: s.coefficients.get(term).copied().unwrap_or(f64::NAN),
                    std_uncertainty: s.std_errors.get(term).copied().unwrap_or(0.0),
                })
                .collect();
            fitted(&term.to_string(), &points, &options, &at).map(|p| (term, p))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(ThermalModel {
        sensor_id: submission.sensor_id.clone(),
        unit: submission.unit.clone(),
        tolerance_k,
        selection: selection(&options),
        fitted_with: fit.params,
        set_points,
        coefficients: TermMap(coefficients),
        thermometer_std_c: None,
    })
}

/// Checks that no run whose temperature was given per position drifted
/// across its positions by more than `tolerance_k`: a run is one set
/// point's, identified with one set of coefficients, and enters the fit
/// at its positions' mean temperature.
fn held(per_position: &[Option<Vec<f64>>], tolerance_k: f64) -> Result<(), Invalid> {
    let mut errors = Errors::default();
    for (j, ts) in per_position.iter().enumerate() {
        let Some(ts) = ts else { continue };
        let lo = ts.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ts.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if hi - lo > tolerance_k {
            errors.add(
                format!("/runs/{j}/temperature_c"),
                format!(
                    "drifted {:.3} K across its positions ({lo} to {hi} °C), more than the set \
                     points' tolerance of {tolerance_k} K: a run must hold its set point; repeat \
                     it once the chamber has settled (or widen tolerance_k)",
                    hi - lo
                ),
            );
        }
    }
    errors.finish(|| ())
}

/// The runs at `temperatures` (every run's, or `None`) grouped within
/// `tolerance_k` into set points, checked to make a sane polynomial: the
/// groups, their temperatures, and `options` with `T_ref` settled.
fn grouped(
    temperatures: Option<&[f64]>,
    tolerance_k: f64,
    options: &Options,
) -> Result<(Vec<thermal::SetPoint>, Vec<f64>, Options), Invalid> {
    let Some(temperatures) = temperatures else {
        return Err(Invalid::one(
            "/runs/0/temperature_c",
            "is missing: a temperature model needs every run's temperature",
        ));
    };
    let groups = thermal::set_points(temperatures, tolerance_k);
    let at: Vec<f64> = groups.iter().map(|g| g.temperature_c).collect();
    let reference = options
        .reference_c
        .unwrap_or_else(|| thermal::reference(&at));
    thermal::check(&at, reference, options.degree, options).map_err(|e| refusal(&e, &at))?;
    let options = Options {
        reference_c: Some(reference),
        ..*options
    };
    Ok((groups, at, options))
}

/// The polynomial of the quantity `name` over the set points `points` (at
/// `at`), or the refusal saying what to add.
fn fitted(
    name: &str,
    points: &[Point],
    options: &Options,
    at: &[f64],
) -> Result<Polynomial, Invalid> {
    thermal::fit(points, options).map_err(|e| match e {
        ThermalError::Unweighted { temperature_c } => Invalid::one(
            "/runs",
            format!(
                "the set point at {} °C gives `{name}` no positive standard error, so it \
                 cannot be weighted: give it more runs, or runs that differ",
                round(temperature_c)
            ),
        ),
        e => refusal(&e, at),
    })
}

/// How the degrees were chosen: `fixed`, `backward` or `forward`.
fn selection(options: &Options) -> String {
    match (options.degree, options.selection) {
        (Some(_), _) => "fixed",
        (None, Selection::Backward) => "backward",
        (None, Selection::Forward) => "forward",
    }
    .to_owned()
}

/// A temperature to 0.01 K, as the refusals print it.
fn round(t: f64) -> f64 {
    (t * 100.0).round() / 100.0
}

/// `3, 5, 7`.
fn list(runs: &[usize]) -> String {
    runs.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The widest gap between set points `at` (sorted): its middle.
fn widest_gap(at: &[f64]) -> Option<f64> {
    at.windows(2)
        .max_by(|a, b| (a[1] - a[0]).total_cmp(&(b[1] - b[0])))
        .map(|w| round((w[0] + w[1]) / 2.0))
}

/// A refusal of the set points `at`, saying what to add.
fn refusal(e: &ThermalError, at: &[f64]) -> Invalid {
    let shown = at
        .iter()
        .map(|t| format!("{} °C", round(*t)))
        .collect::<Vec<_>>()
        .join(", ");
    let detail = match e {
        ThermalError::TooFewSetPoints {
            distinct, needed, ..
        } => format!(
            "{distinct} temperature set point(s) ({shown}): {e}; add {} more, spread over the \
             range the sensor is used in{}",
            needed - distinct,
            widest_gap(at).map_or(String::new(), |m| format!(", e.g. at {m} °C"))
        ),
        ThermalError::SpanTooSmall { min_span_k, .. } => {
            let (lo, hi) = (at[0], at[at.len() - 1]);
            format!(
                "the set points ({shown}) span {} K, less than the {min_span_k} K a temperature \
                 model needs (min_span_k): add a set point at or below {} °C or at or above {} °C",
                round(hi - lo),
                round(hi - min_span_k),
                round(lo + min_span_k)
            )
        }
        ThermalError::IllConditioned { .. } => format!(
            "{e} (max_condition): the set points ({shown}) crowd together; add set points in \
             the gaps{}, or ask for a lower degree",
            widest_gap(at).map_or(String::new(), |m| format!(", e.g. at {m} °C"))
        ),
        e => e.to_string(),
    };
    Invalid::one("/runs", detail)
}

/// The triad's temperature `model` as a file in `format`, described by
/// `source`: `json` the model itself, `c` [`firmware::c_header`], `px4`
/// and `ardupilot` their parameters.
pub fn export(
    model: &TriadThermalModel,
    format: Format,
    source: &str,
) -> Result<String, firmware::ThermalExportError> {
    match format {
        Format::Json => Ok(serde_json::to_string_pretty(model).unwrap_or_default()),
        Format::C => Ok(firmware::c_header(model, source)),
        Format::Px4 => px4(model, source),
        Format::ArduPilot => ardupilot(model, source),
    }
}

/// The file name a temperature model in `format` is suggested under.
pub fn file_name(format: Format) -> &'static str {
    match format {
        Format::Json => "accelcal-thermal-triad.json",
        Format::C => "accelcal_thermal_triad.h",
        Format::Px4 => "accelcal-px4-thermal.params",
        Format::ArduPilot => "accelcal-ardupilot-thermal.param",
    }
}

mod ardupilot;
mod at;
pub mod combine;
pub mod decision;
pub mod firmware;
mod px4;
mod triad;

pub use ardupilot::ardupilot;
pub use px4::px4;
pub use triad::{TriadAt, TriadSetPoint, TriadThermalModel, triad_model};

/// A stored temperature model of either kind, as the `thermal` column
/// holds it: a triad's has `b` and `S` where a single axis's has
/// `coefficients`.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum AnyModel {
    /// A triad's.
    Triad(Box<TriadThermalModel>),
    /// A single axis's.
    Axis(Box<ThermalModel>),
}

impl AnyModel {
    /// The column `m` as the summary's two fields.
    pub fn split(m: Option<AnyModel>) -> (Option<ThermalModel>, Option<TriadThermalModel>) {
        match m {
            Some(AnyModel::Axis(a)) => (Some(*a), None),
            Some(AnyModel::Triad(t)) => (None, Some(*t)),
            None => (None, None),
        }
    }
}

#[cfg(test)]
mod tests;
