//! A checked triad computed ([`compute`]): each form to `b`, `S`, `T`, their
//! uncertainties and the report of the fit or of the detection.

use super::*;

/// 90° minus the angle between rows `m` and `n` of `s`, degrees.
pub(super) fn skew(s: &[[f64; 3]; 3], m: usize, n: usize) -> f64 {
    let dot: f64 = (0..3).map(|k| s[m][k] * s[n][k]).sum();
    let norm = |r: &[f64; 3]| r.iter().map(|x| x * x).sum::<f64>().sqrt();
    let cos = (dot / (norm(&s[m]) * norm(&s[n]))).clamp(-1.0, 1.0);
    90.0 - cos.acos().to_degrees()
}

/// `T = S⁻¹`, column `k` being the compensation of `b + e_k` (refused when
/// `S` is singular to working precision, as compensation is).
pub fn invert(triad: &Triad) -> Option<[[f64; 3]; 3]> {
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

pub(super) fn problem(at: Loc<'_>, detail: impl Into<String>) -> Invalid {
    Invalid::one(at, detail)
}

/// Computes a checked submission.
pub fn compute(sub: TriadSubmission) -> Result<TriadResult, Invalid> {
    let temperature_c = one_temperature(&sub.form)?;
    let base = |method, b, s: [[f64; 3]; 3], t| TriadResult {
        kind: "triad",
        method,
        sensor_id: sub.sensor_id.clone(),
        unit: sub.unit.clone(),
        temperature_c,
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
            ..
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
        Form::Unknown { means, .. } => {
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
            ..
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

/// The one temperature a triad was calibrated at, °C, when `form` gives
/// temperatures: the mean of the runs' (each the mean of its positions'
/// when given per position), of the static positions' or of the
/// recording's samples'. Every reading must lie within
/// [`TOLERANCE_K`] of the coolest — one set point, as a temperature model
/// groups them ([`accelcal_core::thermal::set_points`]); otherwise the
/// reading farther from their mean (the hottest or the coolest) is
/// refused where it is, pointing to the temperature model's routes.
pub(super) fn one_temperature(form: &Form) -> Result<Option<f64>, Invalid> {
    let (readings, averaged, at): (Vec<(usize, f64)>, &[f64], &str) = match form {
        Form::Known {
            temperatures_c: Some(t),
            position_temperatures_c,
            ..
        } => {
            let readings = t
                .iter()
                .enumerate()
                .flat_map(|(j, &mean)| {
                    match position_temperatures_c.get(j).and_then(Option::as_ref) {
                        Some(each) => each.iter().map(|&x| (j, x)).collect(),
                        None => vec![(j, mean)],
                    }
                })
                .collect();
            (readings, t, "/runs")
        }
        Form::Unknown {
            temperatures_c: Some(t),
            ..
        } => (
            t.iter().copied().enumerate().collect(),
            t,
            "/static_temperatures_c",
        ),
        Form::Recording {
            temperatures_c: Some(t),
            ..
        } => (
            t.iter().copied().enumerate().collect(),
            t,
            "/recording/temperature_c",
        ),
        _ => return Ok(None),
    };
    let by = |a: &&(usize, f64), b: &&(usize, f64)| a.1.total_cmp(&b.1);
    if let (Some(coolest), Some(hottest)) = (readings.iter().min_by(by), readings.iter().max_by(by))
        && hottest.1 - coolest.1 > TOLERANCE_K
    {
        // The reading farther from the readings' mean is the odd one out.
        let mean = readings.iter().map(|r| r.1).sum::<f64>() / readings.len() as f64;
        let odd = if hottest.1 - mean >= mean - coolest.1 {
            hottest
        } else {
            coolest
        };
        let at = match form {
            Form::Known { .. } => format!("{at}/{}/temperature_c", odd.0),
            _ => format!("{at}/{}", odd.0),
        };
        return Err(Invalid::one(
            at,
            format!(
                "{} °C: the readings span {:.3} K ({} to {} °C), and a triad calibrated at one \
                 temperature is held within {TOLERANCE_K} K; readings at several temperatures \
                 make a temperature model (POST /v1/identify/thermal/triad fits one, POST \
                 /v1/calibrations/thermal/triad stores it)",
                odd.1,
                hottest.1 - coolest.1,
                coolest.1,
                hottest.1
            ),
        ));
    }
    Ok(Some(averaged.iter().sum::<f64>() / averaged.len() as f64))
}

/// The result of a fit from the gravity magnitude, with its uncertainty
/// budget for the submission's gravity and coverage factor.
pub(super) fn unknown(
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

pub(super) fn detection_report(found: &Detection, rate_hz: f64, d: &Detector) -> DetectionReport {
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

pub(super) fn axis_problem(e: &TriadError) -> Invalid {
    let runs = Loc::Root.key("runs");
    match e {
        TriadError::CopiedRun { run, .. } => problem(runs.index(*run), e.to_string()),
        _ => problem(runs, e.to_string()),
    }
}

pub(super) fn fit_problem(at: Loc<'_>, e: &GravityFitError) -> Invalid {
    problem(at, e.to_string())
}

pub(crate) fn detect_problem(at: &Loc<'_>, e: &DetectError) -> Invalid {
    match e {
        DetectError::Parameter { name } if *name == "rate_hz" => {
            problem(at.key("rate_hz"), e.to_string())
        }
        DetectError::Parameter { name } => problem(at.key("detector").key(name), e.to_string()),
        DetectError::NotFinite { index } => problem(at.key("samples").index(*index), e.to_string()),
        DetectError::TooShort { .. } => problem(at.key("samples"), e.to_string()),
    }
}
