//! The metrology a lab signs, against independent computations: closed forms
//! for the four-position tumble, finite differences through the fit for any
//! schedule, hand-computed regressions and charts.

use accelcal_core::coverage::Coverage;
use accelcal_core::decision::Verdict;
use accelcal_core::history::{Point, as_found, stability};
use accelcal_core::quality::{Scatter, Warning, assess};
use accelcal_core::temperature::sensitivity;
use accelcal_core::uncertainty::{ARCSEC, Stand, budget, coverage_probability};
use accelcal_core::{
    Compensator, Design, Gravity, Model, Mount, Position, Reading, Run, Summary, Term, TermMap,
    TumbleTest,
};

use Term::*;

#[track_caller]
fn near(got: f64, want: f64, relative: f64) {
    assert!(
        (got - want).abs() <= relative * want.abs().max(1e-300),
        "{got:e} vs {want:e} (relative {relative:e})"
    );
}

fn tumble(mount: Mount, n: u32) -> Vec<Position> {
    (0..n)
        .map(|k| Position::from_angle(360.0 * f64::from(k) / f64::from(n), mount, None))
        .collect()
}

/// One noiseless run of `truth` at `positions`, plus a second one with a
/// little deterministic noise (a test needs runs; the budget needs only the
/// design and the coefficients).
fn test_of(truth: &TermMap<f64>, model: &Model, positions: Vec<Position>) -> TumbleTest {
    let c = Compensator::new(truth).unwrap();
    let runs = (0..4)
        .map(|j| {
            Run::from_samples(
                positions
                    .iter()
                    .enumerate()
                    .map(|(r, p)| vec![c.output(&p.a) + 1e-7 * ((j * 7 + r * 3) as f64).sin()])
                    .collect(),
            )
        })
        .collect();
    TumbleTest::new(model.clone(), positions, runs).unwrap()
}

fn linear() -> TermMap<f64> {
    TermMap(vec![(K0, -8.4e-4), (Ki, -1.216), (Kp, 6.2e-3)])
}

/// The normal distribution's coverage probabilities, against the
/// standard tables (GUM Table G.1: k = 1, 1.645, 1.960, 2, 2.576, 3;
/// the values are Python's `math.erf(k / sqrt(2))`).
#[test]
fn coverage_probabilities_are_the_normal_distributions() {
    for (k, p) in [
        (1.0, 0.682_689_492_137_086),
        (1.645, 0.900_030_188_921_757_2),
        (1.960, 0.950_004_209_703_559),
        (2.0, 0.954_499_736_103_642),
        (2.576, 0.990_004_935_368_53),
        (3.0, 0.997_300_203_936_740),
    ] {
        // statrs' erf is good to about 1e-10.
        near(coverage_probability(k), p, 1e-9);
    }
    assert_eq!(coverage_probability(0.0), 0.0);
}

/// Four positions, linear model: by hand (module docs of `uncertainty`),
/// indexing(k0) = σ·√(ki² + kp²)/(2√2), indexing(ki) = σ·|kp|/√2,
/// indexing(kp) = σ·|ki|/√2; gravity = u·|k| on ki and kp, 0 on k0.
#[test]
fn four_position_budget_matches_the_closed_form() {
    let k = linear();
    let t = test_of(&k, &Model::pendulum(), tumble(Mount::Pendulum, 4));
    let se = TermMap(vec![(K0, 1e-6), (Ki, 2e-6), (Kp, 3e-6)]);
    let sigma = 5.0 * ARCSEC;
    let u = 2e-5;
    let b = budget(
        &t,
        &k,
        (&se, &TermMap(vec![])),
        Stand {
            angle_std_rad: sigma,
            gravity_rel_std: u,
            ..Stand::default()
        },
        Coverage::Factor(2.0),
        &TermMap(vec![]),
    )
    .unwrap();
    let (ki, kp) = (k[Ki], k[Kp]);
    near(
        b.terms[K0].indexing,
        sigma * (ki * ki + kp * kp).sqrt() / (2.0 * 2f64.sqrt()),
        1e-12,
    );
    near(b.terms[Ki].indexing, sigma * kp.abs() / 2f64.sqrt(), 1e-12);
    near(b.terms[Kp].indexing, sigma * ki.abs() / 2f64.sqrt(), 1e-12);
    assert!(b.terms[K0].gravity < 1e-20);
    near(b.terms[Ki].gravity, u * ki.abs(), 1e-12);
    near(b.terms[Kp].gravity, u * kp.abs(), 1e-12);
    for term in [K0, Ki, Kp] {
        let tb = b.terms[term];
        assert_eq!(tb.statistical, se[term]);
        near(
            tb.combined,
            (tb.statistical.powi(2) + tb.indexing.powi(2) + tb.gravity.powi(2)).sqrt(),
            1e-15,
        );
        near(tb.expanded, 2.0 * tb.combined, 1e-15);
    }
    assert_eq!(b.coverage, Coverage::Factor(2.0));
}

