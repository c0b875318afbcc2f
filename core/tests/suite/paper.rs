//! The paper's figures (NOTES §5), reproduced to the printed digits.

use accelcal_core::{Term, TermMap, estimate};
use accelcal_paper::{assert_printed, paper_tumble, table2};

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
    assert_printed(
        g(e.mean.dispersion.as_ref().unwrap(), Term::K0),
        "1.9747e-5",
    );
    assert_printed(
        rel(e.mean.relative_dispersion.as_ref().unwrap(), Term::Ki),
        "5.3216e-5",
    );
    assert_printed(
        g(e.mean.dispersion.as_ref().unwrap(), Term::Kp),
        "8.6799e-5",
    );
    // eq. 8 about the fused value (not the paper's σ_rk0, σ_rk1: see NOTES §5)
    assert_printed(
        g(e.fused.dispersion.as_ref().unwrap(), Term::K0),
        "2.0257e-5",
    );
    assert_printed(
        rel(e.fused.relative_dispersion.as_ref().unwrap(), Term::Ki),
        "5.3233e-5",
    );
    assert_printed(
        g(e.fused.dispersion.as_ref().unwrap(), Term::Kp),
        "1.1092e-4",
    );

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

/// The printed-digits check is strict: exactly one unit of the last printed
/// digit away fails, in plain and exponent notation, either side.
#[test]
fn printed_digit_check_fails_one_unit_off() {
    for (value, printed) in [
        (-1.216_146_403_6, "-1.2161464035"),
        (-1.216_146_403_4, "-1.2161464035"),
        (-0.844_926_7e-3, "-0.8449266e-3"),
        (5.574_6e-6, "5.5745e-6"),
        (5.574_4e-6, "5.5745e-6"),
    ] {
        let caught = std::panic::catch_unwind(|| assert_printed(value, printed));
        assert!(caught.is_err(), "{value:e} passed as {printed}");
    }
}

/// ... and just under half a unit away passes.
#[test]
fn printed_digit_check_passes_under_half_a_unit() {
    assert_printed(-1.216_146_403_5 + 0.49e-10, "-1.2161464035");
    assert_printed(-1.216_146_403_5 - 0.49e-10, "-1.2161464035");
    assert_printed(5.5745e-6 + 0.49e-10, "5.5745e-6");
    assert_printed(-0.844_926_6e-3 - 0.49e-10, "-0.8449266e-3");
}

/// Every figure accelcal computes from Table 1 — per-run coefficients,
/// standard errors, residuals, mean, fused values, standard errors, eq. 8
/// about both, batches, normalised values — against an independent
/// computation (`data/reference.py`: closed forms in 50-digit decimals).
#[test]
fn table_1_figures_match_an_independent_computation() {
    let r: serde_json::Value =
        serde_json::from_str(include_str!("../data/reference.json")).unwrap();
    let t1 = &r["table1"];
    let cal = paper_tumble().calibrate(2).unwrap();
    let terms = [Term::K0, Term::Ki, Term::Kp];
    for (j, run) in cal.runs.iter().enumerate() {
        let want = &t1["runs"][j];
        for t in terms {
            close(
                *run.coefficients.get(t).unwrap(),
                &want["coefficients"][t.name()],
                1e-12,
            );
            let se = run.std_errors.as_ref().unwrap();
            close(*se.get(t).unwrap(), &want["std_errors"][t.name()], 1e-9);
        }
        for (k, e) in run.residuals.iter().enumerate() {
            close(*e, &want["residuals"][k], 1e-9);
        }
        close(run.residual_rms, &want["residual_rms"], 1e-9);
        assert_eq!(run.dof, 1);
    }
    for t in terms {
        let n = t.name();
        close(
            *cal.mean.coefficients.get(t).unwrap(),
            &t1["mean"][n],
            1e-12,
        );
        close(
            *cal.mean.dispersion.as_ref().unwrap().get(t).unwrap(),
            &t1["mean_dispersion"][n],
            1e-9,
        );
        close(
            cal.mean
                .relative_dispersion
                .as_ref()
                .unwrap()
                .get(t)
                .unwrap()
                .unwrap(),
            &t1["mean_relative_dispersion"][n],
            1e-9,
        );
        close(
            *cal.fused.coefficients.get(t).unwrap(),
            &t1["fused"][n],
            1e-12,
        );
        close(
            *cal.fused.std_errors.get(t).unwrap(),
            &t1["fused_std_error"][n],
            1e-9,
        );
        close(
            *cal.fused.dispersion.as_ref().unwrap().get(t).unwrap(),
            &t1["fused_dispersion"][n],
            1e-9,
        );
        close(
            cal.fused
                .relative_dispersion
                .as_ref()
                .unwrap()
                .get(t)
                .unwrap()
                .unwrap(),
            &t1["fused_relative_dispersion"][n],
            1e-9,
        );
        for (p, b) in cal.fused.batches.iter().enumerate() {
            close(*b.mean.get(t).unwrap(), &t1["batch_mean"][n][p], 1e-12);
            close(*b.std.get(t).unwrap(), &t1["batch_std"][n][p], 1e-9);
        }
    }
    close(
        cal.normalized.bias_g.unwrap(),
        &t1["normalized"]["bias_g"],
        1e-12,
    );
    close(
        cal.normalized.misalignment_p_rad.unwrap(),
        &t1["normalized"]["misalignment_p_rad"],
        1e-12,
    );
    // The figure the issue singled out: Table 1's own fused SE of α is
    // 6.3637e-6, not Table 2's 6.3639e-6.
    assert_printed(*cal.fused.std_errors.get(Term::Kp).unwrap(), "6.3637e-6");
}

