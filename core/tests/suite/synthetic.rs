//! Noiseless synthetic tumbles: known coefficients are recovered to 1e-12
//! for every term each schedule can identify, and one term more is refused.

use Term::*;
use accelcal_core::{Compensator, Design, Error, Gravity, Model, Mount, Term, TermMap};

/// Coefficients of a plausible pendulous accelerometer (output in mA).
fn truth() -> TermMap<f64> {
    TermMap(vec![
        (K0, -8.4e-4),
        (Ki, -1.216),
        (Kp, 6.2e-3),
        (Ko, -3.1e-3),
        (Kio, 2.2e-4),
        (Kop, 1.7e-4),
        (Kpi, -4.4e-4),
        (Kii, 1.3e-4),
        (Kpp, -2.5e-4),
        (Koo, 0.9e-4),
        (Kiii, -6.0e-5),
    ])
}

fn tumble(mount: Mount, n: u32) -> Vec<Gravity> {
    (0..n)
        .map(|k| mount.gravity(360.0 * f64::from(k) / f64::from(n)))
        .collect()
}

/// Outputs of the model `terms` (with the true values) at each position.
fn outputs(terms: &[Term], positions: &[Gravity]) -> Vec<f64> {
    let t = truth();
    let c = Compensator::new(&TermMap(
        terms.iter().map(|k| (*k, *t.get(*k).unwrap())).collect(),
    ))
    .unwrap();
    positions.iter().map(|a| c.output(a)).collect()
}

/// Recovers every term of `terms` on `positions`, and refuses each extension
/// of `terms` by a term not in it.
fn check(name: &str, terms: &[Term], positions: &[Gravity]) {
    let model = Model::new(terms.to_vec()).unwrap();
    let design = Design::new(&model, positions).unwrap_or_else(|e| panic!("{name}: {e}"));
    let id = design.solve(&outputs(terms, positions));
    let t = truth();
    for (term, got) in id.coefficients.iter() {
        let want = t.get(term).unwrap();
        assert!(
            (got - want).abs() < 1e-12,
            "{name}: {term} = {got:e}, want {want:e}"
        );
    }
    assert!(id.residual_rms < 1e-12, "{name}: rms {}", id.residual_rms);
    if let Some(se) = &id.std_errors {
        assert!(se.iter().all(|(_, s)| *s < 1e-12), "{name}: {se:?}");
    }
    for extra in Term::ALL.iter().filter(|x| !terms.contains(x)) {
        let mut more = terms.to_vec();
        more.push(*extra);
        match Design::new(&Model::new(more).unwrap(), positions) {
            Err(Error::RankDeficient { terms: bad, .. }) => {
                assert!(bad.contains(extra), "{name} + {extra}: named {bad:?}")
            }
            other => panic!("{name}: adding {extra} should be refused, got {other:?}"),
        }
    }
}

#[test]
fn four_position_tumbles() {
    check(
        "pendulum 4",
        &[K0, Ki, Kp, Kii],
        &tumble(Mount::Pendulum, 4),
    );
    check("gate 4", &[K0, Ki, Ko, Kii], &tumble(Mount::Gate, 4));
}

#[test]
fn multipoint_tumbles() {
    for n in [8, 12, 24] {
        check(
            &format!("pendulum {n}"),
            &[K0, Ki, Kp, Kpi, Kii, Kiii],
            &tumble(Mount::Pendulum, n),
        );
        check(
            &format!("gate {n}"),
            &[K0, Ki, Ko, Kio, Kii, Kiii],
            &tumble(Mount::Gate, n),
        );
    }
}

#[test]
fn combined_two_mount_schedule() {
    let mut positions = tumble(Mount::Pendulum, 12);
    positions.extend(tumble(Mount::Gate, 12));
    check(
        "pendulum 12 + gate 12",
        &[K0, Ki, Kp, Ko, Kio, Kpi, Kii, Kpp, Kiii],
        &positions,
    );
}

#[test]
fn paper_model_on_every_schedule() {
    let t = truth();
    for n in [4, 8, 12, 24] {
        let positions = tumble(Mount::Pendulum, n);
        let id = Design::new(&Model::pendulum(), &positions)
            .unwrap()
            .solve(&outputs(&[K0, Ki, Kp], &positions));
        for term in [K0, Ki, Kp] {
            let (got, want) = (id.coefficients.get(term).unwrap(), t.get(term).unwrap());
            assert!(
                (got - want).abs() < 1e-12,
                "{n} positions, {term}: {got:e} vs {want:e}"
            );
        }
        assert!(id.residual_rms < 1e-12);
        assert_eq!(id.dof, n as usize - 3);
    }
}