/// Any schedule and model: the indexing and gravity sensitivities equal
/// finite differences through the fit — perturb one angle (or the gravity
/// magnitude), regenerate the true outputs, refit on the nominal design.
#[test]
fn budget_equals_finite_differences_through_the_fit() {
    let truth = TermMap(vec![
        (K0, -8.4e-4),
        (Ki, -1.216),
        (Kp, 6.2e-3),
        (Kpi, -4.4e-4),
        (Kii, 1.3e-4),
        (Kiii, -6.0e-5),
    ]);
    let model = Model::new(truth.iter().map(|(t, _)| t).collect()).unwrap();
    for (mount, n) in [(Mount::Pendulum, 12), (Mount::Pendulum, 24)] {
        let positions = tumble(mount, n);
        let t = test_of(&truth, &model, positions.clone());
        let zero = TermMap(truth.iter().map(|(t, _)| (t, 0.0)).collect());
        let (sigma, u) = (3.0 * ARCSEC, 1e-5);
        let b = budget(
            &t,
            &truth,
            (&zero, &TermMap(vec![])),
            Stand {
                angle_std_rad: sigma,
                gravity_rel_std: u,
                ..Stand::default()
            },
            Coverage::Factor(2.0),
            &TermMap(vec![]),
        )
        .unwrap();
        let nominal: Vec<Gravity> = positions.iter().map(|p| p.a).collect();
        let design = Design::new(&model, &nominal).unwrap();
        let c = Compensator::new(&truth).unwrap();
        let fit = |y: &[f64]| design.solve(y).coefficients;
        let base: Vec<f64> = nominal.iter().map(|a| c.output(a)).collect();
        let k0 = fit(&base);
        let eps = 1e-6;
        let mut squares = vec![0.0; model.len()];
        for j in 0..positions.len() {
            let deg = 360.0 * j as f64 / n as f64;
            let mut y = base.clone();
            y[j] = c.output(&mount.gravity(deg + f64::to_degrees(eps)));
            let k1 = fit(&y);
            for (m, (term, v)) in k1.iter().enumerate() {
                squares[m] += ((v - k0[term]) / eps).powi(2);
            }
        }
        let scaled: Vec<f64> = nominal
            .iter()
            .map(|a| c.output(&Gravity::from(a.to_array().map(|x| x * (1.0 + eps)))))
            .collect();
        let kg = fit(&scaled);
        // Finite differences carry rounding of ~1e-16/ε; compare to that.
        let floor = 1e-9 * sigma.max(u);
        for (m, term) in model.terms().iter().enumerate() {
            let (idx, grav) = (
                sigma * squares[m].sqrt(),
                u * ((kg[*term] - k0[*term]) / eps).abs(),
            );
            let (got_i, got_g) = (b.terms[*term].indexing, b.terms[*term].gravity);
            assert!(
                (got_i - idx).abs() <= 1e-5 * idx + floor,
                "{term} indexing {got_i:e} vs {idx:e}"
            );
            assert!(
                (got_g - grav).abs() <= 1e-5 * grav + floor,
                "{term} gravity {got_g:e} vs {grav:e}"
            );
        }
    }
}

#[test]
fn without_stand_uncertainties_combined_is_statistical() {
    let k = linear();
    let t = test_of(
        &k,
        &Model::pendulum(),
        tumble(Mount::Gate, 8)
            .into_iter()
            .map(|mut p| {
                p.a = Gravity {
                    i: p.a.i,
                    p: p.a.o,
                    o: 0.0,
                };
                p.rotation = None;
                p
            })
            .collect(),
    );
    let se = TermMap(vec![(K0, 1e-6), (Ki, 2e-6), (Kp, 3e-6)]);
    let b = budget(
        &t,
        &k,
        (&se, &TermMap(vec![])),
        Stand::default(),
        Coverage::Factor(3.0),
        &TermMap(vec![]),
    )
    .unwrap();
    for term in [K0, Ki, Kp] {
        assert_eq!(b.terms[term].combined, se[term]);
        assert_eq!(b.terms[term].expanded, 3.0 * se[term]);
    }
    // A model component enters in quadrature.
    let model = TermMap(vec![(Ki, 4e-6)]);
    let b = budget(
        &t,
        &k,
        (&se, &TermMap(vec![])),
        Stand::default(),
        Coverage::Factor(3.0),
        &model,
    )
    .unwrap();
    assert_eq!(b.terms[Ki].model, 4e-6);
    near(b.terms[Ki].combined, (4e-12f64 + 16e-12).sqrt(), 1e-15);
    assert_eq!(b.terms[K0].model, 0.0);
    assert_eq!(b.terms[K0].combined, se[K0]);
}