/// Table 2's fusion beyond the printed digits, against the same independent
/// computation.
#[test]
fn table_2_fusion_matches_an_independent_computation() {
    let r: serde_json::Value =
        serde_json::from_str(include_str!("../data/reference.json")).unwrap();
    let t2 = &r["table2"];
    let e = table2_estimates(2);
    for t in [Term::K0, Term::Ki, Term::Kp] {
        let n = t.name();
        close(*e.mean.coefficients.get(t).unwrap(), &t2["mean"][n], 1e-12);
        close(
            *e.mean.dispersion.as_ref().unwrap().get(t).unwrap(),
            &t2["mean_dispersion"][n],
            1e-9,
        );
        close(
            *e.fused.coefficients.get(t).unwrap(),
            &t2["fused"][n],
            1e-12,
        );
        close(
            *e.fused.std_errors.get(t).unwrap(),
            &t2["fused_std_error"][n],
            1e-9,
        );
        close(
            *e.fused.dispersion.as_ref().unwrap().get(t).unwrap(),
            &t2["fused_dispersion"][n],
            1e-9,
        );
        close(
            e.fused
                .relative_dispersion
                .as_ref()
                .unwrap()
                .get(t)
                .unwrap()
                .unwrap(),
            &t2["fused_relative_dispersion"][n],
            1e-9,
        );
    }
}

/// `got` within `relative` of the reference value.
#[track_caller]
fn close(got: f64, want: &serde_json::Value, relative: f64) {
    let want = want
        .as_f64()
        .unwrap_or_else(|| panic!("no reference value: {want}"));
    assert!(
        (got - want).abs() <= relative * want.abs(),
        "{got:e} vs reference {want:e} (relative {relative:e})"
    );
}

/// Each of the paper's runs submitted alone is its own estimate: the
/// coefficients and standard errors of the independent closed form for that
/// run, no batches and no eq. 8, and a note saying so. A run that fits
/// exactly (as many positions as terms) has no standard errors to give and
/// is refused, naming both counts.
#[test]
fn a_single_run_is_its_own_estimate() {
    let r: serde_json::Value =
        serde_json::from_str(include_str!("../data/reference.json")).unwrap();
    let paper = paper_tumble();
    for (j, run) in paper.runs().iter().enumerate() {
        let one = accelcal_core::TumbleTest::new(
            paper.model().clone(),
            paper.positions().to_vec(),
            vec![run.clone()],
        )
        .unwrap();
        let cal = one.calibrate(2).unwrap();
        let want = &r["table1"]["runs"][j];
        for t in [Term::K0, Term::Ki, Term::Kp] {
            close(
                cal.fused.coefficients[t],
                &want["coefficients"][t.name()],
                1e-12,
            );
            close(
                cal.mean.coefficients[t],
                &want["coefficients"][t.name()],
                1e-12,
            );
            close(cal.fused.std_errors[t], &want["std_errors"][t.name()], 1e-9);
        }
        assert!(cal.fused.batches.is_empty());
        assert!(cal.fused.dispersion.is_none() && cal.mean.dispersion.is_none());
        assert!(cal.fused.relative_dispersion.is_none() && cal.mean.relative_dispersion.is_none());
        assert_eq!(cal.fused.note, Some(accelcal_core::estimate::SINGLE_RUN));
    }
    let exact = accelcal_core::TumbleTest::new(
        accelcal_core::Model::new(vec![Term::K0, Term::Ki, Term::Kp, Term::Kii]).unwrap(),
        paper.positions().to_vec(),
        vec![paper.runs()[0].clone()],
    )
    .unwrap();
    assert_eq!(
        exact.calibrate(1).unwrap_err(),
        accelcal_core::Error::SingleRunWithoutDof {
            positions: 4,
            terms: 4
        }
    );
    // Two runs or more are fused as before: the note is absent.
    assert_eq!(paper.calibrate(2).unwrap().fused.note, None);
}
