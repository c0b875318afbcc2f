//! Triads: three outputs at once, the single-axis method as the engine
//! (issue 30, known orientations).
//!
//! The model and its convention: outputs `u = (u_x, u_y, u_z)` in the
//! outputs' unit, specific force `g = (g_x, g_y, g_z)` in g in the sensor's
//! body frame,
//!
//! ```text
//! u = b + S g,        and its compensation   g = S⁻¹ (u − b)
//! ```
//!
//! with bias `b` and the 3×3 scale-and-misalignment matrix `S`. Row `m` of
//! `S` is axis `m`'s `(ki, kp, ko)` in the single-axis model with
//! `(a_i, a_p, a_o) = (g_m, g_{m+1}, g_{m+2})` (indices cyclic), and `b_m`
//! its `k0`:
//!
//! ```text
//! S[m][m] = ki_m,   S[m][m+1] = kp_m,   S[m][m+2] = ko_m   (mod 3)
//! ```
//!
//! so each axis is one [`TumbleTest`] over the shared positions, identified,
//! fused across runs and judged exactly as a single axis is; the triad is a
//! view over the three. The derived scale factor of axis `m` is the norm of
//! row `m` (its sensitivity along its own sensitive direction).
//!
//! Optionally each axis has a second-order term, its `kii` (`K2`):
//!
//! ```text
//! u_m = b_m + Σ_k S[m][k] g_k + S2_m g_m²
//! ```
//!
//! and compensation then solves the model for `g` by Newton's iteration
//! from `g₀ = S⁻¹ (u − b)` ([`Triad::compensate`]).

use nalgebra::{Matrix3, Vector3};

use crate::Error;
use crate::position::Position;
use crate::term::{Model, Term};
use crate::tumble::{Calibration, Run, TumbleTest};

/// Why a triad test or its compensation was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TriadError {
    /// One axis's tumble test was refused: the axis (0 = x, 1 = y, 2 = z)
    /// and why.
    #[error("axis {}: {error}", AXES[*.axis])]
    Axis {
        /// The axis, 0 to 2.
        axis: usize,
        /// Why.
        error: Error,
    },
    /// A run whose samples of all three outputs are an earlier run's.
    #[error(
        "run {run} is a copy of run {copy_of}: every position holds the same samples of all \
         three outputs, in the same number; a repeated tumble never reads identically, so send \
         each run's own data once"
    )]
    CopiedRun {
        /// The later run, from 0.
        run: usize,
        /// The run it repeats, from 0.
        copy_of: usize,
    },
    /// `S` has no inverse: outputs cannot be turned into specific force.
    #[error("the scale-and-misalignment matrix S is singular: outputs cannot be compensated")]
    Singular,
    /// With second-order terms, Newton's iteration did not converge: no
    /// specific force near `S⁻¹ (u − b)` gives these outputs.
    #[error(
        "the second-order model has no solution near S^-1 (u - b) for these outputs: \
         Newton's iteration did not converge in {MAX_NEWTON} steps"
    )]
    NoSolution,
}

/// The most Newton steps of a second-order compensation.
pub const MAX_NEWTON: usize = 50;

/// The ratio of `S`'s smallest to largest singular value at or below which
/// [`Triad::compensate`] refuses: a real triad's are all near its scale
/// factors; below this, some direction of specific force leaves no trace in
/// the outputs that double precision can recover.
pub const MIN_RECIPROCAL_CONDITION: f64 = 1e-12;

/// The axes' names.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// Each axis's model: bias and its three sensitivities, and with
/// `second_order` its `kii`.
fn model(second_order: bool) -> Model {
    let mut terms = vec![Term::K0, Term::Ki, Term::Kp, Term::Ko];
    if second_order {
        terms.push(Term::Kii);
    }
    Model::new(terms).expect("distinct terms")
}

/// The six faces of a cube: `±x`, `±y`, `±z` up (specific force +1 g along
/// the axis pointing up), in that order.
pub fn six_faces() -> Vec<[f64; 3]> {
    vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ]
}

/// One run of a triad: `samples[r]` are position `r`'s samples, each the
/// three outputs read at once.
#[derive(Clone, Debug, PartialEq)]
pub struct TriadRun {
    /// Per position, its samples of `(u_x, u_y, u_z)`.
    pub samples: Vec<Vec<[f64; 3]>>,
}

