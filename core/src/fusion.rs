//! Statistics across repeated runs of one coefficient: the arithmetic mean
//! (paper eq. 1), batch-estimation fusion (eq. 4–7) and dispersion (eq. 8).
//!
//! **Batches.** The `n` values are split into `k` contiguous batches in
//! submission order, as equal as possible with the larger batches first
//! (7 values in 2 batches: 4 + 3). Batch `p` has `n_p` values, mean `x̄_p` and
//! sample standard deviation `s_p` (divisor `n_p − 1`, eq. 5).
//!
//! **Fusion.** The batch means are combined with the inverse variances of the
//! *means* as weights:
//!
//! ```text
//! w_p = n_p / s_p²,     x⁺ = Σ_p w_p·x̄_p / Σ_p w_p,     Var(x⁺) = 1 / Σ_p w_p
//! ```
//!
//! For equal batch sizes this is the paper's eq. 7 exactly. The paper's closed
//! form `Πσ_p² / Σσ_p²` for the fused variance equals `1/Σ(1/σ_p²)` only for
//! `k = 2`; the general form above is used for every `k`. With `k = 1` the
//! fused value is the mean and its standard error `s/√n`.
//!
//! **Implausibly consistent batches.** When the runs carry their own
//! standard errors (spare positions), a batch whose `s_p` of a coefficient is
//! below [`CONSISTENCY_FLOOR`] × the median of the runs' standard errors of
//! that coefficient agrees better than the runs' own noise allows (repeated
//! or copied data): its weight uses `s_p` floored at that bound,
//! `w_p = n_p / max(s_p, floor)²`, so it cannot outweigh the other batches by
//! orders of magnitude ([`consistency_floor`], [`fuse_with_floor`]). The
//! batch's reported `s_p` is unchanged. This includes `s_p = 0`, a batch of
//! equal values (a quantised sensor reading the same counts every run):
//! weighted at the floor, not refused. Only without a floor (runs without
//! spare positions, or fitting exactly) is a batch of equal values refused,
//! its weight being infinite.
//!
//! **Scale-free arithmetic.** `1/s_p²` overflows for values near 1e-155 and
//! squares of deviations underflow to zero below 1e-162, although every
//! result is representable. So the weights are taken relative to the
//! smallest standard deviation `s_min`,
//!
//! ```text
//! w'_p = n_p·(s_min/s_p)² ∈ (0, n_p],    x⁺ = Σ w'_p·x̄_p / Σ w'_p,    SE = s_min / √Σ w'_p
//! ```
//!
//! (the common factor `1/s_min²` cancels in `x⁺` and comes out of the root in
//! the standard error), and every root of a sum of squares is computed as
//! `m·√Σ(d/m)²` with `m = max |d|` ([`scaled_norm`]). Scaling all values by
//! `c` then scales every result by `c` (or `|c|`) exactly as the formulas do.
//!
//! **Dispersion (eq. 8).** For an estimate `K` over the per-run values `K_j`:
//!
//! ```text
//! dispersion(K) = sqrt( Σ_j (K − K_j)² / (n − 1) ),    relative = dispersion / |K|
//! ```
//!
//! The mean minimises `Σ(K − K_j)²`, so the dispersion about any other value —
//! the fused one included — is at least the dispersion about the mean.

use std::ops::Range;

use serde::Serialize;

use crate::FusionError;

/// Arithmetic mean `x̄ = Σ x_j / n` (eq. 1); NaN for an empty slice. When
/// the sum overflows (values near the largest double) it is `Σ (x_j / n)`.
pub fn mean(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    let sum = values.iter().sum::<f64>();
    if sum.is_finite() {
        sum / n
    } else {
        values.iter().map(|x| x / n).sum()
    }
}

/// The median (the mean of the middle two for an even count); NaN when empty.
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        mean(&v[n / 2 - 1..=n / 2])
    }
}

/// A batch deviation below this fraction of the runs' median standard error
/// is implausibly small.
pub const CONSISTENCY_FLOOR: f64 = 0.01;

/// The floor of a batch's deviation, `CONSISTENCY_FLOOR × median(run_std_errors)`,
/// for one coefficient's per-run standard errors; 0 (no floor) without any.
pub fn consistency_floor(run_std_errors: &[f64]) -> f64 {
    if run_std_errors.is_empty() {
        return 0.0;
    }
    CONSISTENCY_FLOOR * median(run_std_errors)
}