/// Positions given by gravity vectors: each is turned by a small rotation
/// about each axis (Rodrigues' formula), the run-averaged values refitted on
/// the turned design, and the squared derivatives summed — the definition
/// by central differences, residual term included (the data hold an
/// unmodelled `kii`, so the residuals are far from zero).
#[test]
fn explicit_positions_budget_equals_finite_rotations_through_the_fit() {
    let truth = TermMap(vec![
        (K0, -8.4e-4),
        (Ki, -1.216),
        (Kp, 6.2e-3),
        (Ko, 2e-3),
        (Kii, 4e-3),
    ]);
    let model = Model::new(vec![K0, Ki, Kp, Ko]).unwrap();
    let positions: Vec<Position> = (0..14)
        .map(|k| {
            let z = 1.0 - 2.0 * (f64::from(k) + 0.5) / 14.0;
            let (s, c) = (2.399_963_229_728_653 * f64::from(k)).sin_cos();
            let r = (1.0 - z * z).sqrt();
            Position::from_components([r * c, r * s, z], None)
        })
        .collect();
    let t = test_of(&truth, &model, positions.clone());
    let sigma = 20.0 * ARCSEC;
    let stand = Stand {
        angle_std_rad: sigma,
        gravity_rel_std: 0.0,
        ..Stand::default()
    };
    let zero = TermMap(model.terms().iter().map(|t| (*t, 0.0)).collect());
    let b = budget(
        &t,
        &truth,
        (&zero, &TermMap(vec![])),
        stand,
        Coverage::Factor(2.0),
        &TermMap(vec![]),
    )
    .unwrap();
    let averaged = t.averaged_values();
    let fit = |a: &[Gravity]| {
        Design::new(&model, a)
            .unwrap()
            .solve(&averaged)
            .coefficients
    };
    let nominal: Vec<Gravity> = positions.iter().map(|p| p.a).collect();
    let h = 1e-5;
    let mut squares = vec![0.0; model.len()];
    for j in 0..nominal.len() {
        for axis in 0..3 {
            let turned = |angle: f64| {
                let mut a = nominal.clone();
                let v = a[j].to_array();
                let mut e = [0.0; 3];
                e[axis] = 1.0;
                let cross = [
                    e[1] * v[2] - e[2] * v[1],
                    e[2] * v[0] - e[0] * v[2],
                    e[0] * v[1] - e[1] * v[0],
                ];
                let dot = v[axis];
                let (s, c) = angle.sin_cos();
                a[j] = Gravity::from(
                    [0, 1, 2].map(|m| v[m] * c + cross[m] * s + e[m] * dot * (1.0 - c)),
                );
                fit(&a)
            };
            let (plus, minus) = (turned(h), turned(-h));
            for (m, term) in model.terms().iter().enumerate() {
                squares[m] += ((plus[*term] - minus[*term]) / (2.0 * h)).powi(2);
            }
        }
    }
    for (m, term) in model.terms().iter().enumerate() {
        let want = sigma * squares[m].sqrt();
        assert!(want > 0.0);
        near(b.terms[*term].indexing, want, 1e-6);
    }
}

/// As found: the sensor now follows `now`, the previous calibration said
/// `before`; by hand, error_output = (k0 − k0′) + (ki − ki′)·a_i + (kp − kp′)·a_p
/// and error_g = error_output / ki′.
#[test]
fn as_found_is_the_error_of_the_previous_coefficients() {
    let now = linear();
    let before = TermMap(vec![(K0, -5.0e-4), (Ki, -1.19), (Kp, 6.0e-3)]);
    let positions = tumble(Mount::Pendulum, 4);
    let c = Compensator::new(&now).unwrap();
    // Unequal sample counts: the position value is the mean of every sample,
    // two at +3e-6 and one at −6e-6, which is 0 (the mean of the runs' means
    // would be −1.5e-6). Run 0 given as samples, then as their summary.
    let twice = Run::from_samples(
        positions
            .iter()
            .map(|p| vec![c.output(&p.a) + 3e-6; 2])
            .collect(),
    );
    let summarised = Run {
        readings: positions
            .iter()
            .map(|p| {
                Reading::Summary(Summary {
                    mean: c.output(&p.a) + 3e-6,
                    std: 0.0,
                    count: 2,
                })
            })
            .collect(),
    };
    let once = Run::from_samples(
        positions
            .iter()
            .map(|p| vec![c.output(&p.a) - 6e-6])
            .collect(),
    );
    for run in [twice, summarised] {
        let runs = vec![run, once.clone()];
        let t = TumbleTest::new(Model::pendulum(), positions.clone(), runs).unwrap();
        let af = as_found(&t, &before).unwrap();
        check_as_found(&af, &positions, &now, &before);
        assert!(
            as_found(&t, &TermMap(vec![(K0, 1.0)])).is_none(),
            "no ki, no as found"
        );
    }
}

