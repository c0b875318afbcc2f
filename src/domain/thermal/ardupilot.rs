//! A triad's temperature model as ArduPilot's IMU temperature calibration
//! (issue 45 item 5): `INS_TCAL1_ENABLE`, `INS_TCAL1_TMIN`,
//! `INS_TCAL1_TMAX`, `INS_TCAL1_ACC{1,2,3}_{X,Y,Z}`, with the offsets
//! `INS_ACCOFFS_{X,Y,Z}` and `INS_ACC1_CALTEMP` they are corrected from, in
//! `NAME,VALUE` lines.
//!
//! **ArduPilot's convention**, read in ArduPilot's sources:
//! `AP_InertialSensor::TCal::correct_sensor`
//! (`libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp`) subtracts
//! `p(T) − p(T_cal)` with
//!
//! ```text
//! p(T) = (ACC1 x + ACC2 x² + ACC3 x³) · 10⁻⁶,   x = clamp(T, TMIN, TMAX) − 35,
//! ```
//!
//! about ArduPilot's fixed reference of 35 °C (`TEMP_REFERENCE`), the
//! parameters scaled by 10⁶ (`SCALE_FACTOR`), no constant term, and
//! `T_cal = clamp(INS_ACC1_CALTEMP, TMIN, TMAX)` the temperature the
//! accelerometer calibration was made at; then
//! `AP_InertialSensor_Backend::_rotate_and_correct_accel` subtracts
//! `INS_ACCOFFS` and multiplies by `INS_ACCSCAL`, in m/s². So the offset
//! applied is `INS_ACCOFFS + p(T) − p(T_cal)`, which is `b(T)` when
//!
//! ```text
//! c_k = Σ_{d≥k} a_d C(d, k) h^{d−k},  h = 35 − T_ref    (b about 35 °C),
//! ACCk = 10⁶ c_k (k = 1, 2, 3),  INS_ACC1_CALTEMP = T_cal,  INS_ACCOFFS = b(T_cal),
//! ```
//!
//! with `T_cal` the model's `T_ref` held to its range. The file sets the
//! offsets with their temperature, as ArduPilot's own accelerometer
//! calibration does; a later accelerometer calibration records its own
//! temperature and keeps the polynomial valid.
//!
//! **Not carried**, as for PX4: ArduPilot's temperature calibration has no
//! thermal scale factor or cross-axis term ([`super::firmware`]).

use std::fmt::Write as _;

use super::TriadThermalModel;
use super::firmware::{ThermalExportError, at, carried, not_carried_lines};
use crate::domain::triad_export::{ExportError, ascii_escaped, to_m_s2};

/// ArduPilot's fixed reference temperature, °C (`TEMP_REFERENCE`).
pub const REFERENCE_C: f64 = 35.0;

/// The factor ArduPilot's `ACCk` parameters carry (`SCALE_FACTOR`).
pub const SCALE: f64 = 1.0e6;

/// `n` choose `k`, for `n ≤ 3`.
fn choose(n: usize, k: usize) -> f64 {
    (1..=k).fold(1.0, |c, i| c * (n + 1 - i) as f64 / i as f64)
}

/// `a` (about `reference_c`) re-expanded about `to_c`: `c_0 … c_D`.
pub fn shifted(a: &[f64], reference_c: f64, to_c: f64) -> Vec<f64> {
    let h = to_c - reference_c;
    (0..a.len())
        .map(|k| {
            (k..a.len())
                .map(|d| a[d] * choose(d, k) * h.powi((d - k) as i32))
                .sum()
        })
        .collect()
}

