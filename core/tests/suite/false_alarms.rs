//! The false-alarm rate of every warning on clean simulated tumbles: the
//! model is right, each sample carries independent Gaussian noise and each
//! run its own bias shift (as a real stand's runs do). 2 000 submissions on
//! two schedules; every rate is compared with the rate its test is built
//! for (the independent figure: the F distribution's, α per test), and the
//! p-values of the lack-of-fit and unmodelled-term tests are checked to be
//! uniform, as they are under a true model with the right degrees of
//! freedom. `cargo test -p accelcal-core --test suite false_alarms -- --nocapture`
//! prints the table recorded in docs/method.md.

use accelcal_core::adequacy::{LackOfFit, unmodelled_terms};
use accelcal_core::quality::{Warning, assess};
use accelcal_core::{Model, Mount, Position, Run, TumbleTest};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// Deterministic standard normal deviates (seeded).
struct Normal(StdRng);

impl Normal {
    fn seeded(seed: u64) -> Self {
        Normal(StdRng::seed_from_u64(seed))
    }

    fn next(&mut self) -> f64 {
        StandardNormal.sample(&mut self.0)
    }
}

/// One clean submission: `angles` on the pendulum mount, six runs of two
/// samples a position (cw and ccw), noise 1e-5, bias shifts of 1e-4 between
/// runs, U = −8.4e-4 − 1.216·a_i + 6.2e-3·a_p.
fn clean(rng: &mut Normal, angles: &[f64]) -> TumbleTest {
    let positions: Vec<Position> = angles
        .iter()
        .map(|d| Position::from_angle(*d, Mount::Pendulum, None))
        .collect();
    let runs = (0..6)
        .map(|_| {
            let shift = 1e-4 * rng.next();
            Run::from_samples(
                positions
                    .iter()
                    .map(|p| {
                        let u = -8.4e-4 - 1.216 * p.a.i + 6.2e-3 * p.a.p + shift;
                        (0..2).map(|_| u + 1e-5 * rng.next()).collect()
                    })
                    .collect(),
            )
        })
        .collect();
    TumbleTest::new(Model::pendulum(), positions, runs).unwrap()
}

#[derive(Default, Debug)]
struct Tally {
    submissions: usize,
    lack_of_fit: usize,
    noisy_run: usize,
    unmodelled_term: usize,
    unmodelled_tests: usize,
    implausibly_consistent: usize,
    ill_conditioned: usize,
    lof_p: Vec<f64>,
    unmodelled_p: Vec<f64>,
}

fn tally(angles: &[f64], n: usize, seed: u64) -> Tally {
    let mut rng = Normal::seeded(seed);
    let mut t = Tally::default();
    for _ in 0..n {
        let test = clean(&mut rng, angles);
        let cal = test.calibrate(2).unwrap();
        let q = assess(&test, &cal);
        t.submissions += 1;
        let has = |f: fn(&Warning) -> bool| usize::from(q.warnings.iter().any(f));
        t.lack_of_fit += has(|w| matches!(w, Warning::LackOfFit { .. }));
        t.noisy_run += has(|w| matches!(w, Warning::NoisyRun { .. }));
        t.unmodelled_term += has(|w| matches!(w, Warning::UnmodelledTerm { .. }));
        t.implausibly_consistent +=
            has(|w| matches!(w, Warning::ImplausiblyConsistentBatch { .. }));
        t.ill_conditioned += has(|w| matches!(w, Warning::IllConditioned { .. }));
        if let LackOfFit::Tested { test, .. } = q.lack_of_fit {
            t.lof_p.push(test.p_value);
        }
        let tests = unmodelled_terms(&test);
        t.unmodelled_tests = tests.len();
        t.unmodelled_p.extend(tests.iter().map(|(_, f)| f.p_value));
    }
    t
}

/// At most the nominal rate plus four binomial standard deviations.
#[track_caller]
fn at_most(count: usize, n: usize, nominal: f64, what: &str) {
    let bound = n as f64 * nominal + 4.0 * (n as f64 * nominal * (1.0 - nominal)).sqrt();
    assert!(
        count as f64 <= bound,
        "{what}: {count} of {n}, bound {bound:.1}"
    );
}

/// Uniform on (0, 1): mean 1/2 within four standard errors, and a tenth of
/// them below 0.1 within four binomial deviations, counting `independent`
/// of them as independent (a submission's tests are correlated: on a
/// pendulum tumble `kpp` is `kii` again, since a_p² = 1 − a_i²).
#[track_caller]
fn uniform(p: &[f64], independent: usize, what: &str) {
    let (n, k) = (p.len() as f64, independent as f64);
    let mean = p.iter().sum::<f64>() / n;
    assert!(
        (mean - 0.5).abs() < 4.0 / (12.0 * k).sqrt(),
        "{what}: mean p {mean}"
    );
    let low = p.iter().filter(|x| **x < 0.1).count() as f64 / n;
    assert!(
        (low - 0.1).abs() < 4.0 * (0.09 / k).sqrt(),
        "{what}: {low} below 0.1"
    );
}

