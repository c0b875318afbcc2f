//! The paper's figures (NOTES §5), reproduced to the printed digits.

mod common;

use accelcal_core::{Term, TermMap, estimate};
use common::{assert_printed, paper_tumble, table2};

/// α per run from Table 1 equals Table 2's α column within 1e-9.
#[test]
fn alpha_per_run_from_table_1() {
    let runs = paper_tumble().identify_runs();
    let printed = table2();
    assert_eq!(runs.len(), 6);
    for (j, run) in runs.iter().enumerate() {
        let alpha = *run.coefficients.get(Term::Kp).unwrap();
        assert!(
            (alpha - printed[j][2]).abs() < 1e-9,
            "test {}: α = {alpha} vs printed {}",
            j + 1,
            printed[j][2]
        );
    }
    // Test 4 unrounded: the paper rounded the position means before solving.
    let alpha4 = *runs[3].coefficients.get(Term::Kp).unwrap();
    assert!((alpha4 - 0.006_287_308_25).abs() < 1e-14, "{alpha4}");
}

/// Table 1 gives K1 ≈ −1.2161608 for test 1, not Table 2's −1.216171962
/// (NOTES §5): K0 and K1 of Table 2 come from data the paper does not print.
#[test]
fn k1_of_table_1_differs_from_table_2() {
    let runs = paper_tumble().identify_runs();
    let k1 = *runs[0].coefficients.get(Term::Ki).unwrap();
    assert_printed(k1, "-1.2161608");
    assert!((k1 - table2()[0][1]).abs() > 1e-5);
}

fn table2_estimates(batches: usize) -> accelcal_core::Estimates {
    let t = table2();
    let col = |k: usize| t.iter().map(|r| r[k]).collect::<Vec<_>>();
    let values = TermMap(vec![
        (Term::K0, col(0)),
        (Term::Ki, col(1)),
        (Term::Kp, col(2)),
    ]);
    estimate(&values, batches).unwrap()
}

/// NOTES §5: Table 2's per-run values fused in 2 batches of 3.
#[test]
fn table_2_fusion() {
    let e = table2_estimates(2);
    let g = |m: &TermMap<f64>, t| *m.get(t).unwrap();
    let rel = |m: &TermMap<Option<f64>>, t| m.get(t).unwrap().unwrap();

    // mean (eq. 1)
    assert_printed(g(&e.mean.coefficients, Term::K0), "-0.84905e-3");
    assert_printed(g(&e.mean.coefficients, Term::Ki), "-1.2161464035");
    assert_printed(g(&e.mean.coefficients, Term::Kp), "0.0062108047");
    // fused (eq. 7)
    assert_printed(g(&e.fused.coefficients, Term::K0), "-0.8449266e-3");
    assert_printed(g(&e.fused.coefficients, Term::Ki), "-1.2161479119");
    assert_printed(g(&e.fused.coefficients, Term::Kp), "0.0062738448");
    // fused standard error 1/sqrt(Σw)
    assert_printed(g(&e.fused.std_errors, Term::K0), "5.5745e-6");
    assert_printed(g(&e.fused.std_errors, Term::Ki), "2.8651e-5");
    assert_printed(g(&e.fused.std_errors, Term::Kp), "6.3639e-6");
    // eq. 8 about the mean: the paper's σ_pk0 and σ_pk1 (relative)
    assert_printed(g(&e.mean.dispersion, Term::K0), "1.9747e-5");
    assert_printed(rel(&e.mean.relative_dispersion, Term::Ki), "5.3216e-5");
    assert_printed(g(&e.mean.dispersion, Term::Kp), "8.6799e-5");
    // eq. 8 about the fused value (not the paper's σ_rk0, σ_rk1: see NOTES §5)
    assert_printed(g(&e.fused.dispersion, Term::K0), "2.0257e-5");
    assert_printed(rel(&e.fused.relative_dispersion, Term::Ki), "5.3233e-5");
    assert_printed(g(&e.fused.dispersion, Term::Kp), "1.1092e-4");

    // The batches: runs 0–2 and 3–5.
    assert_eq!(e.fused.batches.len(), 2);
    assert_eq!(e.fused.batches[0].runs, vec![0, 1, 2]);
    assert_eq!(e.fused.batches[1].runs, vec![3, 4, 5]);
}

/// The same fusion from the identified Table 1 runs reproduces α's column.
#[test]
fn table_1_calibration_fuses_alpha_like_table_2() {
    let cal = paper_tumble().calibrate(2).unwrap();
    let alpha = *cal.fused.coefficients.get(Term::Kp).unwrap();
    let mean = *cal.mean.coefficients.get(Term::Kp).unwrap();
    assert!((alpha - 0.006_273_844_8).abs() < 1e-9, "{alpha}");
    assert!((mean - 0.006_210_804_7).abs() < 1e-9, "{mean}");
    assert!(cal.condition_number > 1.414 && cal.condition_number < 1.415);
    let n = cal.normalized;
    assert!(
        (n.misalignment_p_rad.unwrap() - alpha / cal.fused.coefficients.get(Term::Ki).unwrap())
            .abs()
            < 1e-18
    );
}

/// For k = 2 the paper's closed form Πσ²/Σσ² equals 1/Σw; for k = 3 it does
/// not, and accelcal's fused variance is the general 1/Σw.
#[test]
fn fused_variance_is_one_over_sum_of_weights_for_three_batches() {
    let t = table2();
    let k1: Vec<f64> = t.iter().map(|r| r[1]).collect();
    for (k, paper_agrees) in [(2, true), (3, false)] {
        let f = accelcal_core::fusion::fuse(&k1, k).unwrap();
        // variance of each batch mean: σ_p² = s_p² / n_p
        let var: Vec<f64> = f
            .batches
            .iter()
            .map(|b| b.std * b.std / b.runs.len() as f64)
            .collect();
        let general = 1.0 / var.iter().map(|v| 1.0 / v).sum::<f64>();
        let paper = var.iter().product::<f64>() / var.iter().sum::<f64>();
        let fused = f.std_error * f.std_error;
        assert!((fused - general).abs() <= 1e-12 * general, "k = {k}");
        assert_eq!(
            (fused - paper).abs() <= 1e-12 * general,
            paper_agrees,
            "k = {k}: fused {fused:e}, paper's closed form {paper:e}"
        );
    }
}

/// The printed-digits check is strict: one unit off in the last digit fails.
#[test]
#[should_panic(expected = "does not round to the printed")]
fn printed_digit_check_can_fail() {
    assert_printed(-1.216_146_404_5, "-1.2161464035");
    assert_printed(-1.216_146_413_5, "-1.2161464035");
}
