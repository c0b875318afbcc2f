//! Property tests of the core's invariants.

use accelcal_core::fusion::fuse;
use accelcal_core::{Compensator, Design, Gravity, Model, Mount, Term, TermMap};
use proptest::prelude::*;

const PENDULUM_12: [Term; 6] = [
    Term::K0,
    Term::Ki,
    Term::Kp,
    Term::Kpi,
    Term::Kii,
    Term::Kiii,
];

fn tumble12() -> Vec<Gravity> {
    (0..12)
        .map(|k| Mount::Pendulum.gravity(30.0 * f64::from(k)))
        .collect()
}

fn outputs_strategy() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-2.0f64..2.0, 12)
}

proptest! {
    /// Permuting the positions (and their outputs together) leaves the
    /// coefficients unchanged and permutes the residuals the same way.
    #[test]
    fn identification_is_invariant_to_position_order(
        y in outputs_strategy(),
        perm in Just((0..12usize).collect::<Vec<_>>()).prop_shuffle(),
    ) {
        let model = Model::new(PENDULUM_12.to_vec()).unwrap();
        let a = tumble12();
        let base = Design::new(&model, &a).unwrap().solve(&y);
        let pa: Vec<Gravity> = perm.iter().map(|&k| a[k]).collect();
        let py: Vec<f64> = perm.iter().map(|&k| y[k]).collect();
        let shuffled = Design::new(&model, &pa).unwrap().solve(&py);
        for ((_, x), (_, z)) in base.coefficients.iter().zip(shuffled.coefficients.iter()) {
            prop_assert!((x - z).abs() < 1e-12, "{x} vs {z}");
        }
        for (n, &k) in perm.iter().enumerate() {
            prop_assert!((shuffled.residuals[n] - base.residuals[k]).abs() < 1e-12);
        }
    }

    /// Least-squares residuals are orthogonal to every column: Aᵀr = 0.
    #[test]
    fn residuals_are_orthogonal_to_the_design(y in outputs_strategy()) {
        let model = Model::new(PENDULUM_12.to_vec()).unwrap();
        let design = Design::new(&model, &tumble12()).unwrap();
        let id = design.solve(&y);
        let r = nalgebra::DVector::from_vec(id.residuals.clone());
        let atr = design.matrix().tr_mul(&r);
        prop_assert!(atr.amax() < 1e-12, "Aᵀr = {atr}");
    }

    /// Any schedule of faces and tilts, any model it identifies: the fit
    /// satisfies the normal equations (Aᵀr = 0) and A⁺A = I. Designs of
    /// this kind (six faces and six tilts, `k0 ki kp kio`) once met a wrong
    /// factorisation (nalgebra's SVD, dimforge/nalgebra#1172).
    #[test]
    fn every_identifiable_design_is_solved_exactly(
        tilts in prop::collection::vec((-1.0f64..1.0, 0.0f64..6.3), 0..10),
        faces in prop::collection::vec(0usize..6, 0..6),
        mask in 1u16..(1 << 11),
        y in prop::collection::vec(-2.0f64..2.0, 16),
    ) {
        let face = |k: usize| {
            let mut a = [0.0; 3];
            a[k / 2] = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
            Gravity::from(a)
        };
        let mut a: Vec<Gravity> = faces.iter().map(|k| face(*k)).collect();
        for (z, th) in tilts {
            let r = (1.0 - z * z).sqrt();
            let round = |x: f64| (x * 100.0).round() / 100.0;
            a.push(Gravity::from([round(r * th.cos()), round(r * th.sin()), round(z)]));
        }
        let terms: Vec<Term> = Term::ALL.iter().enumerate().filter(|(k, _)| mask >> k & 1 == 1).map(|(_, t)| *t).collect();
        let model = Model::new(terms).unwrap();
        if let Ok(design) = Design::new(&model, &a) {
            let y = &y[..a.len()];
            let id = design.solve(y);
            let r = nalgebra::DVector::from_vec(id.residuals.clone());
            let atr = design.matrix().tr_mul(&r);
            let scale = design.matrix().norm() * nalgebra::DVector::from_column_slice(y).norm();
            prop_assert!(atr.amax() <= 1e-10 * scale, "Aᵀr = {atr}");
            let p = model.len();
            let err = (design.pseudo_inverse() * design.matrix() - nalgebra::DMatrix::identity(p, p)).amax();
            prop_assert!(err <= 1e-13 * design.condition_number(), "A⁺A − I: {err:e}");
        }
    }

    /// Reordering values within a batch leaves the fusion unchanged.
    #[test]
    fn fusion_is_invariant_within_batches(
        values in prop::collection::vec(-10.0f64..10.0, 7),
        first in Just((0..4usize).collect::<Vec<_>>()).prop_shuffle(),
        second in Just((4..7usize).collect::<Vec<_>>()).prop_shuffle(),
    ) {
        let base = fuse(&values, 2);
        prop_assume!(base.is_ok());
        let base = base.unwrap();
        let order: Vec<usize> = first.into_iter().chain(second).collect();
        let shuffled: Vec<f64> = order.iter().map(|&k| values[k]).collect();
        let f = fuse(&shuffled, 2).unwrap();
        prop_assert!((f.value - base.value).abs() <= 1e-12 * base.value.abs().max(1.0));
        prop_assert!((f.std_error - base.std_error).abs() <= 1e-12 * base.std_error);
    }

    /// Compensation inverts the model: the input that produced an output is
    /// recovered from it, for realistic (scale-dominated) coefficients.
    #[test]
    fn compensation_inverts_the_model(
        k in prop::array::uniform11(-1e-2f64..1e-2),
        ki in prop_oneof![-1.5f64..-0.5, 0.5f64..1.5],
        a in prop::array::uniform3(-1.0f64..1.0),
    ) {
        let mut coefficients: Vec<(Term, f64)> = Term::ALL.iter().copied().zip(k).collect();
        coefficients[1].1 = ki;
        let c = Compensator::new(&TermMap(coefficients)).unwrap();
        let a = Gravity::from(a);
        let u = c.output(&a);
        let back = c.input(u, a.p, a.o).unwrap();
        prop_assert!((back - a.i).abs() < 1e-12, "{back} vs {}", a.i);
    }
}