fn check_as_found(
    af: &accelcal_core::history::AsFound,
    positions: &[Position],
    now: &TermMap<f64>,
    before: &TermMap<f64>,
) {
    let mut max = 0.0f64;
    for (p, e) in positions.iter().zip(&af.positions) {
        let want = (now[K0] - before[K0])
            + (now[Ki] - before[Ki]) * p.a.i
            + (now[Kp] - before[Kp]) * p.a.p;
        near(e.error_output, want, 1e-9);
        near(e.error_g, want / before[Ki], 1e-9);
        max = max.max((want / before[Ki]).abs());
    }
    near(af.max_abs_error_g, max, 1e-9);
}

fn point(id: &str, t: f64, x: f64, se: f64) -> Point {
    Point {
        id: id.into(),
        t_years: t,
        values: TermMap(vec![(K0, x)]),
        std_errors: TermMap(vec![(K0, se)]),
    }
}

/// t = 0, 1, 2, 3 and x = 1, 3, 2, 5 by hand: x̄ = 2.75, slope 5.5/5 = 1.1,
/// residuals (−0.1, 0.8, −1.3, 0.6), RSS 2.7, SE(b) = √(1.35/5),
/// moving ranges 2, 1, 3 (mean 2), limits 2.75 ∓ 5.32.
#[test]
fn stability_by_hand() {
    let pts = [
        point("a", 0.0, 1.0, 0.1),
        point("b", 1.0, 3.0, 0.1),
        point("c", 2.0, 2.0, 0.1),
        point("d", 3.0, 5.0, 0.1),
    ];
    let s = stability(&pts, 2.0);
    let k = &s[K0];
    near(k.mean, 2.75, 1e-15);
    near(k.std.unwrap(), (8.75f64 / 3.0).sqrt(), 1e-15);
    assert_eq!((k.min, k.max), (1.0, 5.0));
    near(k.drift_per_year.unwrap(), 1.1, 1e-14);
    near(k.drift_std_error.unwrap(), (1.35f64 / 5.0).sqrt(), 1e-14);
    near(k.drift_t.unwrap(), 1.1 / (1.35f64 / 5.0).sqrt(), 1e-14);
    near(k.control.moving_range_mean.unwrap(), 2.0, 1e-15);
    near(k.control.lower.unwrap(), 2.75 - 5.32, 1e-15);
    near(k.control.upper.unwrap(), 2.75 + 5.32, 1e-15);
    assert!(k.control.out_of_control.is_empty());
    near(k.latest_change.unwrap(), 3.0, 1e-15);
    near(
        k.latest_change_expanded.unwrap(),
        2.0 * 0.02f64.sqrt(),
        1e-15,
    );
    assert_eq!(k.latest_change_significant, Some(true));
}