/// The ArduPilot parameter file of `model`, described by `source`.
pub fn ardupilot(model: &TriadThermalModel, source: &str) -> Result<String, ThermalExportError> {
    let per_unit = to_m_s2(&model.unit).ok_or_else(|| ExportError::Unit {
        format: "ArduPilot",
        unit: model.unit.clone(),
    })?;
    let dropped = carried(model, "ArduPilot")?;
    let [t_min, t_max] = model.b[0].range_c;
    let t_cal = model.b[0].reference_c.clamp(t_min, t_max);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# accelcal temperature model for ArduPilot IMU temperature calibration: {}",
        ascii_escaped(source)
    );
    let _ = writeln!(out, "# outputs u in {}", ascii_escaped(&model.unit));
    for line in [
        "# ArduPilot (AP_InertialSensor_tempcal.cpp, TCal::correct_sensor; AP_InertialSensor_Backend.cpp,",
        "# _rotate_and_correct_accel): a = (u - INS_ACCOFFS - (p(T) - p(INS_ACC1_CALTEMP))) * INS_ACCSCAL, in m/s2,",
        "# p(T) = (ACC1 x + ACC2 x^2 + ACC3 x^3) * 1e-6, x = clamp(T, TMIN, TMAX) - 35: the offset applied is b(T),",
        "# ACCk being b's polynomial about 35 C times 1e6 and INS_ACCOFFS = b(INS_ACC1_CALTEMP).",
        "# For the n-th IMU (n = 2, 3) rename INS_TCAL1_ to INS_TCALn_, INS_ACC1_CALTEMP to INS_ACCn_CALTEMP",
        "# and INS_ACCOFFS_ to INS_ACCnOFFS_; keep INS_ACCSCAL_* from the triad's static calibration.",
    ] {
        let _ = writeln!(out, "{line}");
    }
    not_carried_lines(&mut out, "ArduPilot", &dropped);
    let line = |out: &mut String, name: &str, value: String| {
        let _ = writeln!(out, "{name},{value}");
    };
    line(&mut out, "INS_TCAL1_ENABLE", "1".into());
    line(&mut out, "INS_TCAL1_TMIN", format!("{t_min:.6}"));
    line(&mut out, "INS_TCAL1_TMAX", format!("{t_max:.6}"));
    let about_35: Vec<Vec<f64>> = model
        .b
        .iter()
        .map(|p| {
            let mut a = p.coefficients.clone();
            a.resize(4, 0.0);
            shifted(&a, p.reference_c, REFERENCE_C)
        })
        .collect();
    for k in 1..=3 {
        for (c, axis) in about_35.iter().zip(["X", "Y", "Z"]) {
            let value = c[k] * per_unit * SCALE;
            line(
                &mut out,
                &format!("INS_TCAL1_ACC{k}_{axis}"),
                format!("{value:.9e}"),
            );
        }
    }
    line(&mut out, "INS_ACC1_CALTEMP", format!("{t_cal:.6}"));
    for (p, axis) in model.b.iter().zip(["X", "Y", "Z"]) {
        let value = at(p, t_cal) * per_unit;
        line(
            &mut out,
            &format!("INS_ACCOFFS_{axis}"),
            format!("{value:.9e}"),
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Re-expansion keeps the polynomial: `1 + 2x + 3x² + 4x³` about 20 °C
    /// and its expansion about 35 °C agree everywhere, and the hand
    /// expansion about 21 (h = 1) is `10 + 20x + 15x² + 4x³`.
    #[test]
    fn shifting_the_reference_keeps_the_polynomial() {
        let a = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(shifted(&a, 20.0, 21.0), vec![10.0, 20.0, 15.0, 4.0]);
        let c = shifted(&a, 20.0, 35.0);
        for t in [-20.0f64, 0.0, 33.0, 60.0] {
            let x = t - 20.0;
            let y = t - 35.0;
            let want: f64 = (0..4).map(|d| a[d] * x.powi(d as i32)).sum();
            let got: f64 = (0..4).map(|d| c[d] * y.powi(d as i32)).sum();
            assert!((want - got).abs() < 1e-9 * want.abs().max(1.0), "{t}");
        }
        assert_eq!(
            (choose(3, 0), choose(3, 1), choose(3, 2), choose(3, 3)),
            (1.0, 3.0, 3.0, 1.0)
        );
    }
}