/// A validated triad test: the same positions (specific force in the body
/// frame, in g) for the three axes, and each axis's tumble test.
#[derive(Clone, Debug)]
pub struct TriadTest {
    axes: [TumbleTest; 3],
}

impl TriadTest {
    /// Splits the runs into the three axes' tumble tests, axis `m` seeing
    /// position `g` as `(g_m, g_{m+1}, g_{m+2})`; refuses what
    /// [`TumbleTest::new`] refuses, naming the axis.
    pub fn new(positions: &[[f64; 3]], runs: &[TriadRun]) -> Result<Self, TriadError> {
        Self::with_order(positions, runs, false)
    }

    /// As [`TriadTest::new`], each axis's model with its second-order term
    /// `kii` when `second_order`.
    pub fn with_order(
        positions: &[[f64; 3]],
        runs: &[TriadRun],
        second_order: bool,
    ) -> Result<Self, TriadError> {
        let axis = |m: usize| {
            let seen = positions
                .iter()
                .map(|g| Position::from_components([g[m], g[(m + 1) % 3], g[(m + 2) % 3]], None))
                .collect();
            let outputs = runs
                .iter()
                .map(|run| {
                    Run::from_samples(
                        run.samples
                            .iter()
                            .map(|at| at.iter().map(|u| u[m]).collect())
                            .collect(),
                    )
                })
                .collect();
            TumbleTest::of_axis(model(second_order), seen, outputs)
                .map_err(|error| TriadError::Axis { axis: m, error })
        };
        let axes = [axis(0)?, axis(1)?, axis(2)?];
        if let Some((run, copy_of)) = crate::tumble::copied(runs) {
            return Err(TriadError::CopiedRun { run, copy_of });
        }
        Ok(TriadTest { axes })
    }

    /// Each axis's tumble test (0 = x, 1 = y, 2 = z).
    pub fn axes(&self) -> &[TumbleTest; 3] {
        &self.axes
    }

    /// Calibrates each axis ([`TumbleTest::calibrate`], `batches` batches)
    /// and assembles `b` and `S` from the fused coefficients, and their
    /// standard errors from the fused standard errors.
    pub fn calibrate(&self, batches: usize) -> Result<TriadCalibration, TriadError> {
        let axis = |m: usize| {
            self.axes[m]
                .calibrate(batches)
                .map_err(|error| TriadError::Axis { axis: m, error })
        };
        let axes = [axis(0)?, axis(1)?, axis(2)?];
        let fused = Triad::assemble(&axes, |c, t| c.fused.coefficients.get(t).copied());
        let std_errors = Triad::assemble(&axes, |c, t| c.fused.std_errors.get(t).copied());
        Ok(TriadCalibration {
            axes,
            fused,
            std_errors,
        })
    }
}

/// A triad's bias and scale-and-misalignment matrix (or their standard
/// errors, element by element).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triad {
    /// `b`, in the outputs' unit.
    pub bias: [f64; 3],
    /// `S`, row `m` axis `m`'s, in the outputs' unit per g.
    pub matrix: [[f64; 3]; 3],
    /// `S2`, each axis's second-order coefficient (its `kii`), in the
    /// outputs' unit per g²; zero in a first-order model.
    pub square: [f64; 3],
}

impl Triad {
    /// `b` and `S` from the three axes' coefficients, as the module's doc
    /// maps them (`get` reads one axis's value of a term).
    fn assemble(axes: &[Calibration; 3], get: impl Fn(&Calibration, Term) -> Option<f64>) -> Triad {
        let mut t = Triad {
            bias: [0.0; 3],
            matrix: [[0.0; 3]; 3],
            square: [0.0; 3],
        };
        for (m, c) in axes.iter().enumerate() {
            let value = |term| get(c, term).expect("every axis's model has k0, ki, kp, ko");
            t.bias[m] = value(Term::K0);
            t.matrix[m][m] = value(Term::Ki);
            t.matrix[m][(m + 1) % 3] = value(Term::Kp);
            t.matrix[m][(m + 2) % 3] = value(Term::Ko);
            t.square[m] = get(c, Term::Kii).unwrap_or(0.0);
        }
        t
    }