/// One quantity (a triad's element) by the same hand computation: every
/// figure as `stability_by_hand`; the latest change is judged only with
/// both its points' standard errors.
#[test]
fn one_quantity_by_hand_and_a_change_without_standard_errors_is_not_judged() {
    use accelcal_core::history::quantity;
    let (ids, t, x) = (
        ["a", "b", "c", "d"],
        [0.0, 1.0, 2.0, 3.0],
        [1.0, 3.0, 2.0, 5.0],
    );
    let q = quantity(&ids, &t, &x, &[Some(0.1); 4], 2.0);
    near(q.mean, 2.75, 1e-15);
    near(q.drift_per_year.unwrap(), 1.1, 1e-14);
    near(q.drift_std_error.unwrap(), (1.35f64 / 5.0).sqrt(), 1e-14);
    near(q.control.lower.unwrap(), 2.75 - 5.32, 1e-15);
    near(q.latest_change.unwrap(), 3.0, 1e-15);
    near(
        q.latest_change_expanded.unwrap(),
        2.0 * 0.02f64.sqrt(),
        1e-15,
    );
    assert_eq!(q.latest_change_significant, Some(true));
    let unjudged = quantity(&ids, &t, &x, &[Some(0.1), Some(0.1), None, Some(0.1)], 2.0);
    near(unjudged.latest_change.unwrap(), 3.0, 1e-15);
    assert_eq!(unjudged.latest_change_expanded, None);
    assert_eq!(unjudged.latest_change_significant, None);
    let far = quantity(&ids, &t, &[1.0, 1.0, 1.0, 9.0], &[None; 4], 2.0);
    assert_eq!(
        far.control.out_of_control,
        Vec::<String>::new(),
        "limits 3 ± 2.66·8/3 hold 9"
    );
    let flat = quantity(&ids, &t, &[1.0, 1.1, 0.9, 1.0], &[Some(1.0); 4], 2.0);
    assert_eq!(flat.latest_change_significant, Some(false));
}

#[test]
fn a_perfectly_linear_history_drifts_by_its_slope_with_no_residual() {
    let pts: Vec<Point> = (0..6)
        .map(|k| {
            point(
                &format!("p{k}"),
                0.25 * k as f64,
                1.0 - 0.04 * 0.25 * k as f64,
                0.01,
            )
        })
        .collect();
    let s = stability(&pts, 2.0);
    near(s[K0].drift_per_year.unwrap(), -0.04, 1e-12);
    assert!(s[K0].drift_std_error.unwrap() < 1e-15);
    assert_eq!(
        s[K0].drift_t, None,
        "an exact line has no finite t statistic"
    );
}

#[test]
fn control_limits_catch_an_outlier_and_short_histories_say_less() {
    let mut pts: Vec<Point> = (0..12)
        .map(|k| {
            point(
                &format!("p{k}"),
                k as f64,
                1.0 + 0.001 * (k % 2) as f64,
                0.001,
            )
        })
        .collect();
    pts.push(point("jump", 12.0, 1.1, 0.001));
    let s = stability(&pts, 2.0);
    assert_eq!(s[K0].control.out_of_control, ["jump"]);
    let one = stability(&pts[..1], 2.0);
    assert_eq!(one[K0].std, None);
    assert_eq!(one[K0].control.moving_range_mean, None);
    assert_eq!(one[K0].latest_change, None);
    let two = stability(&pts[..2], 2.0);
    assert_eq!(two[K0].drift_per_year, None);
    assert!(two[K0].latest_change.is_some());
    // Three points are the fewest with a residual degree of freedom: the
    // first three lie symmetric about a flat line, so the slope is exactly 0.
    let three = stability(&pts[..3], 2.0);
    assert_eq!(three[K0].drift_per_year, Some(0.0));
    assert!(three[K0].drift_std_error.unwrap() > 0.0);
    // Only terms present in every calibration.
    let mut mixed = pts[..2].to_vec();
    mixed[1].values.0.push((Ki, 1.0));
    assert_eq!(stability(&mixed, 2.0).len(), 1);
}

/// T = 20, 25, 30 °C and x = 1.0, 1.5, 1.9 by hand: slope 4.5/50 = 0.09 /K,
/// residuals (−1/60, 1/30, −1/60), RSS 1/600, SE √(1/600)/√50.
#[test]
fn temperature_sensitivity_by_hand() {
    let positions = tumble(Mount::Pendulum, 4);
    let runs: Vec<accelcal_core::Identification> = [1.0, 1.5, 1.9]
        .iter()
        .map(|k0| {
            Design::new(
                &Model::new(vec![K0, Ki]).unwrap(),
                &positions.iter().map(|p| p.a).collect::<Vec<_>>(),
            )
            .unwrap()
            .solve(&[*k0, k0 - 1.0, *k0, k0 + 1.0])
        })
        .collect();
    let s = sensitivity(&runs, &[20.0, 25.0, 30.0]).unwrap();
    near(s[K0].per_kelvin, 0.09, 1e-13);
    near(
        s[K0].std_error.unwrap(),
        (1.0f64 / 600.0).sqrt() / 50f64.sqrt(),
        1e-10,
    );
    near(s[K0].reference_c, 25.0, 1e-15);
    near(s[K0].value_at_reference, 4.4 / 3.0, 1e-15);
    assert!(
        s[Ki].per_kelvin.abs() < 1e-14,
        "ki is the same in every run"
    );
    assert!(
        sensitivity(&runs, &[20.0, 20.0, 20.0]).is_none(),
        "one temperature: nothing to fit"
    );
    assert!(
        sensitivity(&runs[..2], &[20.0, 30.0]).unwrap()[K0]
            .std_error
            .is_none()
    );
}

