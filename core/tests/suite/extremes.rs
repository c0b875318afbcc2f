//! Outputs of any magnitude: fusion and identification are scale-free, so
//! scaling every value by `c` scales every result by `c` (or `|c|`), from
//! 1e-160 to 1e150, instead of overflowing to infinity or underflowing to
//! zero (hardening round two, finding 5). Expected values are derived by hand
//! from the definitions, not taken from the code.

use accelcal_core::fusion::{dispersion, fuse, scaled_norm};
use accelcal_core::{Reading, Run, Summary, Term, TermMap, TumbleTest, estimate};
use accelcal_paper::paper_tumble;

#[track_caller]
fn rel(got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol * want.abs(),
        "{got:e} vs {want:e} (relative {tol:e})"
    );
}

/// `[0, 2e-160, 0, 2e-160]` in two batches: each batch has mean 1e-160 and
/// s = √2·1e-160, so w = 2/s² = 1e320 each (beyond f64), x⁺ = 1e-160 and
/// SE = 1/√(2e320) = 1e-160/√2.
#[test]
fn tiny_values_fuse_instead_of_overflowing() {
    let f = fuse(&[0.0, 2e-160, 0.0, 2e-160], 2).unwrap();
    rel(f.value, 1e-160, 1e-15);
    rel(f.std_error, 1e-160 / 2f64.sqrt(), 1e-15);
    rel(f.batches[0].std, 2f64.sqrt() * 1e-160, 1e-15);
}

/// `[1, 2, 3, 4]·1e-300`: deviations square to 1e-601, below the smallest
/// double; each batch still has s = 1e-300/√2, x⁺ = 2.5e-300 and
/// SE = 1/√(2·4e600) = 1e-300/√8.
#[test]
fn tiny_distinct_values_are_not_called_identical() {
    let f = fuse(&[1e-300, 2e-300, 3e-300, 4e-300], 2).unwrap();
    rel(f.value, 2.5e-300, 1e-15);
    rel(f.std_error, 1e-300 / 8f64.sqrt(), 1e-15);
    let d = dispersion(&[1e-300, 2e-300, 3e-300, 4e-300], 2.5e-300).unwrap();
    // Σ(K − K_j)² = (2.25 + 0.25 + 0.25 + 2.25)·1e-600 = 5e-600; /3, root.
    rel(d.absolute, (5.0f64 / 3.0).sqrt() * 1e-300, 1e-15);
    rel(d.relative.unwrap(), (5.0f64 / 3.0).sqrt() / 2.5, 1e-15);
}

#[test]
fn scaled_norm_neither_underflows_nor_overflows() {
    rel(scaled_norm([3e-200, 4e-200].into_iter()), 5e-200, 1e-15);
    rel(scaled_norm([3e200, 4e200].into_iter()), 5e200, 1e-15);
    assert_eq!(scaled_norm([0.0, 0.0].into_iter()), 0.0);
    assert_eq!(scaled_norm(std::iter::empty()), 0.0);
}

fn scaled(test: &TumbleTest, c: f64) -> TumbleTest {
    let runs = test
        .runs()
        .iter()
        .map(|r| Run {
            readings: r
                .readings
                .iter()
                .map(|reading| match reading {
                    Reading::Samples(s) => Reading::Samples(s.iter().map(|u| u * c).collect()),
                    Reading::Summary(s) => Reading::Summary(Summary {
                        mean: s.mean * c,
                        std: s.std * c.abs(),
                        count: s.count,
                    }),
                })
                .collect(),
        })
        .collect();
    TumbleTest::new(test.model().clone(), test.positions().to_vec(), runs).unwrap()
}

/// The paper's tumble with every reading multiplied by c: coefficients,
/// per-run and fused standard errors, dispersions and residuals all scale by
/// c (|c| for the non-negative ones); relative dispersions do not change.
#[test]
fn calibration_scales_with_the_outputs() {
    let base = paper_tumble().calibrate(2).unwrap();
    for c in [1e-152, 1e-160, -1e-120, 1e-9, 1e120, -1e150] {
        let cal = scaled(&paper_tumble(), c).calibrate(2).unwrap();
        let tol = 1e-9;
        for t in [Term::K0, Term::Ki, Term::Kp] {
            let g = |m: &TermMap<f64>| *m.get(t).unwrap();
            rel(
                g(&cal.fused.coefficients),
                c * g(&base.fused.coefficients),
                tol,
            );
            rel(
                g(&cal.fused.std_errors),
                c.abs() * g(&base.fused.std_errors),
                tol,
            );
            rel(
                g(cal.mean.dispersion.as_ref().unwrap()),
                c.abs() * g(base.mean.dispersion.as_ref().unwrap()),
                tol,
            );
            rel(
                g(cal.fused.dispersion.as_ref().unwrap()),
                c.abs() * g(base.fused.dispersion.as_ref().unwrap()),
                tol,
            );
            rel(
                cal.fused
                    .relative_dispersion
                    .as_ref()
                    .unwrap()
                    .get(t)
                    .unwrap()
                    .unwrap(),
                base.fused
                    .relative_dispersion
                    .as_ref()
                    .unwrap()
                    .get(t)
                    .unwrap()
                    .unwrap(),
                tol,
            );
            for (run, b) in cal.runs.iter().zip(&base.runs) {
                rel(g(&run.coefficients), c * g(&b.coefficients), tol);
                let (se, bse) = (
                    run.std_errors.as_ref().unwrap(),
                    b.std_errors.as_ref().unwrap(),
                );
                rel(g(se), c.abs() * g(bse), tol);
            }
        }
        for (run, b) in cal.runs.iter().zip(&base.runs) {
            rel(run.residual_rms, c.abs() * b.residual_rms, tol);
        }
    }
}

/// Fusing given values is scale-free too (`POST /v1/fuse`).
#[test]
fn estimates_scale_with_the_values() {
    let t = accelcal_paper::table2();
    let base_values = TermMap(vec![(Term::K0, t.iter().map(|r| r[0]).collect::<Vec<_>>())]);
    let base = estimate(&base_values, 2).unwrap();
    for c in [1e-155, 1e150] {
        let values = TermMap(vec![(
            Term::K0,
            t.iter().map(|r| r[0] * c).collect::<Vec<_>>(),
        )]);
        let e = estimate(&values, 2).unwrap();
        let g = |m: &TermMap<f64>| *m.get(Term::K0).unwrap();
        rel(
            g(&e.fused.coefficients),
            c * g(&base.fused.coefficients),
            1e-12,
        );
        rel(g(&e.fused.std_errors), c * g(&base.fused.std_errors), 1e-12);
        rel(
            g(&e.mean.coefficients),
            c * g(&base.mean.coefficients),
            1e-12,
        );
    }
}
