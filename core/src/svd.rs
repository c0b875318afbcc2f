//! The thin singular value decomposition of a design, by one-sided Jacobi
//! rotations (Hestenes 1958; Demmel and Veselić 1992).
//!
//! For an `m × p` matrix `A` with `m ≥ p`, `W` starts as `A` and `V` as the
//! `p × p` identity. A rotation of the column pair `(i, j)`,
//!
//! ```text
//! α = ‖w_i‖²,   β = ‖w_j‖²,   γ = w_iᵀ·w_j
//! ζ = (β − α) / (2γ),   t = sign(ζ) / (|ζ| + √(1 + ζ²)),   c = 1/√(1 + t²),   s = c·t
//! (w_i, w_j) ← (c·w_i − s·w_j,  s·w_i + c·w_j),   the same for (v_i, v_j)
//! ```
//!
//! makes `w_i` and `w_j` orthogonal: the new `w_iᵀ·w_j` is
//! `c·s·(α − β) + (c² − s²)·γ`, zero when `t² + 2ζ·t − 1 = 0`, of whose
//! roots `t` is the smaller (a rotation by at most π/4). Every rotation
//! keeps `W = A·V` with `V` orthogonal. Sweeps over every pair go on until
//! no pair has `|γ| > ε·√(α·β)` (`ε` the machine epsilon): then `W`'s
//! columns are orthogonal to working precision, and
//!
//! ```text
//! σ_k = ‖w_k‖,   u_k = w_k / σ_k   (u_k = 0 when σ_k = 0),   A = U·Σ·Vᵀ
//! ```
//!
//! with the columns ordered by decreasing `σ`. A column whose norm has
//! fallen to `ε·‖A‖_F` or below is rounding noise (a rank-deficient `A`:
//! more columns than the rank can keep orthogonal and non-zero) and is
//! rotated no further: it would only shrink by a factor a sweep, never to
//! zero, and its `σ`, below `ε·‖A‖_F`, changes no other by more than that. The method computes small
//! singular values to high relative accuracy (Demmel and Veselić), which
//! the rank test of [`crate::identify`] relies on; it converges
//! quadratically, in a handful of sweeps for a design's few columns.

use nalgebra::{DMatrix, DVector};

/// Sweeps after which a decomposition that has not converged is given up
/// (a handful suffice; only non-finite entries come near this).
const MAX_SWEEPS: usize = 64;

/// The factors of a thin SVD `A = U·Σ·Vᵀ`: `U` (m × p) and `V` (p × p) with
/// orthonormal columns (but `U`'s of a zero `σ`, which are zero), `σ`
/// non-negative and decreasing.
#[derive(Clone, Debug)]
pub struct Factors {
    /// The left singular vectors, one column per singular value.
    pub u: DMatrix<f64>,
    /// The singular values, largest first.
    pub sigma: DVector<f64>,
    /// The right singular vectors, one column per singular value.
    pub v: DMatrix<f64>,
}

/// The thin SVD of `a`, which has at least as many rows as columns; `None`
/// if the sweeps do not converge (a non-finite entry).
///
/// # Panics
/// If `a` has fewer rows than columns.
pub fn thin(a: &DMatrix<f64>) -> Option<Factors> {
    let (m, p) = a.shape();
    assert!(m >= p, "at least as many rows as columns");
    let mut w = a.clone();
    let mut v = DMatrix::<f64>::identity(p, p);
    let negligible = (f64::EPSILON * a.norm()).powi(2);
    let mut converged = false;
    for _ in 0..MAX_SWEEPS {
        let mut rotated = false;
        for i in 0..p {
            for j in i + 1..p {
                let alpha = w.column(i).norm_squared();
                let beta = w.column(j).norm_squared();
                let gamma = w.column(i).dot(&w.column(j));
                if alpha.min(beta) <= negligible
                    || gamma.abs() <= f64::EPSILON * (alpha * beta).sqrt()
                {
                    continue;
                }
                rotated = true;
                let zeta = (beta - alpha) / (2.0 * gamma);
                let t = zeta.signum() / (zeta.abs() + zeta.hypot(1.0));
                let c = 1.0 / t.hypot(1.0);
                let s = c * t;
                rotate(&mut w, i, j, c, s);
                rotate(&mut v, i, j, c, s);
            }
        }
        if !rotated {
            converged = true;
            break;
        }
    }
    if !converged {
        return None;
    }
    let norms: Vec<f64> = (0..p).map(|k| w.column(k).norm()).collect();
    let mut order: Vec<usize> = (0..p).collect();
    order.sort_by(|x, y| norms[*y].total_cmp(&norms[*x]));
    let u = DMatrix::from_fn(m, p, |r, k| {
        let from = order[k];
        if norms[from] > 0.0 {
            w[(r, from)] / norms[from]
        } else {
            0.0
        }
    });
    Some(Factors {
        u,
        sigma: DVector::from_fn(p, |k, _| norms[order[k]]),
        v: DMatrix::from_fn(p, p, |r, k| v[(r, order[k])]),
    })
}