#[test]
fn every_warning_keeps_its_false_alarm_rate_on_clean_tumbles() {
    let eight: Vec<f64> = (0..8).map(|k| 45.0 * f64::from(k)).collect();
    let schedules = [
        ("8 positions", eight, 2026),
        ("4 positions", vec![0.0, 90.0, 180.0, 270.0], 27),
    ];
    println!(
        "| schedule | submissions | lack_of_fit | noisy_run | unmodelled_term | implausibly_consistent_batch | ill_conditioned |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (name, angles, seed) in schedules {
        let n = 1000;
        let t = tally(&angles, n, seed);
        println!(
            "| {name} | {n} | {} | {} | {} ({} tests each) | {} | {} |",
            t.lack_of_fit,
            t.noisy_run,
            t.unmodelled_term,
            t.unmodelled_tests,
            t.implausibly_consistent,
            t.ill_conditioned
        );
        at_most(t.lack_of_fit, n, 0.001, "lack of fit");
        at_most(t.noisy_run, n, 0.01, "noisy run");
        at_most(
            t.unmodelled_term,
            n,
            0.001 * t.unmodelled_tests as f64,
            "unmodelled term",
        );
        at_most(
            t.implausibly_consistent,
            n,
            0.001,
            "implausibly consistent batch",
        );
        assert_eq!(t.ill_conditioned, 0, "{name}");
        assert_eq!(t.lof_p.len(), n, "{name}: lack of fit tested every time");
        uniform(&t.lof_p, n, &format!("{name} lack-of-fit p-values"));
        if t.unmodelled_tests > 0 {
            uniform(
                &t.unmodelled_p,
                n,
                &format!("{name} unmodelled-term p-values"),
            );
        }
    }
}

/// One submission of the paper's schedule (four positions, six runs of two
/// samples, noise 1e-5, bias shifts 1e-4) in which run 3's samples scatter
/// `k` times as much.
fn one_noisy(rng: &mut Normal, k: f64) -> TumbleTest {
    let positions: Vec<Position> = [0.0, 90.0, 180.0, 270.0]
        .iter()
        .map(|d| Position::from_angle(*d, Mount::Pendulum, None))
        .collect();
    let runs = (0..6)
        .map(|j| {
            let shift = 1e-4 * rng.next();
            let sigma = if j == 3 { k * 1e-5 } else { 1e-5 };
            Run::from_samples(
                positions
                    .iter()
                    .map(|p| {
                        let u = -8.4e-4 - 1.216 * p.a.i + 6.2e-3 * p.a.p + shift;
                        (0..2).map(|_| u + sigma * rng.next()).collect()
                    })
                    .collect(),
            )
        })
        .collect();
    TumbleTest::new(Model::pendulum(), positions, runs).unwrap()
}

/// `P(F(ν1, ν2) > c / k²)` with `c` the upper `α` point: the power of the
/// test of a run whose variance is `k²` times the others'. The pure-error
/// test has ν1 = 4 (two samples at four positions), ν2 = 20; the residual
/// test, which it replaces, ν1 = P − p = 1, ν2 = 5.
fn power(df1: f64, df2: f64, alpha: f64, k: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    let f = FisherSnedecor::new(df1, df2).unwrap();
    let c = f.inverse_cdf(1.0 - alpha);
    f.sf(c / (k * k))
}

/// `noisy_run` finds a run with k× the others' sample scatter at the rate
/// the F distribution gives for the pure-error test (within four binomial
/// deviations), and names that run; the residual test it replaces would
/// find it far less often. `-- --nocapture` prints the table in
/// docs/method.md.
#[test]
fn noisy_run_has_the_power_of_the_pure_error_test() {
    let alpha = 0.01 / 6.0;
    let n = 400;
    println!(
        "| run scatter | flagged (of {n}) | pure-error test, F(4, 20) | residual test, F(1, 5) |"
    );
    println!("|---|---|---|---|");
    for (k, seed) in [(3.0, 31), (10.0, 32), (30.0, 33)] {
        let mut rng = Normal::seeded(seed);
        let mut found = 0;
        for _ in 0..n {
            let test = one_noisy(&mut rng, k);
            let q = assess(&test, &test.calibrate(2).unwrap());
            let runs: Vec<usize> = q
                .warnings
                .iter()
                .filter_map(|w| match w {
                    Warning::NoisyRun { run, .. } => Some(*run),
                    _ => None,
                })
                .collect();
            if runs.contains(&3) {
                found += 1;
            }
        }
        let expected = power(4.0, 20.0, alpha, k);
        let residual = power(1.0, 5.0, alpha, k);
        println!(
            "| ×{k} | {found} ({:.1} %) | {:.1} % | {:.1} % |",
            100.0 * found as f64 / n as f64,
            100.0 * expected,
            100.0 * residual
        );
        let sd = (n as f64 * expected * (1.0 - expected)).sqrt();
        assert!(
            (found as f64 - n as f64 * expected).abs() <= 4.0 * sd + 1.0,
            "×{k}: {found} of {n}, expected {:.1}",
            n as f64 * expected
        );
    }
}
