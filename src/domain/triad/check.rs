//! A triad body checked ([`TriadBody::check`]): every fault named by JSON
//! pointer, within the limits.

use super::*;

/// A one-line label of at most `max` characters.
pub(super) fn label(
    at: Loc<'_>,
    text: Option<String>,
    max: usize,
    errors: &mut Errors,
) -> Option<String> {
    let t = text?;
    if let Err(why) = check_str(&t, max, Chars::Line) {
        errors.add(at, why);
    }
    Some(t)
}

/// Three outputs, each finite and within ±[`MAX_READING`].
pub(super) fn reading(at: Loc<'_>, u: &[f64; 3], errors: &mut Errors) {
    if u.iter().any(|x| !(x.is_finite() && x.abs() <= MAX_READING)) {
        errors.add(
            at,
            format!("must be three finite numbers within ±{MAX_READING:e}"),
        );
    }
}

/// The detector's settings within [`MIN_DETECTOR`] and their largest
/// values, its window at least [`MIN_WINDOW_SAMPLES`] samples at `rate_hz`.
pub(super) fn check_detector(d: &Detector, rate_hz: f64, at: Loc<'_>, errors: &mut Errors) {
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
pub(super) fn at_most(at: Loc<'_>, n: usize, max: usize, what: &str, errors: &mut Errors) -> bool {
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
            for (role, id) in [
                ("stand", &named.stand),
                ("thermometer", &named.thermometer),
                ("gravity", &named.gravity),
            ] {
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
            if named.stand.is_none() && named.thermometer.is_none() && named.gravity.is_none() {
                errors.add(
                    root.key("standards"),
                    "must name a `stand`, a `thermometer`, a `gravity` or several",
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
        if self.static_temperatures_c.is_some() && self.static_positions.is_none() {
            errors.add(
                root.key("static_temperatures_c"),
                "is for `static_positions`, one per position: with `orientations` each run \
                 gives its `temperature_c`",
            );
        }
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
                let temperatures_c = self.static_temperatures_c.filter(|ts| {
                    let at = root.key("static_temperatures_c");
                    one_each(ts, positions.len(), "static position", at, &mut errors)
                });
                Some(Form::Unknown {
                    means,
                    temperatures_c,
                })
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
                let temperatures_c = r.temperature_c.filter(|ts| {
                    let at = at.key("temperature_c");
                    one_each(ts, r.samples.len(), "sample", at, &mut errors)
                });
                Some(Form::Recording {
                    rate_hz: r.rate_hz,
                    samples: r.samples,
                    detector,
                    temperatures_c,
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
        let (temperatures_c, position_temperatures_c) =
            temperatures(&runs, positions.len(), errors);
        Some(Form::Known {
            positions,
            runs: runs
                .into_iter()
                .map(|r| TriadRun { samples: r.samples })
                .collect(),
            batches,
            second_order: self.second_order.unwrap_or(false),
            temperatures_c,
            position_temperatures_c,
        })
    }
}

/// The runs' temperatures: every run's, or none; each a plausible
/// temperature ([`super::super::limits::TEMPERATURE_C`]), or one per
/// position (of `positions`), the run's their mean. With them, per run, its
/// positions' temperatures when given so.
fn temperatures(
    runs: &[TriadRunBody],
    positions: usize,
    errors: &mut Errors,
) -> (Option<Vec<f64>>, Vec<Option<Vec<f64>>>) {
    let all = Loc::Root.key("runs");
    let given = runs.iter().filter(|r| r.temperature_c.is_some()).count();
    if given == 0 {
        return (None, Vec::new());
    }
    let range = super::super::limits::TEMPERATURE_C;
    let plausible = |t: f64| range.contains(&t);
    let why = format!(
        "must be a temperature from {} to {} °C",
        range.start(),
        range.end()
    );
    let mut out = Vec::with_capacity(runs.len());
    let mut each = Vec::with_capacity(runs.len());
    for (j, r) in runs.iter().enumerate() {
        let run = all.index(j);
        let at = run.key("temperature_c");
        match &r.temperature_c {
            None => errors.add(
                at,
                "is missing: give `temperature_c` for every run or for none",
            ),
            Some(RunTemperature::One(t)) if !plausible(*t) => errors.add(at, why.as_str()),
            Some(RunTemperature::One(t)) => {
                out.push(*t);
                each.push(None);
            }
            Some(RunTemperature::Each(ts)) if ts.len() != positions => errors.add(
                at,
                format!(
                    "must be the run's temperature or one per position ({positions}), not {}",
                    ts.len()
                ),
            ),
            Some(RunTemperature::Each(ts)) => {
                let wrong: Vec<usize> = (0..ts.len()).filter(|&i| !plausible(ts[i])).collect();
                for &i in &wrong {
                    errors.add(at.index(i), why.as_str());
                }
                if wrong.is_empty() {
                    out.push(ts.iter().sum::<f64>() / ts.len() as f64);
                    each.push(Some(ts.clone()));
                }
            }
        }
    }
    if out.len() != runs.len() {
        return (None, Vec::new());
    }
    (Some(out), each)
}

/// Temperatures given one per `noun` (`static position`, `sample`) of `n`
/// (`static_temperatures_c`, a recording's `temperature_c`), each
/// plausible; the first implausible one named, not each of thousands.
fn one_each(ts: &[f64], n: usize, noun: &str, at: Loc<'_>, errors: &mut Errors) -> bool {
    if ts.len() != n {
        errors.add(
            at,
            format!(
                "must give one temperature per {noun} ({n}), not {}",
                ts.len()
            ),
        );
        return false;
    }
    let range = super::super::limits::TEMPERATURE_C;
    match ts.iter().position(|t| !range.contains(t)) {
        Some(i) => {
            errors.add(
                at.index(i),
                format!(
                    "must be a temperature from {} to {} °C",
                    range.start(),
                    range.end()
                ),
            );
            false
        }
        None => true,
    }
}