    /// A first-order triad: bias `b` and matrix `S`.
    pub fn linear(bias: [f64; 3], matrix: [[f64; 3]; 3]) -> Triad {
        Triad {
            bias,
            matrix,
            square: [0.0; 3],
        }
    }

    /// The outputs `b + S g + S2 ⊙ g²` for specific force `g`.
    pub fn outputs(&self, g: [f64; 3]) -> [f64; 3] {
        let u = self.s() * Vector3::from(g) + Vector3::from(self.bias);
        [0, 1, 2].map(|m| u[m] + self.square[m] * g[m] * g[m])
    }

    /// The specific force `g` that gave outputs `u`: `S⁻¹ (u − b)` in a
    /// first-order model; with second-order terms, Newton's iteration on
    /// `F(g) = b + S g + S2 ⊙ g² − u` with Jacobian `J = S + diag(2 S2 ⊙ g)`,
    /// from `g₀ = S⁻¹ (u − b)`, until a step is at most `1e-15 (1 + ‖g‖)`
    /// ([`TriadError::NoSolution`] after [`MAX_NEWTON`] steps, or when a
    /// Jacobian is singular). Refused when `S` is singular to working
    /// precision: its smallest singular value below
    /// [`MIN_RECIPROCAL_CONDITION`] times its largest.
    pub fn compensate(&self, u: [f64; 3]) -> Result<[f64; 3], TriadError> {
        let s = self.s();
        let sv = s.singular_values();
        // Written so that a NaN anywhere refuses too.
        let conditioned = sv.min() > MIN_RECIPROCAL_CONDITION * sv.max();
        if !conditioned {
            return Err(TriadError::Singular);
        }
        let inverse = s.try_inverse().ok_or(TriadError::Singular)?;
        let mut g = inverse * (Vector3::from(u) - Vector3::from(self.bias));
        if self.square == [0.0; 3] {
            return Ok([g[0], g[1], g[2]]);
        }
        let square = Vector3::from(self.square);
        for _ in 0..MAX_NEWTON {
            let f = s * g + Vector3::from(self.bias) + square.component_mul(&g.component_mul(&g))
                - Vector3::from(u);
            let j = s + Matrix3::from_diagonal(&(2.0 * square.component_mul(&g)));
            let step = j.try_inverse().ok_or(TriadError::NoSolution)? * f;
            g -= step;
            if step.norm() <= 1e-15 * (1.0 + g.norm()) {
                return Ok([g[0], g[1], g[2]]);
            }
        }
        Err(TriadError::NoSolution)
    }

    /// Each axis's scale factor: the norm of its row of `S`.
    pub fn scale_factors(&self) -> [f64; 3] {
        self.matrix
            .map(|row| row.iter().map(|x| x * x).sum::<f64>().sqrt())
    }

    fn s(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| self.matrix[r][c])
    }
}

/// A triad's calibration: each axis's, and `b`, `S` with their standard
/// errors.
#[derive(Clone, Debug)]
pub struct TriadCalibration {
    /// Each axis's calibration (0 = x, 1 = y, 2 = z): runs, mean, fusion,
    /// eq. 8, exactly as a single axis's.
    pub axes: [Calibration; 3],
    /// `b` and `S` from the fused coefficients.
    pub fused: Triad,
    /// Their fused standard errors, element by element.
    pub std_errors: Triad,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triad with every element of `S` different, so that a misplaced
    /// element shows.
    fn truth() -> Triad {
        Triad::linear(
            [0.012, -0.021, 0.0053],
            [
                [1.021, 0.0031, -0.0022],
                [0.0014, 0.983, 0.0043],
                [-0.0035, 0.0027, 1.0105],
            ],
        )
    }

    /// The six faces and two tilted positions (spare positions give each
    /// run its standard errors).
    fn positions() -> Vec<[f64; 3]> {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut p = six_faces();
        p.push([h, h, 0.0]);
        p.push([0.0, -h, h]);
        p
    }

