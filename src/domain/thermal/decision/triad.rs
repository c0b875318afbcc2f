//! A triad's temperature model judged against a sensor type's limits
//! (issue 45 item 4, triads). A sensor type limits single-axis terms; as a
//! stored triad is judged ([`crate::domain::triad::decide_triad`]), axis
//! `m`'s terms are elements of the triad — `k0` is `b_m`, `ki`, `kp`, `ko`
//! are row `m` of `S` ([`row_terms`]). So axis `m`'s model over
//! temperature is the single axis's model whose `k0(T)`, `ki(T)`, … are
//! those elements' polynomials, its set points the triad's with those
//! elements' fused values, standard errors and the axis's fused degrees of
//! freedom, and the thermometer the triad's ([`axis_model`]); each axis is
//! judged exactly as a single axis's model is ([`decide_model`]: every
//! limited term at every set point and across the range, its worst), and
//! each judgement named by the element it is (`b_x`, `S_xy`). The model's
//! verdict is the worst of its elements'. Of a model from the gravity
//! magnitude, `S_xy`, `S_xz`, `S_yz` are zero by the frame convention and
//! are not judged.

use std::collections::BTreeMap;

use accelcal_core::coverage::Coverage;
use accelcal_core::decision::{Limit, Rule, Verdict};
use accelcal_core::{Term, TermMap};
use serde::{Deserialize, Serialize};

use super::super::{SetPointResult, ThermalModel, ThermalParams, TriadThermalModel};
use super::{ThermalTermDecision, decide_model};
use crate::domain::triad::{FIXED_BY_CONVENTION, GRAVITY_MAGNITUDE, Slot, element, row_terms};

/// A triad's temperature model judged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriadThermalDecision {
    /// The rule applied.
    pub rule: Rule,
    /// The worst verdict of the elements.
    pub verdict: Verdict,
    /// Per limited element (`b_x`, `S_xy`, …), judged as a single axis's
    /// coefficient over temperature.
    pub elements: BTreeMap<String, ThermalTermDecision>,
}

/// Axis `m`'s terms of a model over temperature and where each sits
/// (`kii` has no polynomial: second-order terms are not modelled over
/// temperature).
fn slots(m: usize) -> impl Iterator<Item = (Term, Slot)> {
    row_terms(m)
        .into_iter()
        .filter(|(_, slot)| *slot != Slot::S2)
}

/// Whether axis `m`'s term at `slot` is zero by the frame convention of
/// a model from the gravity magnitude: not measured, so not judged (as a
/// triad's at one temperature is not).
fn by_convention(model: &TriadThermalModel, m: usize, slot: Slot) -> bool {
    model.method == GRAVITY_MAGNITUDE
        && matches!(slot, Slot::S(k) if FIXED_BY_CONVENTION.contains(&(m, k)))
}

/// The element of `b` or `S` at `slot` of axis `m`.
fn pick<T>(slot: Slot, m: usize, b: &[T; 3], s: &[[T; 3]; 3]) -> Option<T>
where
    T: Clone,
{
    match slot {
        Slot::B => Some(b[m].clone()),
        Slot::S(k) => Some(s[m][k].clone()),
        Slot::S2 => None,
    }
}

/// Axis `m` of `model` as a single axis's model over temperature (module
/// doc).
pub fn axis_model(model: &TriadThermalModel, m: usize) -> ThermalModel {
    let map = |b: &[f64; 3], s: &[[f64; 3]; 3]| {
        TermMap(
            slots(m)
                .filter_map(|(t, slot)| pick(slot, m, b, s).map(|v| (t, v)))
                .collect(),
        )
    };
    let set_points = model
        .set_points
        .iter()
        .map(|p| SetPointResult {
            temperature_c: p.temperature_c,
            runs: p.runs.clone(),
            batches: p.batches,
            coefficients: map(&p.b, &p.s),
            std_errors: map(&p.b_std_errors, &p.s_std_errors),
            dof: p.axes_dof.as_ref().map(|d| d[m].clone()),
        })
        .collect();
    ThermalModel {
        sensor_id: model.sensor_id.clone().unwrap_or_default(),
        unit: model.unit.clone(),
        tolerance_k: model.tolerance_k,
        selection: model.selection.clone(),
        fitted_with: ThermalParams::default(),
        set_points,
        coefficients: TermMap(
            slots(m)
                .filter_map(|(t, slot)| pick(slot, m, &model.b, &model.s).map(|p| (t, p)))
                .collect(),
        ),
        thermometer_std_c: model.thermometer_std_c,
    }
}

/// `model` judged by `rule` against `limits` with `coverage` (module
/// doc); a limited term no axis models (`kii`, or a term a triad does not
/// identify) is the error.
pub fn decide_triad_model(
    model: &TriadThermalModel,
    rule: Rule,
    limits: &TermMap<Limit>,
    coverage: Coverage,
) -> Result<TriadThermalDecision, Term> {
    let mut elements = BTreeMap::new();
    let mut verdict = Verdict::Pass;
    for m in 0..3 {
        let measured = TermMap(
            limits
                .iter()
                .filter(|(t, _)| {
                    !slots(m).any(|(term, slot)| term == *t && by_convention(model, m, slot))
                })
                .map(|(t, l)| (t, *l))
                .collect(),
        );
        let judged = decide_model(&axis_model(model, m), rule, &measured, coverage)?;
        verdict = verdict.max(judged.verdict);
        for (term, d) in judged.terms.0 {
            if let Some((_, slot)) = slots(m).find(|(t, _)| *t == term) {
                elements.insert(element(m, slot), d);
            }
        }
    }
    Ok(TriadThermalDecision {
        rule,
        verdict,
        elements,
    })
}