/// Sample standard deviation `sqrt(Σ (x_j − x̄)² / (n − 1))` (eq. 5);
/// `None` for fewer than two values.
pub fn sample_std(values: &[f64]) -> Option<f64> {
    dispersion(values, mean(values)).map(|d| d.absolute)
}

/// The Euclidean norm `sqrt(Σ d_j²)` computed as `m·sqrt(Σ (d_j/m)²)` with
/// `m = max |d_j|`, so that it neither underflows for tiny `d` nor overflows
/// for huge ones (the idea of LAPACK's `dnrm2`). 0 for an empty or all-zero
/// input.
pub fn scaled_norm(d: impl Iterator<Item = f64> + Clone) -> f64 {
    let m = d.clone().fold(0.0_f64, |m, x| m.max(x.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    m * d.map(|x| (x / m).powi(2)).sum::<f64>().sqrt()
}

/// Eq. 8 dispersion of the values about an estimate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Dispersion {
    /// `sqrt(Σ (K − K_j)² / (n − 1))`, in the coefficient's unit.
    pub absolute: f64,
    /// `absolute / |K|`; `None` when `K = 0` or the ratio is not a finite
    /// number (an estimate so close to zero that the ratio overflows).
    pub relative: Option<f64>,
}

/// Eq. 8 dispersion of `values` about `estimate`; `None` for fewer than two values.
pub fn dispersion(values: &[f64], estimate: f64) -> Option<Dispersion> {
    let n = values.len();
    if n < 2 {
        return None;
    }
    let norm = scaled_norm(values.iter().map(|x| estimate - x));
    let absolute = norm / ((n - 1) as f64).sqrt();
    let relative = Some(absolute / estimate.abs()).filter(|r| estimate != 0.0 && r.is_finite());
    Some(Dispersion { absolute, relative })
}

/// The index ranges of `k` contiguous batches over `n` values, larger first.
///
/// Refuses `k = 0` and any split that leaves a batch with fewer than two
/// values (naming the first such batch).
pub fn batch_ranges(n: usize, k: usize) -> Result<Vec<Range<usize>>, FusionError> {
    if k == 0 {
        return Err(FusionError::NoBatches);
    }
    let (base, extra) = (n / k, n % k);
    let mut start = 0;
    let mut ranges = Vec::with_capacity(k);
    for batch in 0..k {
        let len = base + usize::from(batch < extra);
        if len < 2 {
            return Err(FusionError::TooFewRuns {
                batch,
                runs: len,
                total: n,
                batches: k,
            });
        }
        ranges.push(start..start + len);
        start += len;
    }
    Ok(ranges)
}

/// One batch of a fusion: which runs, their mean and standard deviation.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// The runs (value indices) in this batch.
    pub runs: Range<usize>,
    /// Batch mean `x̄_p` (eq. 4).
    pub mean: f64,
    /// Batch sample standard deviation `s_p` (eq. 5).
    pub std: f64,
}

/// The batch-estimation fusion of one coefficient's per-run values.
#[derive(Clone, Debug, PartialEq)]
pub struct Fusion {
    /// The batches, in order.
    pub batches: Vec<Batch>,
    /// Fused value `x⁺ = Σ w_p·x̄_p / Σ w_p`.
    pub value: f64,
    /// Fused standard error `1 / sqrt(Σ w_p)`.
    pub std_error: f64,
    /// Its degrees of freedom, `1 / Σ_p (w_p/W)² / (n_p − 1)` with the
    /// weights used ([`crate::coverage::fused_dof`]).
    pub dof: f64,
}

/// Fuses `values` (one per run, in submission order) over `k` batches.
pub fn fuse(values: &[f64], k: usize) -> Result<Fusion, FusionError> {
    fuse_with_floor(values, k, 0.0)
}