    /// Four runs of `truth`'s outputs, each sample shifted by a small
    /// deterministic amount that differs per run, position and axis.
    fn runs() -> Vec<TriadRun> {
        (0..4)
            .map(|j| TriadRun {
                samples: positions()
                    .iter()
                    .enumerate()
                    .map(|(r, g)| {
                        let u = truth().outputs(*g);
                        let e = |m: usize| 1e-6 * (((j * 7 + r * 3 + m * 5) % 11) as f64 - 5.0);
                        vec![[u[0] + e(0), u[1] + e(1), u[2] + e(2)]]
                    })
                    .collect(),
            })
            .collect()
    }

    #[test]
    fn the_six_faces_are_the_unit_axes_up_and_down() {
        let faces = six_faces();
        assert_eq!(faces.len(), 6);
        for (k, f) in faces.iter().enumerate() {
            let axis = k / 2;
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            for (m, x) in f.iter().enumerate() {
                assert_eq!(*x, if m == axis { sign } else { 0.0 }, "face {k}");
            }
        }
    }

    /// `b` and `S` come back where the convention puts them, to the noise
    /// (a few 1e-6 of the outputs), from data built by `u = b + S g`
    /// directly (not by the code under test's mapping).
    #[test]
    fn b_and_s_are_recovered_element_by_element() {
        let cal = TriadTest::new(&positions(), &runs())
            .unwrap()
            .calibrate(2)
            .unwrap();
        let t = truth();
        for m in 0..3 {
            assert!(
                (cal.fused.bias[m] - t.bias[m]).abs() < 1e-5,
                "b[{m}] = {}",
                cal.fused.bias[m]
            );
            for n in 0..3 {
                assert!(
                    (cal.fused.matrix[m][n] - t.matrix[m][n]).abs() < 1e-5,
                    "S[{m}][{n}] = {} against {}",
                    cal.fused.matrix[m][n],
                    t.matrix[m][n]
                );
                let se = cal.std_errors.matrix[m][n];
                assert!(se > 0.0 && se < 1e-5, "se S[{m}][{n}] = {se}");
            }
            let se = cal.std_errors.bias[m];
            assert!(se > 0.0 && se < 1e-5, "se b[{m}] = {se}");
        }
        // Each axis is the single-axis method's own calibration: axis y's
        // ki is S[1][1], its kp S[1][2], its ko S[1][0].
        let y = &cal.axes[1].fused.coefficients;
        assert_eq!(*y.get(Term::Ki).unwrap(), cal.fused.matrix[1][1]);
        assert_eq!(*y.get(Term::Kp).unwrap(), cal.fused.matrix[1][2]);
        assert_eq!(*y.get(Term::Ko).unwrap(), cal.fused.matrix[1][0]);
        assert_eq!(cal.axes[0].runs.len(), 4);
    }

    /// Compensation inverts the model: from `u = b + S g` back to `g`, and
    /// outputs of the calibrated triad at a position are the position's
    /// specific force once compensated.
    #[test]
    fn compensation_inverts_the_model() {
        let t = truth();
        for g in [
            [0.3, -0.5, 0.812_403_840_463_596],
            [0.0, 0.0, 1.0],
            [-1.0, 0.0, 0.0],
        ] {
            let u = t.outputs(g);
            // u by hand, row by row.
            for ((um, bm), row) in u.iter().zip(t.bias).zip(t.matrix) {
                let by_hand = bm + row.iter().zip(g).map(|(s, x)| s * x).sum::<f64>();
                assert!((um - by_hand).abs() < 1e-15);
            }
            let back = t.compensate(u).unwrap();
            for (b, x) in back.iter().zip(g) {
                assert!((b - x).abs() < 1e-12, "{back:?} against {g:?}");
            }
        }
    }

    #[test]
    fn scale_factors_are_the_row_norms() {
        let t = truth();
        let sf = t.scale_factors();
        assert!(
            (sf[0] - (1.021f64.powi(2) + 0.0031f64.powi(2) + 0.0022f64.powi(2)).sqrt()).abs()
                < 1e-15
        );
        assert!(
            (sf[1] - (0.0014f64.powi(2) + 0.983f64.powi(2) + 0.0043f64.powi(2)).sqrt()).abs()
                < 1e-15
        );
        assert!(
            (sf[2] - (0.0035f64.powi(2) + 0.0027f64.powi(2) + 1.0105f64.powi(2)).sqrt()).abs()
                < 1e-15
        );
    }

