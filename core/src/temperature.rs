//! Temperature sensitivity of the coefficients, from runs at different
//! temperatures.
//!
//! For each coefficient, ordinary least squares of its per-run values `x_j`
//! on the runs' temperatures `T_j` (°C):
//!
//! ```text
//! per_kelvin = Σ(T − T̄)(x − x̄) / Σ(T − T̄)²
//! std_error  = √(Σ r² / (n − 2)) / √Σ(T − T̄)²        (none for n < 3)
//! reference_c = T̄,   value_at_reference = x̄          (the fit passes through the means)
//! ```
//!
//! Given only when the runs have at least two distinct temperatures.

use serde::Serialize;

use crate::fusion::mean;
use crate::history::centred;
use crate::identify::Identification;
use crate::term::TermMap;

/// One coefficient's temperature sensitivity.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Sensitivity {
    /// Slope, in the coefficient's unit per kelvin.
    pub per_kelvin: f64,
    /// Its standard error; none with fewer than three runs.
    pub std_error: Option<f64>,
    /// The mean run temperature, °C.
    pub reference_c: f64,
    /// The fitted value at the reference temperature.
    pub value_at_reference: f64,
}

/// Sensitivities of every coefficient to the run temperatures
/// `temperatures_c` (one per run); `None` unless at least two differ.
pub fn sensitivity(
    runs: &[Identification],
    temperatures_c: &[f64],
) -> Option<TermMap<Sensitivity>> {
    let t = temperatures_c;
    if t.len() != runs.len() || t.iter().all(|v| *v == t[0]) {
        return None;
    }
    let n = t.len();
    let tm = mean(t);
    let dt = centred(t);
    let stt: f64 = dt.iter().map(|d| d * d).sum();
    let first = runs.first()?;
    Some(TermMap(
        first
            .coefficients
            .iter()
            .map(|(term, _)| {
                let x: Vec<f64> = runs
                    .iter()
                    .filter_map(|r| r.coefficients.get(term).copied())
                    .collect();
                let xm = mean(&x);
                let dx = centred(&x);
                let slope = dt.iter().zip(&dx).map(|(a, b)| a * b).sum::<f64>() / stt;
                let std_error = (n >= 3).then(|| {
                    let rss: f64 = dt
                        .iter()
                        .zip(&dx)
                        .map(|(a, b)| (b - slope * a).powi(2))
                        .sum();
                    (rss / (n - 2) as f64).sqrt() / stt.sqrt()
                });
                (
                    term,
                    Sensitivity {
                        per_kelvin: slope,
                        std_error,
                        reference_c: tm,
                        value_at_reference: xm,
                    },
                )
            })
            .collect(),
    ))
}