/// Fuses `values` over `k` batches, each batch weighted by its deviation
/// floored at `floor` (see [`consistency_floor`]; 0 for none).
pub fn fuse_with_floor(values: &[f64], k: usize, floor: f64) -> Result<Fusion, FusionError> {
    if let Some(run) = values.iter().position(|x| !x.is_finite()) {
        return Err(FusionError::NonFinite { run });
    }
    let ranges = batch_ranges(values.len(), k)?;
    let mut batches = Vec::with_capacity(k);
    for (batch, runs) in ranges.into_iter().enumerate() {
        let xs = &values[runs.clone()];
        // Zero exactly when every value is the same: the deviations are
        // scaled, so distinct values never underflow to a zero spread.
        let std = sample_std(xs).unwrap_or(0.0);
        if std == 0.0 && floor <= 0.0 {
            return Err(FusionError::NoSpread {
                batch,
                first: runs.start,
                last: runs.end - 1,
            });
        }
        batches.push(Batch {
            runs,
            mean: mean(xs),
            std,
        });
    }
    // Weights relative to the smallest (floored) deviation: w'_p = n_p·(s_min/s_p)².
    let weighed = |b: &Batch| b.std.max(floor);
    let s_min = batches.iter().map(weighed).fold(f64::INFINITY, f64::min);
    let (mut sum_w, mut sum_wx) = (0.0, 0.0);
    let mut weights = Vec::with_capacity(batches.len());
    for b in &batches {
        let w = b.runs.len() as f64 * (s_min / weighed(b)).powi(2);
        sum_w += w;
        sum_wx += w * b.mean;
        weights.push((b.runs.len(), w));
    }
    let (value, std_error) = (sum_wx / sum_w, s_min / sum_w.sqrt());
    if !(value.is_finite() && std_error.is_finite()) {
        return Err(FusionError::NotRepresentable);
    }
    Ok(Fusion {
        batches,
        value,
        std_error,
        dof: crate::coverage::fused_dof(&weights),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_are_contiguous_and_larger_first() {
        assert_eq!(batch_ranges(7, 2).unwrap(), vec![0..4, 4..7]);
        assert_eq!(batch_ranges(6, 2).unwrap(), vec![0..3, 3..6]);
        assert_eq!(batch_ranges(8, 3).unwrap(), vec![0..3, 3..6, 6..8]);
        assert_eq!(batch_ranges(2, 1).unwrap(), vec![0..2]);
    }

    #[test]
    fn batches_of_one_and_zero_batches_are_refused() {
        assert_eq!(batch_ranges(3, 0), Err(FusionError::NoBatches));
        assert_eq!(
            batch_ranges(5, 3),
            Err(FusionError::TooFewRuns {
                batch: 2,
                runs: 1,
                total: 5,
                batches: 3
            })
        );
        assert_eq!(
            batch_ranges(1, 1),
            Err(FusionError::TooFewRuns {
                batch: 0,
                runs: 1,
                total: 1,
                batches: 1
            })
        );
    }

    #[test]
    fn identical_batch_is_refused_with_its_runs() {
        assert_eq!(
            fuse(&[1.0, 2.0, 3.0, 5.0, 5.0, 5.0], 2),
            Err(FusionError::NoSpread {
                batch: 1,
                first: 3,
                last: 5
            })
        );
        assert_eq!(
            fuse(&[1.0, f64::NAN, 3.0, 4.0], 2),
            Err(FusionError::NonFinite { run: 1 })
        );
    }

    /// Equal values with a floor: weighted at the floor, `w = n/floor²`.
    /// Batch 0: [1, 3], mean 2, s² = 2 → w = 1; batch 1: [5, 5] at the
    /// floor 0.5 → w = 2/0.25 = 8. x⁺ = (2 + 40)/9, Var = 1/9.
    #[test]
    fn identical_batch_is_weighted_at_the_floor() {
        let f = fuse_with_floor(&[1.0, 3.0, 5.0, 5.0], 2, 0.5).unwrap();
        assert_eq!(f.batches[1].std, 0.0, "reported as it is");
        assert!((f.value - 42.0 / 9.0).abs() < 1e-15, "{}", f.value);
        assert!((f.std_error - (1.0f64 / 9.0).sqrt()).abs() < 1e-15);
        // Every batch equal: the floors weigh them alike.
        let f = fuse_with_floor(&[2.0, 2.0, 2.0, 2.0], 2, 1e-3).unwrap();
        assert_eq!(f.value, 2.0);
        assert!((f.std_error - 1e-3 / 2.0).abs() < 1e-18);
    }

    #[test]
    fn one_batch_is_the_mean_with_standard_error_of_the_mean() {
        let xs = [1.0, 2.0, 4.0, 7.0];
        let f = fuse(&xs, 1).unwrap();
        assert_eq!(f.value, mean(&xs));
        let s = sample_std(&xs).unwrap();
        assert!((f.std_error - s / 2.0).abs() < 1e-15);
    }

    #[test]
    fn weights_are_those_of_the_batch_means() {
        // Batch 1: [1, 3] mean 2, s² 2, n 2 → w = 1; batch 2: [10, 11, 12]
        // mean 11, s² 1, n 3 → w = 3. x⁺ = (2 + 33)/4, Var = 1/4.
        let f = fuse(&[10.0, 11.0, 12.0, 1.0, 3.0], 2).unwrap();
        assert_eq!(f.value, 35.0 / 4.0);
        assert_eq!(f.std_error, 0.5);
        assert_eq!(f.batches[0].runs, 0..3);
        // ν = 1 / ((3/4)²/2 + (1/4)²/1).
        assert!((f.dof - 1.0 / (9.0 / 32.0 + 1.0 / 16.0)).abs() < 1e-12);
    }

    #[test]
    fn a_relative_dispersion_too_large_to_represent_is_none() {
        // |K| is the smallest subnormal: Σ(K − K_j)² ≈ 4, so the absolute
        // dispersion is 2 and the ratio overflows.
        let d = dispersion(&[0.0, 2.0], f64::from_bits(1)).unwrap();
        assert!((d.absolute - 2.0).abs() < 1e-15);
        assert_eq!(d.relative, None);
    }

    #[test]
    fn means_near_the_largest_double_do_not_overflow() {
        assert_eq!(mean(&[1.5e308, 1.7e308]), 1.6e308);
        assert_eq!(mean(&[1.0, 2.0, 4.0]), 7.0 / 3.0);
        // Batch means fine, but the weighted sum of them overflows.
        let huge = [1.0e308, 1.01e308, 1.02e308, 1.1e308, 1.11e308, 1.12e308];
        assert_eq!(fuse(&huge, 2), Err(FusionError::NotRepresentable));
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&[5.0, 1.0, 3.0]), 3.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 10.0]), 3.5);
        assert_eq!(median(&[2.0, 8.0]), 5.0);
        assert_eq!(median(&[7.0]), 7.0);
    }

    #[test]
    fn the_floor_is_a_hundredth_of_the_median_standard_error() {
        assert_eq!(consistency_floor(&[]), 0.0);
        assert_eq!(consistency_floor(&[4.0, 1.0, 3.0]), 0.03);
        assert_eq!(consistency_floor(&[2.0, 6.0]), 0.04);
    }

    #[test]
    fn a_batch_below_the_floor_is_weighed_at_the_floor() {
        // Batch 0: [1, 1 + 2e-6], s = √2·1e-6; batch 1: [3, 5], s = √2.
        // Unfloored, batch 0 takes all the weight (ratio 1e12).
        let xs = [1.0, 1.000_002, 3.0, 5.0];
        let plain = fuse(&xs, 2).unwrap();
        assert!((plain.value - 1.000_001).abs() < 1e-9);
        // Floored at √2: equal weights, x⁺ = (1.000001 + 4)/2, SE = √2/√(2 + 2).
        let floor = 2f64.sqrt();
        let f = fuse_with_floor(&xs, 2, floor).unwrap();
        assert!((f.value - 2.500_000_5).abs() < 1e-12, "{}", f.value);
        assert!((f.std_error - floor / 2.0).abs() < 1e-12);
        assert_eq!(
            f.batches[0].std, plain.batches[0].std,
            "s_p is reported as is"
        );
        // A floor below every deviation changes nothing.
        assert_eq!(fuse_with_floor(&xs, 2, 1e-9).unwrap(), plain);
    }

    #[test]
    fn dispersion_is_eq_8() {
        let d = dispersion(&[1.0, 2.0, 3.0], 2.0).unwrap();
        assert_eq!(d.absolute, 1.0);
        assert_eq!(d.relative, Some(0.5));
        assert_eq!(dispersion(&[1.0, -1.0], 0.0).unwrap().relative, None);
        assert_eq!(dispersion(&[1.0], 1.0), None);
    }
}