    #[test]
    fn a_singular_matrix_is_refused() {
        let mut t = truth();
        t.matrix[2] = [0.0; 3];
        assert_eq!(t.compensate([0.1, 0.2, 0.3]), Err(TriadError::Singular));
        // Rows that are multiples of each other: no inverse either, though
        // rounding leaves the determinant a few ulps from zero.
        let mut t = truth();
        t.matrix[1] = t.matrix[0].map(|x| 2.0 * x);
        assert_eq!(t.compensate([0.1, 0.2, 0.3]), Err(TriadError::Singular));
        // Either side of the bound, relative to the largest singular value
        // (1024 here; powers of two, so that the inverse is exact): a ratio
        // of 2⁻³⁶ ≈ 1.5e-11 accepted, 2⁻⁴⁰ ≈ 9.1e-13 refused.
        let mut t = truth();
        let big = 1024.0;
        let small = big * 2f64.powi(-36);
        t.matrix = [[big, 0.0, 0.0], [0.0, big, 0.0], [0.0, 0.0, small]];
        t.bias = [0.0; 3];
        assert_eq!(t.compensate([512.0, 256.0, small]), Ok([0.5, 0.25, 1.0]));
        let tiny = big * 2f64.powi(-40);
        t.matrix[2][2] = tiny;
        assert_eq!(
            t.compensate([512.0, 256.0, tiny]),
            Err(TriadError::Singular)
        );
        // At the bound exactly: refused (the bound is the last ratio refused).
        t.matrix = [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, MIN_RECIPROCAL_CONDITION],
        ];
        assert_eq!(t.compensate([1.0, 1.0, 1.0]), Err(TriadError::Singular));
    }

    /// A refusal names the axis whose tumble test was refused: positions
    /// only along ±z cannot separate x's kp from its bias.
    #[test]
    fn refusals_name_the_axis() {
        let up_down = vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let runs = vec![
            TriadRun {
                samples: vec![vec![[0.0; 3]]; 4],
            };
            2
        ];
        match TriadTest::new(&up_down, &runs) {
            Err(TriadError::Axis {
                axis: 0,
                error: Error::RankDeficient { .. },
            }) => {}
            other => panic!("{other:?}"),
        }
        let short = vec![TriadRun {
            samples: vec![vec![[0.0; 3]]; 3],
        }];
        let e = TriadTest::new(&positions(), &short).unwrap_err();
        assert!(matches!(
            e,
            TriadError::Axis {
                axis: 0,
                error: Error::ReadingCount { .. }
            }
        ));
        assert!(e.to_string().starts_with("axis x: "), "{e}");
        let axis_z = TriadError::Axis {
            axis: 2,
            error: Error::NoRuns,
        };
        assert_eq!(axis_z.to_string(), "axis z: the test has no runs");
    }

    /// `truth` with a second-order term on every axis.
    fn curved() -> Triad {
        Triad {
            square: [2.0e-3, -1.5e-3, 1.0e-3],
            ..truth()
        }
    }

    /// Each axis's `kii` is its `S2`: recovered from outputs built by
    /// `u_m = b_m + (S g)_m + S2_m g_m²` by hand, with `b` and `S`; a
    /// first-order test of the same data has no `S2`.
    #[test]
    fn second_order_terms_are_recovered_axis_by_axis() {
        let t = curved();
        let runs: Vec<TriadRun> = (0..4)
            .map(|j| TriadRun {
                samples: positions()
                    .iter()
                    .enumerate()
                    .map(|(r, g)| {
                        let e = |m: usize| 1e-7 * (((j * 7 + r * 3 + m * 5) % 11) as f64 - 5.0);
                        let u = [0, 1, 2].map(|m| {
                            t.bias[m]
                                + (0..3).map(|k| t.matrix[m][k] * g[k]).sum::<f64>()
                                + t.square[m] * g[m] * g[m]
                                + e(m)
                        });
                        vec![u]
                    })
                    .collect(),
            })
            .collect();
        let cal = TriadTest::with_order(&positions(), &runs, true)
            .unwrap()
            .calibrate(2)
            .unwrap();
        for m in 0..3 {
            assert!((cal.fused.square[m] - t.square[m]).abs() < 1e-6, "S2[{m}]");
            assert!((cal.fused.bias[m] - t.bias[m]).abs() < 1e-6, "b[{m}]");
            assert!(cal.std_errors.square[m] > 0.0, "se S2[{m}]");
            assert_eq!(
                cal.axes[m].fused.coefficients.get(Term::Kii),
                Some(&cal.fused.square[m])
            );
        }
        let linear = TriadTest::new(&positions(), &runs)
            .unwrap()
            .calibrate(2)
            .unwrap();
        assert_eq!(linear.fused.square, [0.0; 3]);
        assert_eq!(linear.axes[0].fused.coefficients.get(Term::Kii), None);
    }

    /// Newton's iteration inverts the second-order model to working
    /// precision, off the unit sphere too; outputs are checked by hand.
    #[test]
    fn second_order_compensation_inverts_the_model() {
        let t = curved();
        for g in [
            [0.3, -0.5, 0.812_403_840_463_596],
            [0.0, 0.0, 1.0],
            [-1.0, 0.0, 0.0],
            [2.0, -1.5, 0.25],
        ] {
            let u = t.outputs(g);
            for m in 0..3 {
                let by_hand = t.bias[m]
                    + (0..3).map(|k| t.matrix[m][k] * g[k]).sum::<f64>()
                    + t.square[m] * g[m] * g[m];
                assert_eq!(u[m], by_hand);
            }
            let back = t.compensate(u).unwrap();
            for m in 0..3 {
                assert!((back[m] - g[m]).abs() < 1e-13, "{g:?}: {back:?}");
            }
            // The first-order inverse is off by about S2 g² / S.
            let linear = Triad::linear(t.bias, t.matrix).compensate(u).unwrap();
            assert!((0..3).any(|m| (linear[m] - g[m]).abs() > 1e-4), "{g:?}");
        }
    }

    /// Newton's stopping rule scales with `g`: a step within 1e-15 of
    /// `1 + ‖g‖` ends it, so it ends both far out (where rounding leaves
    /// steps of an ulp of hundreds of g) and near zero (where an absolute
    /// floor of 1e-15 is all rounding in the outputs allows).
    #[test]
    fn second_order_compensation_ends_far_out_and_near_zero() {
        let t = curved();
        for g in [
            [300.0, -200.0, 150.0],
            [-150.0, 250.0, -300.0],
            [1e-3, -2e-3, 5e-4],
            [3e-7, 1e-9, -4e-8],
            // Found by search: here rounding leaves steps of ~1e-19, which
            // a floor relative to ‖g‖ alone never admits.
            [
                -5.670103092783504e-5,
                4.831460674157304e-4,
                -6.385542168674699e-4,
            ],
        ] {
            let u = t.outputs(g);
            let back = t.compensate(u).unwrap();
            for m in 0..3 {
                assert!(
                    (back[m] - g[m]).abs() <= 1e-12 * (1.0 + g[m].abs()),
                    "{g:?}: {back:?}"
                );
            }
        }
    }

    /// Outputs no specific force near `S⁻¹ (u − b)` gives: `u_x = g_x − g_x²`
    /// never exceeds 1/4, so `u_x = 1` has no solution.
    #[test]
    fn second_order_compensation_refuses_outputs_without_a_solution() {
        let t = Triad {
            bias: [0.0; 3],
            matrix: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            square: [-1.0, 0.0, 0.0],
        };
        assert_eq!(t.compensate([1.0, 0.0, 0.0]), Err(TriadError::NoSolution));
        assert!(
            TriadError::NoSolution
                .to_string()
                .contains(&format!("in {MAX_NEWTON} steps"))
        );
        // Within reach, the root nearer g₀ = u: u_x = 0.21 at g_x = 0.3.
        let g = t.compensate([0.21, 0.5, -0.5]).unwrap();
        assert!((g[0] - 0.3).abs() < 1e-14, "{g:?}");
        assert_eq!((g[1], g[2]), (0.5, -0.5));
    }
}