/// Columns `i` and `j` of `x` replaced by `c·x_i − s·x_j` and `s·x_i + c·x_j`.
fn rotate(x: &mut DMatrix<f64>, i: usize, j: usize, c: f64, s: f64) {
    for r in 0..x.nrows() {
        let (xi, xj) = (x[(r, i)], x[(r, j)]);
        x[(r, i)] = c * xi - s * xj;
        x[(r, j)] = s * xi + c * xj;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Householder reflection `I − 2·h·hᵀ/‖h‖²` (orthogonal, symmetric).
    fn reflection(h: &[f64]) -> DMatrix<f64> {
        let h = DVector::from_column_slice(h);
        DMatrix::identity(h.len(), h.len()) - &h * h.transpose() * (2.0 / h.norm_squared())
    }

    fn assert_orthonormal(x: &DMatrix<f64>, tolerance: f64) {
        let gram = x.transpose() * x;
        let off = (gram - DMatrix::identity(x.ncols(), x.ncols())).amax();
        assert!(off < tolerance, "columns not orthonormal by {off:e}");
    }

    /// `A = Q₁·diag(σ)·Q₂ᵀ` built from reflections, with singular values
    /// given in no order: they come back largest first, each within
    /// `1e-14·σ_max` (what rounding `A` itself allows), with orthonormal
    /// factors that reconstruct `A`.
    #[test]
    fn known_singular_values_come_back_largest_first() {
        let (m, p) = (7, 4);
        let q1 = reflection(&[1.0, -2.0, 0.5, 3.0, -1.0, 0.25, 2.0]);
        let q2 = reflection(&[0.3, 1.0, -0.7, 2.0]);
        let sigma = [0.02, 3.0, 10.0, 0.5];
        let mut d = DMatrix::zeros(m, p);
        for (k, s) in sigma.iter().enumerate() {
            d[(k, k)] = *s;
        }
        let a = &q1 * d * q2.transpose();
        let f = thin(&a).expect("it converges");
        for (got, want) in f.sigma.iter().zip([10.0, 3.0, 0.5, 0.02]) {
            assert!(
                (got - want).abs() < 1e-14 * 10.0,
                "{got:e} against {want:e}"
            );
        }
        assert_orthonormal(&f.u, 1e-14);
        assert_orthonormal(&f.v, 1e-14);
        let back = &f.u * DMatrix::from_diagonal(&f.sigma) * f.v.transpose();
        assert!((back - &a).amax() < 1e-12);
    }

    /// Two equal columns and a zero one: two singular values are exactly
    /// zero (not merely small), the zero one's left vector is zero, and the
    /// right vectors of the zero singular values span the null space:
    /// `(e₀ − e₁)/√2` and `e₂`.
    #[test]
    fn dependent_and_zero_columns_give_exact_zeros_and_the_null_space() {
        let a = DMatrix::from_row_slice(
            4,
            3,
            &[
                1.0, 1.0, 0.0, //
                2.0, 2.0, 0.0, //
                -1.0, -1.0, 0.0, //
                0.5, 0.5, 0.0,
            ],
        );
        let f = thin(&a).expect("it converges");
        assert!((f.sigma[0] - 2f64.sqrt() * 2.5).abs() < 1e-14);
        assert_eq!((f.sigma[1], f.sigma[2]), (0.0, 0.0));
        assert!(f.u.column(1).iter().chain(f.u.column(2)).all(|x| *x == 0.0));
        assert_orthonormal(&f.v, 1e-15);
        let null = f.v.columns(1, 2);
        let share = |row: usize| null.row(row).norm_squared();
        assert!((share(0) - 0.5).abs() < 1e-15);
        assert!((share(1) - 0.5).abs() < 1e-15);
        assert!((share(2) - 1.0).abs() < 1e-15);
        assert!((&a * null).amax() < 1e-15);
    }

    /// Columns of very different norms (a graded matrix) whose product is
    /// tiny but not negligible are still rotated apart: `U` stays
    /// orthonormal to working precision and the small singular value is
    /// found to its last digits (a threshold on `γ` that grew with the
    /// larger column, not with `√(α·β)`, would leave `u₀ᵀu₁ = 1e-14`).
    #[test]
    fn graded_columns_stay_orthonormal() {
        let a = DMatrix::from_row_slice(2, 2, &[1e3, 1e-17, 0.0, 1e-3]);
        let f = thin(&a).expect("it converges");
        assert_orthonormal(&f.u, 1e-15);
        assert_orthonormal(&f.v, 1e-15);
        assert!((f.sigma[0] / 1e3 - 1.0).abs() < 1e-15);
        assert!((f.sigma[1] / 1e-3 - 1.0).abs() < 1e-15);
    }

    /// A column at rounding-noise level, `ε·‖A‖_F` or below, is left as it
    /// is: `V` is the identity exactly and its `σ` its norm.
    #[test]
    fn a_column_at_noise_level_is_not_rotated() {
        let a = DMatrix::from_row_slice(2, 2, &[1e3, 1e-14, 0.0, 0.0]);
        let f = thin(&a).expect("it converges");
        assert_eq!(f.v, DMatrix::identity(2, 2));
        assert_eq!(f.sigma.as_slice(), &[1e3, 1e-14]);
    }

    /// Columns already orthogonal need no rotation: `V` is a permutation
    /// and `σ` the columns' norms.
    #[test]
    fn orthogonal_columns_are_their_own_factors() {
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 3.0, 0.0, 0.0]);
        let f = thin(&a).expect("it converges");
        assert_eq!(f.sigma.as_slice(), &[3.0, 1.0]);
        assert_eq!(f.v, DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 1.0, 0.0]));
        assert_eq!(f.u.column(0).as_slice(), &[0.0, 1.0, 0.0]);
    }

    /// A non-finite entry never converges: `None`, not a factorisation of
    /// NaNs.
    #[test]
    fn a_non_finite_entry_does_not_converge() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, f64::NAN, 0.5, 2.0]);
        assert!(thin(&a).is_none());
    }

    #[test]
    #[should_panic(expected = "at least as many rows")]
    fn a_wide_matrix_is_refused() {
        let _ = thin(&DMatrix::zeros(2, 3));
    }
}
