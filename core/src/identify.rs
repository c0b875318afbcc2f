//! Per-run least-squares identification of the model coefficients.
//!
//! For a model with terms `t_1 … t_p` and positions `a_1 … a_m`, the design
//! matrix is `A[r][j] = regressor_{t_j}(a_r)` and a run's position values are
//! `y_r` (the mean of that position's samples). The coefficients solve
//!
//! ```text
//! min_x ‖A·x − y‖²
//! ```
//!
//! by the singular value decomposition `A = U·Σ·Vᵀ` ([`crate::svd`];
//! never the normal equations, whose condition number is the square of
//! `A`'s):
//!
//! ```text
//! x = V·Σ⁻¹·Uᵀ·y,     r = y − A·x,     dof = m − p
//! σ̂² = rᵀr / dof,     Cov(x) = σ̂²·(AᵀA)⁻¹ = σ̂²·V·Σ⁻²·Vᵀ
//! ```
//!
//! so the standard error of `x_j` is `σ̂·sqrt(Σ_k V[j][k]² / σ_k²)`, reported
//! only when `dof > 0`. The design's 2-norm condition number is
//! `σ_max / σ_min`. `‖r‖` is computed scaled ([`scaled_norm`]) so that
//! outputs of any magnitude give their standard errors rather than zero
//! (underflow) or infinity.
//!
//! **Identifiability.** A singular value `σ_k ≤ RANK_TOLERANCE·σ_max` counts as
//! zero; its right singular vector spans part of the null space
//! `N = {x : A·x = 0}`. A term `t_j` cannot be separated from the others
//! exactly when its unit vector has a component in `N`, i.e. when row `j` of a
//! basis of `N` is non-zero — a basis-independent test. With fewer positions
//! than terms the matrix is padded with zero rows, which leaves `N` unchanged.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::Error;
use crate::fusion::scaled_norm;
use crate::position::Gravity;
use crate::svd::{self, Factors};
use crate::term::{Model, TermMap};

/// Singular values at or below this fraction of the largest count as zero:
/// a design whose condition number exceeds `1e10` is refused as rank deficient.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// A null-space basis row with a norm above this names its term as inseparable.
const NULL_SPACE_PARTICIPATION: f64 = 1e-8;

/// The identified coefficients of one run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Identification {
    /// Least-squares coefficients, keyed by term in model order.
    pub coefficients: TermMap<f64>,
    /// Standard errors `σ̂·sqrt(diag (AᵀA)⁻¹)`; `None` when `dof = 0`.
    pub std_errors: Option<TermMap<f64>>,
    /// `y − A·x` per position, in the output's unit.
    pub residuals: Vec<f64>,
    /// `sqrt(rᵀr / m)`: root mean square of the residuals over the positions.
    pub residual_rms: f64,
    /// Degrees of freedom `m − p`.
    pub dof: usize,
}

/// A checked, factorised design: positions × model terms, known to be of full
/// column rank. Build it once per tumble and solve it for every run.
#[derive(Clone, Debug)]
pub struct Design {
    model: Model,
    matrix: DMatrix<f64>,
    u: DMatrix<f64>,
    sigma: DVector<f64>,
    v: DMatrix<f64>,
}