/// Explicit components rounded to 6 decimals make k0 with kii, kpp, koo
/// merely ill-conditioned instead of singular: accepted, and flagged with
/// those terms.
#[test]
fn a_nearly_singular_design_is_flagged_with_its_terms() {
    let positions: Vec<Position> = (0..40)
        .map(|k| {
            let z = 1.0 - 2.0 * (f64::from(k) + 0.5) / 40.0;
            let (s, c) = (2.399_963_229_728_653 * f64::from(k)).sin_cos();
            let r = (1.0 - z * z).sqrt();
            let round = |x: f64| (x * 1e6).round() / 1e6;
            Position::from_components([round(r * c), round(r * s), round(z)], None)
        })
        .collect();
    let model = Model::new(vec![K0, Ki, Kp, Ko, Kii, Kpp, Koo]).unwrap();
    let truth = TermMap(vec![
        (K0, 1e-3),
        (Ki, -1.2),
        (Kp, 6e-3),
        (Ko, -3e-3),
        (Kii, 1e-4),
        (Kpp, 0.0),
        (Koo, 0.0),
    ]);
    let t = test_of(&truth, &model, positions);
    let cal = t.calibrate(2).unwrap();
    let q = assess(&t, &cal);
    assert!(q.condition_number > 1e6, "{}", q.condition_number);
    match &q.warnings[..] {
        [Warning::IllConditioned { terms, .. }] => {
            for term in [K0, Kii, Kpp, Koo] {
                assert!(terms.contains(&term), "{terms:?}");
            }
            assert!(!terms.contains(&Ki), "{terms:?}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_run_ten_times_noisier_than_the_median_is_flagged() {
    let positions = tumble(Mount::Pendulum, 8);
    let c = Compensator::new(&linear()).unwrap();
    let runs: Vec<Run> = (0..5)
        .map(|j| {
            let amp = if j == 3 { 1e-4 } else { 1e-5 };
            Run::from_samples(
                positions
                    .iter()
                    .enumerate()
                    .map(|(r, p)| vec![c.output(&p.a) + amp * ((r * 5 + j) as f64).sin()])
                    .collect(),
            )
        })
        .collect();
    let t = TumbleTest::new(Model::pendulum(), positions, runs).unwrap();
    let cal = t.calibrate(2).unwrap();
    let q = assess(&t, &cal);
    let noisy: Vec<usize> = q
        .warnings
        .iter()
        .filter_map(|w| match w {
            Warning::NoisyRun {
                run,
                test,
                scatter:
                    Scatter::Residual {
                        residual_std,
                        others_residual_std,
                    },
            } => {
                assert!(*residual_std > 3.0 * others_residual_std);
                assert_eq!((test.df1, test.df2), (5, 20));
                assert!(test.p_value < 0.01 / 5.0);
                Some(*run)
            }
            _ => None,
        })
        .collect();
    assert_eq!(noisy, [3]);
    assert_eq!(
        cal.fused.coefficients.len(),
        3,
        "flags never change the numbers"
    );
    let _ = Verdict::Pass;
}

/// The wire names of verdicts are their serde names.
#[test]
fn verdicts_are_named_as_serialised() {
    for v in [Verdict::Pass, Verdict::Conditional, Verdict::Fail] {
        assert_eq!(
            serde_json::to_value(v).unwrap(),
            serde_json::Value::from(v.as_str())
        );
    }
    assert_eq!(
        [Verdict::Pass, Verdict::Conditional, Verdict::Fail].map(Verdict::as_str),
        ["pass", "conditional", "fail"]
    );
}

/// A previous calibration whose scale factor is zero or not finite cannot
/// refer errors to the input: no as found.
#[test]
fn as_found_needs_a_usable_previous_scale_factor() {
    let positions = tumble(Mount::Pendulum, 4);
    let t = test_of(&linear(), &Model::pendulum(), positions);
    for ki in [0.0, f64::NAN, f64::INFINITY] {
        let before = TermMap(vec![(K0, -5.0e-4), (Ki, ki), (Kp, 6.0e-3)]);
        assert!(as_found(&t, &before).is_none(), "ki = {ki}");
    }
}

/// The year the drift is per, and the arcsecond the stand is given in.
#[test]
fn units_are_what_they_say() {
    assert_eq!(accelcal_core::history::SECONDS_PER_YEAR, 31_557_600.0);
    // π / 648 000, to 15 digits.
    near(ARCSEC, 4.848_136_811_095_36e-6, 1e-14);
}

/// Both ways out of the limits count, and a steady history has none: its
/// moving range is 0, so its limits coincide with every point — which is on
/// them, not outside.
#[test]
fn control_limits_are_two_sided_and_exclusive() {
    let mut pts: Vec<Point> = (0..12)
        .map(|k| {
            point(
                &format!("p{k}"),
                k as f64,
                1.0 + 0.001 * (k % 2) as f64,
                0.001,
            )
        })
        .collect();
    pts.push(point("drop", 12.0, 0.9, 0.001));
    assert_eq!(stability(&pts, 2.0)[K0].control.out_of_control, ["drop"]);
    let steady: Vec<Point> = (0..5)
        .map(|k| point(&format!("s{k}"), k as f64, 0.25, 0.001))
        .collect();
    let s = stability(&steady, 2.0);
    assert_eq!(s[K0].control.moving_range_mean, Some(0.0));
    assert_eq!(
        (s[K0].control.lower, s[K0].control.upper),
        (Some(0.25), Some(0.25))
    );
    assert!(s[K0].control.out_of_control.is_empty());
}

/// t = 0, 1, 2, 4, 5 and x = 1, 3, 2, 6, 5 by hand (exact fractions):
/// t̄ = 12/5, x̄ = 17/5, Σ(t − t̄)² = 86/5, slope 38/43, RSS 162/43,
/// SE(b) = √(RSS/3)/√(86/5). The latest change is x₅ − x₄ = −1 with
/// U = 2·√(0.3² + 0.4²) = 1 (the fourth and fifth points' standard errors).
#[test]
fn five_calibrations_by_hand() {
    let pts = [
        point("a", 0.0, 1.0, 0.9),
        point("b", 1.0, 3.0, 0.9),
        point("c", 2.0, 2.0, 0.9),
        point("d", 4.0, 6.0, 0.4),
        point("e", 5.0, 5.0, 0.3),
    ];
    let s = &stability(&pts, 2.0)[K0];
    near(s.mean, 3.4, 1e-15);
    near(s.drift_per_year.unwrap(), 38.0 / 43.0, 1e-14);
    let se = (162.0 / 43.0 / 3.0f64).sqrt() / (86.0f64 / 5.0).sqrt();
    near(s.drift_std_error.unwrap(), se, 1e-14);
    near(s.drift_t.unwrap(), 38.0 / 43.0 / se, 1e-13);
    assert_eq!(s.latest_change, Some(-1.0));
    near(s.latest_change_expanded.unwrap(), 1.0, 1e-15);
    // With U exactly representable: k = 1, se 3 and 4 give U = 5; a change of
    // exactly 5 is not beyond it, a change a hair larger is.
    let exact = |last: f64| {
        let p = [point("x", 0.0, 0.0, 4.0), point("y", 1.0, last, 3.0)];
        stability(&p, 1.0)[K0].latest_change_significant
    };
    assert_eq!(exact(5.0), Some(false));
    assert_eq!(exact(-5.0), Some(false));
    assert_eq!(exact(5.000_001), Some(true));
    assert_eq!(exact(-5.000_001), Some(true));
}

/// Five temperatures, by hand (exact fractions): T = 10, 15, 20, 30, 40 °C and
/// k0 = 10, 14, 21, 29, 42: T̄ = 23, x̄ = 116/5, Σ(T − T̄)² = 580, slope
/// 153/145 per K, RSS 146/29, SE = √(RSS/3)/√580.
#[test]
fn five_temperatures_by_hand() {
    let positions = tumble(Mount::Pendulum, 4);
    let design = Design::new(
        &Model::new(vec![K0, Ki]).unwrap(),
        &positions.iter().map(|p| p.a).collect::<Vec<_>>(),
    )
    .unwrap();
    let runs: Vec<accelcal_core::Identification> = [10.0, 14.0, 21.0, 29.0, 42.0]
        .iter()
        .map(|k0| design.solve(&[*k0, k0 - 1.0, *k0, k0 + 1.0]))
        .collect();
    let s = sensitivity(&runs, &[10.0, 15.0, 20.0, 30.0, 40.0]).unwrap();
    near(s[K0].per_kelvin, 153.0 / 145.0, 1e-13);
    near(
        s[K0].std_error.unwrap(),
        (146.0 / 29.0 / 3.0f64).sqrt() / 580f64.sqrt(),
        1e-12,
    );
    near(s[K0].reference_c, 23.0, 1e-15);
    near(s[K0].value_at_reference, 116.0 / 5.0, 1e-14);
}

/// `da/dθ` is the derivative of the mount's gravity, at any angle.
#[test]
fn the_mount_derivative_is_the_derivative() {
    let h: f64 = 1e-6;
    for mount in [Mount::Pendulum, Mount::Gate] {
        for deg in [0.0, 17.0, 45.0, 123.4, 200.0, 271.5, 333.3] {
            let d = mount.derivative(deg).to_array();
            let (up, down) = (
                mount.gravity(deg + h.to_degrees()).to_array(),
                mount.gravity(deg - h.to_degrees()).to_array(),
            );
            for k in 0..3 {
                let fd = (up[k] - down[k]) / (2.0 * h);
                assert!(
                    (d[k] - fd).abs() < 1e-8,
                    "{mount:?} {deg}° component {k}: {} vs {fd}",
                    d[k]
                );
            }
        }
    }
}

/// The budget against finite differences on irregular schedules — no
/// mirror symmetry to hide a sign — for both mounts, with terms that vary
/// along the output axis on the gate mount.
#[test]
fn budget_equals_finite_differences_on_irregular_schedules() {
    let angles = [
        3.0, 17.0, 41.0, 97.0, 130.0, 160.0, 178.0, 222.0, 251.0, 299.0, 333.0, 350.0,
    ];
    let cases = [
        (
            Mount::Pendulum,
            TermMap(vec![
                (K0, -8.4e-4),
                (Ki, -1.216),
                (Kp, 6.2e-3),
                (Kpi, -4.4e-4),
                (Kii, 1.3e-4),
                (Kiii, -6.0e-5),
            ]),
        ),
        (
            Mount::Gate,
            TermMap(vec![
                (K0, 5.1e-4),
                (Ki, 1.19),
                (Ko, -3.3e-3),
                (Kio, 2.7e-4),
                (Kii, -1.1e-4),
                (Kiii, 4.0e-5),
            ]),
        ),
    ];
    for (mount, truth) in cases {
        let model = Model::new(truth.iter().map(|(t, _)| t).collect()).unwrap();
        let positions: Vec<Position> = angles
            .iter()
            .map(|d| Position::from_angle(*d, mount, None))
            .collect();
        let t = test_of(&truth, &model, positions.clone());
        let zero = TermMap(truth.iter().map(|(t, _)| (t, 0.0)).collect());
        let (sigma, u) = (3.0 * ARCSEC, 1e-5);
        let stand = Stand {
            angle_std_rad: sigma,
            gravity_rel_std: u,
            ..Stand::default()
        };
        let b = budget(
            &t,
            &truth,
            (&zero, &TermMap(vec![])),
            stand,
            Coverage::Factor(2.0),
            &TermMap(vec![]),
        )
        .unwrap();
        let nominal: Vec<Gravity> = positions.iter().map(|p| p.a).collect();
        let design = Design::new(&model, &nominal).unwrap();
        let c = Compensator::new(&truth).unwrap();
        let fit = |y: &[f64]| design.solve(y).coefficients;
        let base: Vec<f64> = nominal.iter().map(|a| c.output(a)).collect();
        let k0 = fit(&base);
        let eps: f64 = 1e-6;
        let mut squares = vec![0.0; model.len()];
        for (j, deg) in angles.iter().enumerate() {
            let mut y = base.clone();
            y[j] = c.output(&mount.gravity(deg + eps.to_degrees()));
            let k1 = fit(&y);
            for (m, (term, v)) in k1.iter().enumerate() {
                squares[m] += ((v - k0[term]) / eps).powi(2);
            }
        }
        let scaled: Vec<f64> = nominal
            .iter()
            .map(|a| c.output(&Gravity::from(a.to_array().map(|x| x * (1.0 + eps)))))
            .collect();
        let kg = fit(&scaled);
        let floor = 1e-9 * sigma.max(u);
        for (m, term) in model.terms().iter().enumerate() {
            let idx = sigma * squares[m].sqrt();
            let grav = u * ((kg[*term] - k0[*term]) / eps).abs();
            let (got_i, got_g) = (b.terms[*term].indexing, b.terms[*term].gravity);
            assert!(
                (got_i - idx).abs() <= 1e-5 * idx + floor,
                "{mount:?} {term} indexing {got_i:e} vs {idx:e}"
            );
            assert!(
                (got_g - grav).abs() <= 1e-5 * grav + floor,
                "{mount:?} {term} gravity {got_g:e} vs {grav:e}"
            );
        }
    }
}
