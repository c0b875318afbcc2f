//! A triad's temperature model as PX4's thermal compensation parameters
//! (issue 45 item 5): `TC_A_ENABLE`, `TC_A0_TREF`, `TC_A0_TMIN`,
//! `TC_A0_TMAX` and `TC_A0_X{0..3}_{0,1,2}`, in QGroundControl's
//! parameter-file lines (`1 1 NAME VALUE TYPE`, 9 a float, 6 an integer).
//!
//! **PX4's convention**, read in PX4-Autopilot's sources:
//! `TemperatureCompensation::calc_thermal_offsets_3D`
//! (`src/modules/temperature_compensation/TemperatureCompensation.cpp`)
//! computes, per axis `i`,
//!
//! ```text
//! offset_i = X0_i + X1_i dT + X2_i dT² + X3_i dT³,   dT = clamp(T, TMIN, TMAX) − TREF
//! ```
//!
//! in m/s², and `Accelerometer::Correct`
//! (`src/lib/sensor_calibration/Accelerometer.hpp`) subtracts it with the
//! static offset before the scale: `a = R ((u − offset − CAL_ACC0_OFF) ⊙
//! CAL_ACC0_SCALE)`. So `X_d_i` is exactly `a_d` of `b_i`'s polynomial (in
//! m/s² per K^d) about `TREF = T_ref`, `TMIN`/`TMAX` its valid range, and
//! the offset evaluated is `b_i(T)` itself — its constant term included,
//! so `CAL_ACC0_xOFF` must be 0 beside it (or calibrated after loading, as
//! PX4's own thermal workflow recalibrates). PX4 clamps the temperature to
//! the range, which is what the model's range asks.
//!
//! **Not carried**: PX4 has no thermal scale factor or cross-axis term,
//! so `S(T)` is not exported; the file states how far each element moves
//! over the range against its uncertainty, and the export is refused when
//! one moves beyond it ([`super::firmware`]).

use std::fmt::Write as _;

use super::TriadThermalModel;
use super::firmware::{ThermalExportError, carried, not_carried_lines};
use crate::domain::triad_export::{ExportError, ascii_escaped, to_m_s2};

/// The PX4 parameter file of `model`, described by `source`.
pub fn px4(model: &TriadThermalModel, source: &str) -> Result<String, ThermalExportError> {
    let per_unit = to_m_s2(&model.unit).ok_or_else(|| ExportError::Unit {
        format: "PX4",
        unit: model.unit.clone(),
    })?;
    let dropped = carried(model, "PX4")?;
    let reference = model.b[0].reference_c;
    let [t_min, t_max] = model.b[0].range_c;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# accelcal temperature model for PX4 thermal compensation: {}",
        ascii_escaped(source)
    );
    let _ = writeln!(out, "# outputs u in {}", ascii_escaped(&model.unit));
    let _ = writeln!(
        out,
        "# PX4 (TemperatureCompensation.cpp, calc_thermal_offsets_3D): offset_i = X0_i + X1_i dT + \
         X2_i dT^2 + X3_i dT^3, dT = clamp(T, TMIN, TMAX) - TREF, in m/s2,"
    );
    let _ = writeln!(
        out,
        "# subtracted from the reading with CAL_ACC0_xOFF (Accelerometer.hpp, Correct): offset = b(T), \
         the whole bias, so set CAL_ACC0_xOFF to 0 beside it."
    );
    let _ = writeln!(
        out,
        "# Set TC_A0_ID to the accelerometer's device id before loading."
    );
    not_carried_lines(&mut out, "PX4", &dropped);
    // Temperatures to 1e-6 K; the polynomial's coefficients, which span
    // many decades (a_3 of 1e-9 beside a_0 of 1e-1), to ten significant
    // digits — more than the float PX4 keeps.
    let float = |out: &mut String, name: &str, value: f64| {
        let _ = writeln!(out, "1\t1\t{name}\t{value:.6}\t9");
    };
    let coefficient = |out: &mut String, name: &str, value: f64| {
        let _ = writeln!(out, "1\t1\t{name}\t{value:.9e}\t9");
    };
    let _ = writeln!(out, "1\t1\tTC_A_ENABLE\t1\t6");
    float(&mut out, "TC_A0_TREF", reference);
    float(&mut out, "TC_A0_TMIN", t_min);
    float(&mut out, "TC_A0_TMAX", t_max);
    for d in 0..=3 {
        for (i, b) in model.b.iter().enumerate() {
            let a = b.coefficients.get(d).copied().unwrap_or(0.0) * per_unit;
            coefficient(&mut out, &format!("TC_A0_X{d}_{i}"), a);
        }
    }
    Ok(out)
}
