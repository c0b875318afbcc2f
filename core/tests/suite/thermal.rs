//! Coefficients over temperature (issue 45) against numpy and scipy
//! (`core/tests/data/thermal.py`, not accelcal's code): each case's
//! weighted polynomial, its Birge-inflated covariance, the degree each
//! selection rule picks with its partial F tests, the value, standard
//! uncertainty and slope at a temperature, and the design's condition
//! number; and the selection's false-alarm rate on a true line.

use accelcal_core::thermal::{Options, Point, Selection, condition, fit};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use serde_json::Value;

fn reference() -> Value {
    serde_json::from_str(include_str!("../data/thermal.json")).unwrap()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(f).collect()
}

/// `got` within `rel` of `want` (relative to the larger of |want| and `floor`).
fn close(got: f64, want: f64, rel: f64, floor: f64, what: &str) {
    assert!(
        (got - want).abs() <= rel * want.abs().max(floor),
        "{what}: {got} vs numpy's {want}"
    );
}

#[test]
fn every_case_agrees_with_numpy() {
    for c in reference()["cases"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let (t, v, u) = (
            floats(&c["temperatures_c"]),
            floats(&c["values"]),
            floats(&c["std_uncertainties"]),
        );
        let points: Vec<Point> = (0..t.len())
            .map(|s| Point {
                temperature_c: t[s],
                value: v[s],
                std_uncertainty: u[s],
            })
            .collect();
        let degree = c["degree"].as_u64().unwrap() as usize;
        let options = Options {
            degree: c["fixed"].as_bool().unwrap().then_some(degree),
            ..Options::default()
        };
        let p = fit(&points, &options).unwrap();
        assert_eq!(p.degree, degree, "{name}: degree");
        assert_eq!(p.reference_c, f(&c["reference_c"]), "{name}: T_ref");
        assert_eq!(p.dof, c["dof"].as_u64().unwrap() as usize, "{name}: ν");
        close(p.chi2, f(&c["chi2"]), 1e-6, 1e-9, &format!("{name}: χ²"));
        let want = floats(&c["coefficients"]);
        let cov = c["covariance"].as_array().unwrap();
        for d in 0..=degree {
            let scale = cov[d][d].as_f64().unwrap().sqrt();
            // Each a_d to a millionth of its standard uncertainty.
            assert!(
                (p.coefficients[d] - want[d]).abs() <= 1e-6 * scale,
                "{name}: a_{d} = {} vs numpy's {}",
                p.coefficients[d],
                want[d]
            );
            // Each covariance to 1e-7 of √(C_dd C_ee) (an element zero by
            // symmetry is numpy's rounding error, 1e-28, here 0).
            for e in 0..=degree {
                let scale = (f(&cov[d][d]) * f(&cov[e][e])).sqrt();
                assert!(
                    (p.covariance[d][e] - f(&cov[d][e])).abs() <= 1e-7 * scale,
                    "{name}: C[{d}][{e}] = {} vs numpy's {}",
                    p.covariance[d][e],
                    f(&cov[d][e])
                );
            }
        }
        let tests = c["tests"].as_array().unwrap();
        assert_eq!(p.selection.len(), tests.len(), "{name}: tests made");
        for (got, want) in p.selection.iter().zip(tests) {
            assert_eq!(got.df2, want["df2"].as_u64().unwrap() as usize, "{name}");
            close(got.f, f(&want["f"]), 1e-6, 1e-9, &format!("{name}: F"));
            close(
                got.p_value,
                f(&want["p_value"]),
                1e-6,
                1e-12,
                &format!("{name}: p"),
            );
        }
        let at = f(&c["at_c"]);
        let (value, std) = p.at(at);
        let su = f(&c["std_uncertainty_at"]);
        assert!(
            (value - f(&c["value_at"])).abs() <= 1e-6 * su,
            "{name}: c(T)"
        );
        close(std, su, 1e-7, 0.0, &format!("{name}: u(T)"));
        close(
            p.slope(at),
            f(&c["slope_at"]),
            1e-6,
            1e-9,
            &format!("{name}: slope"),
        );
        close(
            condition(&t, p.reference_c, degree),
            f(&c["condition"]),
            1e-9,
            1.0,
            &format!("{name}: condition"),
        );
        // The forward selection, where numpy ran it.
        if let Some(fw) = c["forward"].as_object() {
            let up = fit(
                &points,
                &Options {
                    selection: Selection::Forward,
                    ..Options::default()
                },
            )
            .unwrap();
            assert_eq!(
                up.degree as u64,
                fw["degree"].as_u64().unwrap(),
                "{name}: forward"
            );
            let want = fw["tests"].as_array().unwrap();
            assert_eq!(up.selection.len(), want.len(), "{name}: forward tests");
            for (got, want) in up.selection.iter().zip(want) {
                close(
                    got.p_value,
                    f(&want["p_value"]),
                    1e-6,
                    1e-12,
                    &format!("{name}: forward p"),
                );
            }
        }
    }
}

/// 2 000 lines (bias 0.5, slope 1e-4 per K) at the five chamber set points,
/// each point's noise at its stated u. Backward elimination makes two tests
/// above the line (the cubic's, the quadratic's), each at 1 %, so it keeps a
/// spurious degree with probability 1 − 0.99² ≈ 2 % (the count binomial:
/// 40 expected, outside 18…66 about once in 10⁴ runs); forward selection
/// makes one, 1 % (20 expected, outside 5…40 about as rarely). Neither ever
/// loses the line, 100 u over the range.
#[test]
fn false_alarms_of_the_degree_selection_on_a_true_line() {
    let mut rng = StdRng::seed_from_u64(45);
    let chamber = [-20.0, 0.0, 20.0, 40.0, 60.0];
    let u = [4e-5, 3e-5, 2e-5, 3e-5, 5e-5];
    let mut counts = [[0usize; 2]; 2];
    for _ in 0..2_000 {
        let points: Vec<Point> = chamber
            .iter()
            .zip(u)
            .map(|(&t, u)| {
                let e: f64 = StandardNormal.sample(&mut rng);
                Point {
                    temperature_c: t,
                    value: 0.5 + 1e-4 * (t - 20.0) + u * e,
                    std_uncertainty: u,
                }
            })
            .collect();
        for (k, selection) in [Selection::Backward, Selection::Forward]
            .into_iter()
            .enumerate()
        {
            let options = Options {
                selection,
                ..Options::default()
            };
            let d = fit(&points, &options).unwrap().degree;
            counts[k][0] += usize::from(d > 1);
            counts[k][1] += usize::from(d < 1);
        }
    }
    println!(
        "a true line, 2 000 times: backward above degree 1 in {}, forward in {}; below in {} and {}",
        counts[0][0], counts[1][0], counts[0][1], counts[1][1]
    );
    assert_eq!(
        (counts[0][1], counts[1][1]),
        (0, 0),
        "the line is never lost"
    );
    assert!(
        (18..=66).contains(&counts[0][0]),
        "backward: {}",
        counts[0][0]
    );
    assert!(
        (5..=40).contains(&counts[1][0]),
        "forward: {}",
        counts[1][0]
    );
}
