//! A single axis's temperature model read at a temperature (issue 45
//! items 3 and 4): every coefficient `c(T) = Σ a_d (T − T_ref)^d` with its
//! standard uncertainty
//!
//! ```text
//! u(c(T))² = vᵀ C_a v + (u_T · c′(T))²,   v_d = (T − T_ref)^d,
//! ```
//!
//! the polynomial's own ([`accelcal_core::thermal::Polynomial::at`]) and,
//! when a thermometer was named, its reading's standard uncertainty `u_T`
//! carried through the slope `c′(T) = Σ d a_d (T − T_ref)^(d−1)` (a
//! temperature read `u_T` off moves `c` by `c′ u_T` to first order; the
//! two are independent). And how far `T` lies
//! outside the valid range `[T_min, T_max]` — which a caller must allow
//! before it is used there; and where a polynomial is stationary on its
//! range (what the exports and the decisions search).

use accelcal_core::TermMap;
use accelcal_core::thermal::Polynomial;

use super::ThermalModel;

/// The temperatures inside `p`'s range where `c′(T) = a_1 + 2 a_2 x +
/// 3 a_3 x² = 0` (`x = T − T_ref`): with the ends, where `c` can be
/// largest or smallest on its range.
pub fn stationary(p: &Polynomial) -> Vec<f64> {
    let [lo, hi] = p.range_c;
    let a = |d: usize| p.coefficients.get(d).copied().unwrap_or(0.0);
    let (q0, q1, q2) = (a(1), 2.0 * a(2), 3.0 * a(3));
    let mut xs = Vec::new();
    if q2 != 0.0 {
        let disc = q1 * q1 - 4.0 * q2 * q0;
        if disc >= 0.0 {
            xs.extend([
                (-q1 + disc.sqrt()) / (2.0 * q2),
                (-q1 - disc.sqrt()) / (2.0 * q2),
            ]);
        }
    } else if q1 != 0.0 {
        xs.push(-q0 / q1);
    }
    xs.into_iter()
        .map(|x| x + p.reference_c)
        .filter(|t| (lo..=hi).contains(t))
        .collect()
}

/// Polynomial `p` at `temperature_c`: its value and standard uncertainty,
/// with the term of a thermometer read to `thermometer_std_c` (module
/// doc) — a single axis's coefficient or a triad's element alike.
pub fn read(p: &Polynomial, temperature_c: f64, thermometer_std_c: Option<f64>) -> (f64, f64) {
    let (value, u) = p.at(temperature_c);
    let u = match thermometer_std_c {
        Some(u_t) => u.hypot(u_t * p.slope(temperature_c)),
        None => u,
    };
    (value, u)
}

/// The coefficients of a model at one temperature.
#[derive(Clone, Debug, PartialEq)]
pub struct AtTemperature {
    /// The temperature, °C.
    pub temperature_c: f64,
    /// Every coefficient there.
    pub coefficients: TermMap<f64>,
    /// Their standard uncertainties through the polynomials' covariance.
    pub std_errors: TermMap<f64>,
    /// How far outside the valid range, K (0 within).
    pub outside_k: f64,
}

impl ThermalModel {
    /// `T_ref`, °C (every coefficient's: the set points are one).
    pub fn reference_c(&self) -> f64 {
        self.coefficients
            .iter()
            .next()
            .map_or(f64::NAN, |(_, p)| p.reference_c)
    }

    /// The valid range `[T_min, T_max]`, °C: the set points' span.
    pub fn range_c(&self) -> [f64; 2] {
        self.coefficients
            .iter()
            .next()
            .map_or([f64::NAN; 2], |(_, p)| p.range_c)
    }

    /// Polynomial `p` of this model at `temperature_c`: its value and
    /// standard uncertainty, the thermometer's term included (module doc).
    pub fn read(&self, p: &Polynomial, temperature_c: f64) -> (f64, f64) {
        read(p, temperature_c, self.thermometer_std_c)
    }

    /// Every coefficient at `temperature_c`.
    pub fn at(&self, temperature_c: f64) -> AtTemperature {
        let mut coefficients = Vec::with_capacity(self.coefficients.len());
        let mut std_errors = Vec::with_capacity(self.coefficients.len());
        for (term, p) in self.coefficients.iter() {
            let (value, u) = self.read(p, temperature_c);
            coefficients.push((term, value));
            std_errors.push((term, u));
        }
        let [lo, hi] = self.range_c();
        AtTemperature {
            temperature_c,
            coefficients: TermMap(coefficients),
            std_errors: TermMap(std_errors),
            outside_k: (lo - temperature_c).max(temperature_c - hi).max(0.0),
        }
    }

    /// Every number it holds, named: what must be finite to be stored.
    pub fn numbers(&self) -> impl Iterator<Item = (String, f64)> + '_ {
        let set_points = self.set_points.iter().enumerate().flat_map(|(s, p)| {
            std::iter::once((format!("set_points[{s}].temperature_c"), p.temperature_c)).chain(
                p.coefficients
                    .iter()
                    .chain(p.std_errors.iter())
                    .map(move |(t, v)| (format!("set_points[{s}].{t}"), *v)),
            )
        });
        let polynomials = self.coefficients.iter().flat_map(|(t, p)| {
            p.coefficients
                .iter()
                .chain(&p.std_uncertainties)
                .chain(p.covariance.iter().flatten())
                .chain(&p.range_c)
                .chain([&p.reference_c, &p.chi2, &p.inflation])
                .map(move |v| (format!("coefficients.{t}"), *v))
        });
        set_points
            .chain(polynomials)
            .chain([("tolerance_k".to_owned(), self.tolerance_k)])
            .chain(
                self.thermometer_std_c
                    .map(|u| ("thermometer_std_c".to_owned(), u)),
            )
    }
}