impl Design {
    /// Builds and factorises the design of `model` over `positions`.
    ///
    /// Refuses non-finite gravity components, an empty tumble and a design
    /// whose columns are numerically dependent (naming the terms involved).
    pub fn new(model: &Model, positions: &[Gravity]) -> Result<Self, Error> {
        if positions.is_empty() {
            return Err(Error::NoPositions);
        }
        for (position, a) in positions.iter().enumerate() {
            if let Some(axis) = a.to_array().iter().position(|x| !x.is_finite()) {
                return Err(Error::NonFiniteGravity { position, axis });
            }
        }
        let (m, p) = (positions.len(), model.len());
        let matrix = DMatrix::from_fn(m, p, |r, j| model.terms()[j].regressor(&positions[r]));
        // Zero rows do not change the null space; they give the SVD a full V.
        let padded = if m < p {
            matrix.clone().resize_vertically(p, 0.0)
        } else {
            matrix.clone()
        };
        let Factors { u, sigma, v } = svd::thin(&padded)
            .ok_or_else(|| rank_deficient(model, m, 0, model.terms().to_vec()))?;
        let sigma_max = sigma.max();
        let null: Vec<usize> = (0..sigma.len())
            .filter(|&k| counts_as_zero(sigma[k], sigma_max))
            .collect();
        if !null.is_empty() || m < p {
            let terms = model
                .terms()
                .iter()
                .enumerate()
                .filter(|(j, _)| {
                    let share: f64 = null.iter().map(|&k| v[(*j, k)].powi(2)).sum();
                    share.sqrt() > NULL_SPACE_PARTICIPATION
                })
                .map(|(_, t)| *t)
                .collect();
            return Err(rank_deficient(model, m, p - null.len(), terms));
        }
        Ok(Design {
            model: model.clone(),
            matrix,
            u,
            sigma,
            v,
        })
    }

    /// The model whose terms are the columns.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Number of positions (rows).
    pub fn positions(&self) -> usize {
        self.matrix.nrows()
    }

    /// The design matrix `A` (positions × terms).
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.matrix
    }

    /// The 2-norm condition number `σ_max / σ_min` of `A`.
    pub fn condition_number(&self) -> f64 {
        self.sigma.max() / self.sigma.min()
    }

    /// The pseudo-inverse `A⁺ = (AᵀA)⁻¹Aᵀ = V·Σ⁻¹·Uᵀ` (terms × positions):
    /// row `t` gives coefficient `t` as a weighted sum of position values.
    pub fn pseudo_inverse(&self) -> DMatrix<f64> {
        let mut vs = self.v.clone();
        for (k, s) in self.sigma.iter().enumerate() {
            vs.column_mut(k).unscale_mut(*s);
        }
        vs * self.u.transpose()
    }

    /// `(AᵀA)⁻¹ = V·Σ⁻²·Vᵀ` (terms × terms): the coefficients' covariance per
    /// unit residual variance.
    pub fn inverse_gram(&self) -> DMatrix<f64> {
        let mut vs = self.v.clone();
        for (k, s) in self.sigma.iter().enumerate() {
            vs.column_mut(k).unscale_mut(*s);
        }
        &vs * vs.transpose()
    }

    /// The unit right singular vector of the smallest singular value: the
    /// combination of coefficients the positions determine worst, one
    /// component per term.
    pub fn weakest_direction(&self) -> TermMap<f64> {
        let k = self.sigma.imin();
        TermMap(
            self.model
                .terms()
                .iter()
                .enumerate()
                .map(|(j, t)| (*t, self.v[(j, k)]))
                .collect(),
        )
    }

    /// The design widened by one column `x` (one value per position,
    /// finite): its fit found from this design's factors, with only the
    /// singular values of `[A x]` computed (for the rank test) instead of a
    /// new design's factors. It is refused (`None`) exactly as [`Design::new`]
    /// would refuse it: a singular value of `[A x]` at or below
    /// [`RANK_TOLERANCE`] of the largest (so also fewer positions than
    /// columns). Otherwise the answer is `ẑ = z / ‖z‖`, `z = (I − U·Uᵀ)·x`
    /// the part of `x` outside `A`'s columns: since `[A x]` spans what
    /// `[U ẑ]` spans, with orthonormal columns, the widened fit of any `y`
    /// leaves the residual `r − ẑ·(ẑᵀ·r)`, `r` this design's residual of
    /// `y`.
    ///
    /// # Panics
    /// If `x.len()` differs from the number of positions.
    pub fn widened(&self, x: &[f64]) -> Option<DVector<f64>> {
        let (m, p) = self.matrix.shape();
        assert_eq!(x.len(), m, "one value per position");
        let wide = DMatrix::from_fn(m.max(p + 1), p + 1, |r, j| match (r < m, j < p) {
            (false, _) => 0.0,
            (true, true) => self.matrix[(r, j)],
            (true, false) => x[r],
        });
        let sigma = svd::thin(&wide)?.sigma;
        let max = sigma.iter().copied().fold(0.0, f64::max);
        if sigma.iter().any(|s| counts_as_zero(*s, max)) {
            return None;
        }
        let x = DVector::from_column_slice(x);
        let z = &x - &self.u * self.u.tr_mul(&x);
        let norm = z.norm();
        Some(z.unscale(norm))
    }

    /// Solves the least-squares problem for position values `y` (one per row).
    ///
    /// # Panics
    /// If `y.len()` differs from the number of positions: callers build `y`
    /// from a validated run.
    pub fn solve(&self, y: &[f64]) -> Identification {
        let (m, p) = self.matrix.shape();
        assert_eq!(y.len(), m, "one value per position");
        let y = DVector::from_column_slice(y);
        // x = V·Σ⁻¹·Uᵀ·y
        let mut uty = self.u.tr_mul(&y);
        uty.component_div_assign(&self.sigma);
        let x = &self.v * uty;
        let residuals = &y - &self.matrix * &x;
        // ‖r‖ = sqrt(rᵀr), scaled against under- and overflow.
        let norm = scaled_norm(residuals.iter().copied());
        let dof = m - p;
        let terms = self.model.terms();
        let std_errors = (dof > 0).then(|| {
            // σ̂ = ‖r‖ / √dof; SE_j = σ̂·sqrt(Σ_k (V_jk / σ_k)²).
            let sigma_hat = norm / (dof as f64).sqrt();
            TermMap(
                terms
                    .iter()
                    .enumerate()
                    .map(|(j, t)| {
                        let var: f64 = (0..p)
                            .map(|k| (self.v[(j, k)] / self.sigma[k]).powi(2))
                            .sum();
                        (*t, sigma_hat * var.sqrt())
                    })
                    .collect(),
            )
        });
        Identification {
            coefficients: TermMap(terms.iter().copied().zip(x.iter().copied()).collect()),
            std_errors,
            residuals: residuals.iter().copied().collect(),
            residual_rms: norm / (m as f64).sqrt(),
            dof,
        }
    }
}