mod metrology {
    use accelcal_core::coverage::Coverage;
    use accelcal_core::history::{Point, stability};
    use accelcal_core::uncertainty::{Stand, budget};
    use accelcal_core::{Compensator, Model, Mount, Position, Run, Term, TermMap, TumbleTest};
    use proptest::prelude::*;

    fn test_of(k: &TermMap<f64>, n: u32) -> TumbleTest {
        let positions: Vec<Position> = (0..n)
            .map(|j| {
                Position::from_angle(360.0 * f64::from(j) / f64::from(n), Mount::Pendulum, None)
            })
            .collect();
        let c = Compensator::new(k).unwrap();
        let runs = (0..4)
            .map(|r| {
                Run::from_samples(
                    positions
                        .iter()
                        .enumerate()
                        .map(|(p, pos)| vec![c.output(&pos.a) + 1e-7 * ((r * 11 + p) as f64).cos()])
                        .collect(),
                )
            })
            .collect();
        TumbleTest::new(Model::pendulum(), positions, runs).unwrap()
    }

    proptest! {
        /// A linear model's gravity component is |k|·u on the scale terms
        /// and zero on the bias, whatever the schedule.
        #[test]
        fn linear_gravity_component_is_k_times_u(
            k0 in -1e-2f64..1e-2, ki in prop_oneof![-2.0f64..-0.5, 0.5f64..2.0], kp in -1e-2f64..1e-2,
            u in 0.0f64..1e-3, n in prop::sample::select(vec![4u32, 8, 12, 24]),
        ) {
            let k = TermMap(vec![(Term::K0, k0), (Term::Ki, ki), (Term::Kp, kp)]);
            let se = TermMap(vec![(Term::K0, 0.0), (Term::Ki, 0.0), (Term::Kp, 0.0)]);
            let b = budget(&test_of(&k, n), &k, (&se, &TermMap(vec![])), Stand { gravity_rel_std: u, ..Stand::default() }, Coverage::Factor(2.0), &TermMap(vec![])).unwrap();
            prop_assert!((b.terms[Term::Ki].gravity - u * ki.abs()).abs() <= 1e-12 * u.max(1e-300));
            prop_assert!((b.terms[Term::Kp].gravity - u * kp.abs()).abs() <= 1e-12 * u.max(1e-300));
            prop_assert!(b.terms[Term::K0].gravity <= 1e-13 * u);
        }

        /// Without stand uncertainties the combined uncertainty is the
        /// statistical one, and the expanded is k times it.
        #[test]
        fn zero_stand_inputs_leave_the_statistical_part(
            se0 in 0.0f64..1e-3, se1 in 0.0f64..1e-3, se2 in 0.0f64..1e-3, k in 1.0f64..3.0,
        ) {
            let coefficients = TermMap(vec![(Term::K0, 1e-3), (Term::Ki, -1.2), (Term::Kp, 6e-3)]);
            let se = TermMap(vec![(Term::K0, se0), (Term::Ki, se1), (Term::Kp, se2)]);
            let b = budget(&test_of(&coefficients, 8), &coefficients, (&se, &TermMap(vec![])), Stand::default(), Coverage::Factor(k), &TermMap(vec![])).unwrap();
            for (t, tb) in b.terms.iter() {
                prop_assert_eq!(tb.combined, se[t]);
                prop_assert_eq!(tb.expanded, k * se[t]);
            }
        }

        /// A perfectly linear history drifts by its slope, with no residual.
        #[test]
        fn a_linear_history_drifts_by_its_slope(
            intercept in -10.0f64..10.0, slope in -1.0f64..1.0,
            times in prop::collection::btree_set(0u32..4000, 3..20),
        ) {
            let points: Vec<Point> = times
                .iter()
                .map(|d| {
                    let t = f64::from(*d) / 365.25;
                    Point {
                        id: d.to_string(),
                        t_years: t,
                        values: TermMap(vec![(Term::K0, intercept + slope * t)]),
                        std_errors: TermMap(vec![(Term::K0, 0.01)]),
                    }
                })
                .collect();
            let s = stability(&points, 2.0);
            let k0 = &s[Term::K0];
            prop_assert!((k0.drift_per_year.unwrap() - slope).abs() < 1e-9);
            prop_assert!(k0.drift_std_error.unwrap() < 1e-9);
        }
    }
}