/// Whether singular value `s` of a matrix whose largest is `max` counts as
/// zero ([`RANK_TOLERANCE`]; every one does when `max` is zero).
fn counts_as_zero(s: f64, max: f64) -> bool {
    s <= RANK_TOLERANCE * max || max == 0.0
}

fn rank_deficient(model: &Model, positions: usize, rank: usize, terms: Vec<crate::Term>) -> Error {
    Error::RankDeficient {
        terms,
        positions,
        columns: model.len(),
        rank,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Term::*;
    use crate::position::Mount;

    fn tumble(mount: Mount, n: u32) -> Vec<Gravity> {
        (0..n)
            .map(|k| mount.gravity(360.0 * f64::from(k) / f64::from(n)))
            .collect()
    }

    fn refused(terms: &[crate::Term], positions: &[Gravity]) -> Vec<crate::Term> {
        match Design::new(&Model::new(terms.to_vec()).unwrap(), positions) {
            Err(Error::RankDeficient { terms, .. }) => terms,
            other => panic!("expected a rank-deficiency error, got {other:?}"),
        }
    }

    #[test]
    fn four_position_design_is_orthogonal_closed_form() {
        let d = Design::new(&Model::pendulum(), &tumble(Mount::Pendulum, 4)).unwrap();
        // Columns [1, a_i, a_p] over the tumble have norms 2, √2, √2.
        assert!((d.condition_number() - 2f64.sqrt()).abs() < 1e-14);
        let y = [0.3, 1.7, -0.5, -1.1];
        let id = d.solve(&y);
        let get = |t| *id.coefficients.get(t).unwrap();
        assert!((get(K0) - (0.3 + 1.7 - 0.5 - 1.1) / 4.0).abs() < 1e-15);
        assert!((get(Ki) - (-1.1 - 1.7) / 2.0).abs() < 1e-15);
        assert!((get(Kp) - (0.3 + 0.5) / 2.0).abs() < 1e-15);
        assert_eq!(id.dof, 1);
        // One degree of freedom: the residual is ±e on every position, with
        // e = (y0 + y180 − y90 − y270)/4, and RMS |e|.
        let e: f64 = (0.3 - 0.5 - 1.7 + 1.1) / 4.0;
        assert!((id.residual_rms - e.abs()).abs() < 1e-15);
        let se = id.std_errors.unwrap();
        // σ̂² = 4e²/1; var(k0) = σ̂²/4, var(ki) = var(kp) = σ̂²/2.
        assert!((se.get(K0).unwrap() - e.abs()).abs() < 1e-15);
        assert!((se.get(Ki).unwrap() - (2.0 * e * e).sqrt()).abs() < 1e-15);
    }

    /// Widening by a term's column refuses exactly what a design built with
    /// the term refuses, and otherwise leaves the residual of that design's
    /// own factorisation, on tumbles where some terms alias and others not.
    #[test]
    fn a_widened_design_is_the_design_with_its_column() {
        let y: Vec<f64> = (0..12).map(|k| (0.37 * f64::from(k)).sin() + 0.1).collect();
        let (mut both, mut neither) = (0, 0);
        for positions in [
            tumble(Mount::Pendulum, 4),
            tumble(Mount::Pendulum, 8),
            tumble(Mount::Pendulum, 12),
            sphere(12),
        ] {
            let base = Design::new(&Model::pendulum(), &positions).unwrap();
            let y = &y[..positions.len()];
            let r = DVector::from_vec(base.solve(y).residuals);
            for t in crate::Term::ALL {
                if base.model().index_of(t).is_some() {
                    continue;
                }
                let mut terms = base.model().terms().to_vec();
                terms.push(t);
                let rebuilt = Design::new(&Model::new(terms).unwrap(), &positions);
                let column: Vec<f64> = positions.iter().map(|a| t.regressor(a)).collect();
                let widened = base.widened(&column);
                let n = positions.len();
                match (&rebuilt, &widened) {
                    (Ok(d), Some(z)) => {
                        let want = d.solve(y).residuals;
                        let got = &r - z * z.dot(&r);
                        for (g, w) in got.iter().zip(&want) {
                            assert!((g - w).abs() < 1e-12, "{n} positions, {t}: {g} vs {w}");
                        }
                        both += 1;
                    }
                    (Err(_), None) => neither += 1,
                    _ => panic!("{n} positions, {t}: {rebuilt:?} vs {widened:?}"),
                }
            }
        }
        assert!(both > 0 && neither > 0, "{both} widened, {neither} refused");
        // At the edge: the bias column plus δ·w, w = a_i² − a_p² (cos 2θ,
        // orthogonal to 1, a_i and a_p over eight positions). [A x] then has
        // σ_max ≈ 4 and σ_min ≈ 0.7·δ: refused at δ = 1e-10 (σ_min / σ_max
        // under RANK_TOLERANCE), kept at δ = 1e-8.
        let eight = tumble(Mount::Pendulum, 8);
        let base = Design::new(&Model::pendulum(), &eight).unwrap();
        let near_bias = |delta: f64| -> Vec<f64> {
            eight
                .iter()
                .map(|a| 1.0 + delta * (Kii.regressor(a) - Kpp.regressor(a)))
                .collect()
        };
        assert!(base.widened(&near_bias(1e-10)).is_none());
        assert!(base.widened(&near_bias(1e-8)).is_some());
        // A column beyond as many as the positions allow is refused.
        let four = tumble(Mount::Pendulum, 4);
        let full = Design::new(&Model::new(vec![K0, Ki, Kp, Kii]).unwrap(), &four).unwrap();
        assert!(full.widened(&[1.0, 2.0, 3.0, 5.0]).is_none());
        let base = Design::new(&Model::pendulum(), &four).unwrap();
        assert!(base.widened(&[1.0, 2.0, 3.0, 5.0]).is_some());
    }

    /// Unit vectors spread over the sphere, exciting every regressor of eq. 2.
    fn sphere(n: u32) -> Vec<Gravity> {
        (0..n)
            .map(|k| {
                let z = 1.0 - 2.0 * (f64::from(k) + 0.5) / f64::from(n);
                let (s, c) = (2.399_963_229_728_653 * f64::from(k)).sin_cos();
                let r = (1.0 - z * z).sqrt();
                Gravity::from([r * c, r * s, z])
            })
            .collect()
    }

    #[test]
    fn unit_sphere_makes_k0_and_squares_inseparable() {
        let full = [K0, Ki, Kp, Ko, Kio, Kop, Kpi, Kii, Kpp, Koo];
        assert_eq!(refused(&full, &sphere(40)), vec![K0, Kii, Kpp, Koo]);
        // Any three of the four are separable.
        assert!(Design::new(&Model::new(full[..9].to_vec()).unwrap(), &sphere(40)).is_ok());
        // On a two-mount schedule kop is never excited (a_o·a_p = 0) as well.
        let mut schedule = tumble(Mount::Pendulum, 12);
        schedule.extend(tumble(Mount::Gate, 12));
        assert_eq!(refused(&full, &schedule), vec![K0, Kop, Kii, Kpp, Koo]);
    }

    #[test]
    fn cubic_term_aliases_scale_factor_on_four_positions() {
        let t = tumble(Mount::Pendulum, 4);
        assert_eq!(refused(&[K0, Ki, Kp, Kiii], &t), vec![Ki, Kiii]);
    }

    #[test]
    fn unexcited_axis_is_named() {
        let t = tumble(Mount::Pendulum, 8);
        assert_eq!(refused(&[K0, Ki, Ko], &t), vec![Ko]);
    }

    #[test]
    fn fewer_positions_than_terms_is_refused_with_terms() {
        let t = tumble(Mount::Pendulum, 4);
        match Design::new(&Model::new(vec![K0, Ki, Kp, Kpi, Kii]).unwrap(), &t[..2]) {
            Err(Error::RankDeficient {
                terms,
                positions,
                columns,
                rank,
            }) => {
                assert_eq!((positions, columns, rank), (2, 5, 2));
                assert!(terms.len() >= 3, "{terms:?}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn non_finite_and_empty_positions_are_refused() {
        let m = Model::pendulum();
        assert_eq!(Design::new(&m, &[]).unwrap_err(), Error::NoPositions);
        let bad = [Gravity::default(), Gravity::from([0.0, f64::NAN, 0.0])];
        assert_eq!(
            Design::new(&m, &bad).unwrap_err(),
            Error::NonFiniteGravity {
                position: 1,
                axis: 1
            }
        );
    }

    /// Eight positions, three terms: dof = 5. The columns [1, −sin θ, cos θ]
    /// over θ = 0°, 45°, … are orthogonal with norms² 8, 4, 4, so by hand
    /// k0 = Σy/8, ki = −Σ y·sin θ / 4, kp = Σ y·cos θ / 4, σ̂² = rᵀr / 5,
    /// SE(k0) = σ̂/√8 and SE(ki) = SE(kp) = σ̂/2.
    #[test]
    fn standard_errors_follow_the_closed_form_with_several_degrees_of_freedom() {
        let positions = tumble(Mount::Pendulum, 8);
        let d = Design::new(&Model::pendulum(), &positions).unwrap();
        assert_eq!(d.positions(), 8);
        let y = [0.31, 1.27, 1.69, 1.02, -0.48, -1.33, -1.61, -0.97];
        let id = d.solve(&y);
        let angles: Vec<f64> = (0..8).map(|k| (45.0 * f64::from(k)).to_radians()).collect();
        let k0: f64 = y.iter().sum::<f64>() / 8.0;
        let ki: f64 = -y.iter().zip(&angles).map(|(u, t)| u * t.sin()).sum::<f64>() / 4.0;
        let kp: f64 = y.iter().zip(&angles).map(|(u, t)| u * t.cos()).sum::<f64>() / 4.0;
        let rss: f64 = y
            .iter()
            .zip(&angles)
            .map(|(u, t)| (u - (k0 - ki * t.sin() + kp * t.cos())).powi(2))
            .sum();
        let sigma = (rss / 5.0).sqrt();
        let get = |m: &TermMap<f64>, t| *m.get(t).unwrap();
        assert!((get(&id.coefficients, K0) - k0).abs() < 1e-14);
        assert!((get(&id.coefficients, Ki) - ki).abs() < 1e-14);
        assert!((get(&id.coefficients, Kp) - kp).abs() < 1e-14);
        assert_eq!(id.dof, 5);
        let se = id.std_errors.unwrap();
        assert!((get(&se, K0) - sigma / 8f64.sqrt()).abs() < 1e-14 * sigma);
        assert!((get(&se, Ki) - sigma / 2.0).abs() < 1e-14 * sigma);
        assert!((get(&se, Kp) - sigma / 2.0).abs() < 1e-14 * sigma);
        assert!((id.residual_rms - (rss / 8.0).sqrt()).abs() < 1e-14);
    }

    /// Six faces and six tilts (z = ±0.6 every 60°, as a station computes
    /// them) with `k0 ki kp kio`: the singular values are those of numpy
    /// (LAPACK) and the fit satisfies the normal equations. nalgebra 0.35's
    /// SVD gives 1.9818 and 0.8322 for two of them on this design, and its
    /// reconstruction is off by 0.046 (dimforge/nalgebra#1172).
    #[test]
    fn faces_and_tilts_are_factorised_exactly() {
        let (c, s) = (0.400_000_000_000_000_13, 0.692_820_323_027_550_9);
        let a: Vec<Gravity> = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.8, 0.0, 0.6],
            [c, s, -0.6],
            [-0.399_999_999_999_999_86, 0.692_820_323_027_551, 0.6],
            [-0.8, 9.797_174_393_178_825e-17, -0.6],
            [-0.400_000_000_000_000_3, -0.692_820_323_027_550_7, 0.6],
            [c, -s, -0.6],
        ]
        .map(Gravity::from)
        .to_vec();
        let d = Design::new(&Model::new(vec![K0, Ki, Kp, Kio]).unwrap(), &a).unwrap();
        let mut sigma: Vec<f64> = d.sigma.iter().copied().collect();
        sigma.sort_by(|x, y| y.total_cmp(x));
        let numpy = [
            3.464_101_615_137_754_4,
            1.979_898_987_322_333_2,
            1.979_898_987_322_333_2,
            0.831_384_387_633_061_2,
        ];
        for (s, n) in sigma.iter().zip(numpy) {
            assert!((s - n).abs() < 1e-12, "{sigma:?}");
        }
        let y: Vec<f64> = (0..12).map(|k| (f64::from(k) * 0.7).sin()).collect();
        let r = DVector::from_vec(d.solve(&y).residuals);
        assert!(d.matrix().tr_mul(&r).amax() < 1e-13);
    }

    #[test]
    fn the_inverse_gram_matrix_inverts_the_normal_equations() {
        let d = Design::new(
            &Model::new(vec![K0, Ki, Kp, Kii]).unwrap(),
            &tumble(Mount::Pendulum, 12),
        )
        .unwrap();
        let gram = d.matrix().transpose() * d.matrix();
        let product = gram * d.inverse_gram();
        assert!((product - DMatrix::identity(4, 4)).amax() < 1e-12);
    }

    #[test]
    fn the_design_keeps_its_model_and_positions() {
        let model = Model::new(vec![K0, Ki, Kp, Kii]).unwrap();
        let d = Design::new(&model, &tumble(Mount::Pendulum, 12)).unwrap();
        assert_eq!(d.model(), &model);
        assert_eq!(d.positions(), 12);
        assert_eq!(d.matrix().shape(), (12, 4));
    }

    #[test]
    fn exactly_determined_design_has_no_standard_errors() {
        let t = tumble(Mount::Pendulum, 4);
        let d = Design::new(&Model::new(vec![K0, Ki, Kp, Kii]).unwrap(), &t).unwrap();
        let id = d.solve(&[1.0, 2.0, 3.0, 5.0]);
        assert_eq!(id.dof, 0);
        assert!(id.std_errors.is_none());
        assert!(id.residual_rms < 1e-14);
    }
}
