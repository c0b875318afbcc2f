//! Static intervals in a continuous triad recording (issue 30, item 3).
//!
//! A station may record a triad while turning it by hand between still
//! orientations. The detector (after Tedaldi, Pretto and Menegatti, ICRA
//! 2014) compares the moving variance of the outputs with their variance
//! during an initial still period:
//!
//! ```text
//! σ²_init = Σ_m var(u_m over the first `still_s` seconds)
//! v(t)    = Σ_m var(u_m over the `window_s` window centred on sample t)
//! static(t)  ⇔  v(t) ≤ k · σ²_init
//! ```
//!
//! and takes each maximal run of static samples as an interval. An interval
//! shorter than `min_static_s` is rejected (a pause in the motion, not a
//! held orientation); the others are the positions, each the mean of its
//! samples — the initial still period is itself the first. A window that
//! straddles a rotation sees its variance, so an interval's edges stay half
//! a window clear of the motion — an interval lasts about one window less
//! than the hold, so a hold of `min_static_s + window_s` seconds is the
//! shortest kept. The defaults ([`Detector::default`]):
//! `still_s` 3 s, `window_s` 1 s, `k` 6, `min_static_s` 2 s.

/// The detector's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detector {
    /// Length of the initial still period, s.
    pub still_s: f64,
    /// Width of the moving-variance window, s.
    pub window_s: f64,
    /// The threshold as a multiple `k` of the initial period's variance.
    pub threshold: f64,
    /// The shortest interval used, s.
    pub min_static_s: f64,
}

impl Default for Detector {
    fn default() -> Self {
        Detector {
            still_s: 3.0,
            window_s: 1.0,
            threshold: 6.0,
            min_static_s: 2.0,
        }
    }
}

/// Why an interval was not used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rejection {
    /// Shorter than `min_static_s`.
    TooShort,
}

/// One static interval.
#[derive(Debug, Clone, PartialEq)]
pub struct Interval {
    /// Its first sample.
    pub start: usize,
    /// One past its last sample.
    pub end: usize,
    /// The mean of its samples.
    pub mean: [f64; 3],
    /// Why it was not used, if it was not.
    pub rejected: Option<Rejection>,
}

/// What the detector found.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// `σ²_init`, in the outputs' unit squared.
    pub still_variance: f64,
    /// The variance threshold `k·σ²_init`.
    pub threshold_variance: f64,
    /// Every static interval, in time order.
    pub intervals: Vec<Interval>,
}

impl Detection {
    /// The used intervals' means: the positions.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.intervals
            .iter()
            .filter(|i| i.rejected.is_none())
            .map(|i| i.mean)
            .collect()
    }
}

/// Why a recording cannot be searched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectError {
    /// The rate or a parameter is not a positive finite number.
    #[error("`{name}` must be a positive number")]
    Parameter {
        /// Which.
        name: &'static str,
    },
    /// The recording is shorter than the initial still period plus a window.
    #[error(
        "the recording lasts {seconds:.2} s: it must hold at least the initial still period \
         ({still_s} s) and one window"
    )]
    TooShort {
        /// Its length.
        seconds: f64,
        /// The still period asked for.
        still_s: f64,
    },
    /// A sample is not finite.
    #[error("sample {index}: its outputs are not all finite numbers")]
    NotFinite {
        /// The sample, from 0.
        index: usize,
    },
}

/// Sums of a window's samples and squares, per axis, taken about the first
/// sample (so that the squares do not swamp the variance).
struct Prefix {
    sum: Vec<[f64; 3]>,
    sq: Vec<[f64; 3]>,
}

impl Prefix {
    fn new(samples: &[[f64; 3]]) -> Prefix {
        let origin = samples[0];
        let mut sum = vec![[0.0; 3]; samples.len() + 1];
        let mut sq = vec![[0.0; 3]; samples.len() + 1];
        for (i, u) in samples.iter().enumerate() {
            for m in 0..3 {
                let x = u[m] - origin[m];
                sum[i + 1][m] = sum[i][m] + x;
                sq[i + 1][m] = sq[i][m] + x * x;
            }
        }
        Prefix { sum, sq }
    }

    /// `Σ_m var(u_m)` over samples `[a, b)`, `b − a ≥ 2`.
    fn variance(&self, a: usize, b: usize) -> f64 {
        let n = (b - a) as f64;
        (0..3)
            .map(|m| {
                let s = self.sum[b][m] - self.sum[a][m];
                let q = self.sq[b][m] - self.sq[a][m];
                ((q - s * s / n) / (n - 1.0)).max(0.0)
            })
            .sum()
    }
}

/// The least variance threshold: a noiseless recording's still variance is
/// zero, so allow the rounding of the running sums, `10⁻¹²` of the square
/// of the recording's range about its first sample.
fn floor(samples: &[[f64; 3]]) -> f64 {
    let origin = samples[0];
    let range = samples
        .iter()
        .flat_map(|u| (0..3).map(move |m| (u[m] - origin[m]).abs()))
        .fold(0.0f64, f64::max);
    1e-12 * range * range
}

/// Finds the static intervals of a recording at `rate_hz`.
pub fn detect(rate_hz: f64, samples: &[[f64; 3]], d: &Detector) -> Result<Detection, DetectError> {
    for (name, v) in [
        ("rate_hz", rate_hz),
        ("still_s", d.still_s),
        ("window_s", d.window_s),
        ("threshold", d.threshold),
        ("min_static_s", d.min_static_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(DetectError::Parameter { name });
        }
    }
    if let Some(index) = samples
        .iter()
        .position(|u| u.iter().any(|x| !x.is_finite()))
    {
        return Err(DetectError::NotFinite { index });
    }
    let window = ((d.window_s * rate_hz).round() as usize).max(2);
    let still = ((d.still_s * rate_hz).round() as usize).max(2);
    if samples.len() < still + window {
        return Err(DetectError::TooShort {
            seconds: samples.len() as f64 / rate_hz,
            still_s: d.still_s,
        });
    }
    let prefix = Prefix::new(samples);
    let still_variance = prefix.variance(0, still);
    let threshold_variance = (d.threshold * still_variance).max(floor(samples));
    let half = window / 2;
    let n = samples.len();
    let quiet: Vec<bool> = (0..n)
        .map(|t| {
            let a = t.saturating_sub(half).min(n - window);
            prefix.variance(a, a + window) <= threshold_variance
        })
        .collect();
    let min_len = (d.min_static_s * rate_hz).round() as usize;
    let mut intervals = Vec::new();
    let mut start = 0;
    for run in quiet.chunk_by(|a, b| a == b) {
        let end = start + run.len();
        if run[0] {
            let count = run.len() as f64;
            let mut mean = [0.0; 3];
            for u in &samples[start..end] {
                for m in 0..3 {
                    mean[m] += u[m] / count;
                }
            }
            intervals.push(Interval {
                start,
                end,
                mean,
                rejected: (run.len() < min_len).then_some(Rejection::TooShort),
            });
        }
        start = end;
    }
    Ok(Detection {
        still_variance,
        threshold_variance,
        intervals,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const RATE: f64 = 100.0;

    /// A recording: holds of `seconds` at `directions` (outputs `b + s·g`),
    /// joined by rotations of 1.5 s along the great circle, with noise.
    fn recording(holds: &[([f64; 3], f64)]) -> (Vec<[f64; 3]>, Vec<(usize, usize)>) {
        let (b, s) = ([0.02, -0.01, 0.03], 1.01);
        let noise = Normal::new(0.0, 1e-3).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let mut out = Vec::new();
        let mut planted = Vec::new();
        let at = |g: [f64; 3]| [0, 1, 2].map(|m| b[m] + s * g[m]);
        for (k, (g, seconds)) in holds.iter().enumerate() {
            if k > 0 {
                let from = holds[k - 1].0;
                let steps = (1.5 * RATE) as usize;
                for i in 0..steps {
                    let f = i as f64 / steps as f64;
                    let v = [0, 1, 2].map(|m| from[m] * (1.0 - f) + g[m] * f);
                    let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    out.push(at(v.map(|x| x / norm)));
                }
            }
            let start = out.len();
            for _ in 0..(seconds * RATE) as usize {
                out.push(at(*g));
            }
            planted.push((start, out.len()));
        }
        for u in out.iter_mut() {
            for x in u.iter_mut() {
                *x += noise.sample(&mut rng);
            }
        }
        (out, planted)
    }

    fn holds() -> Vec<([f64; 3], f64)> {
        let r = std::f64::consts::FRAC_1_SQRT_2;
        vec![
            ([0.0, 0.0, 1.0], 6.0),
            ([1.0, 0.0, 0.0], 4.0),
            ([0.0, 1.0, 0.0], 4.0),
            ([r, r, 0.0], 1.0),
            ([-1.0, 0.0, 0.0], 4.0),
            ([0.0, -1.0, 0.0], 4.0),
            ([0.0, 0.0, -1.0], 4.0),
            ([r, 0.0, r], 3.0),
        ]
    }

    #[test]
    fn the_planted_intervals_are_found() {
        let (samples, planted) = recording(&holds());
        let found = detect(RATE, &samples, &Detector::default()).unwrap();
        assert_eq!(found.intervals.len(), planted.len(), "{found:?}");
        let half = (0.5 * RATE) as usize + 1;
        for (i, (f, p)) in found.intervals.iter().zip(&planted).enumerate() {
            // Within half a window of the planted hold, never into the motion.
            assert!(f.start >= p.0 && f.start <= p.0 + half, "{i}: {f:?} {p:?}");
            assert!(f.end <= p.1 && f.end + half >= p.1, "{i}: {f:?} {p:?}");
        }
        // The 1 s hold is found and rejected; the rest are the positions.
        let rejected: Vec<usize> = found
            .intervals
            .iter()
            .enumerate()
            .filter(|(_, i)| i.rejected == Some(Rejection::TooShort))
            .map(|(k, _)| k)
            .collect();
        assert_eq!(rejected, [3]);
        let positions = found.positions();
        assert_eq!(positions.len(), 7);
        // The first position is the initial still period, z up.
        let first = positions[0];
        assert!((first[2] - (0.03 + 1.01)).abs() < 1e-3, "{first:?}");
        assert!((first[0] - 0.02).abs() < 1e-3);
        // The second, x up: b + 1.01 (1, 0, 0).
        assert!((positions[1][0] - 1.03).abs() < 1e-3, "{:?}", positions[1]);
        assert!((positions[1][2] - 0.03).abs() < 1e-3);
        // σ²_init is the planted noise's: 3 × (1e-3)².
        assert!((found.still_variance / 3e-6 - 1.0).abs() < 0.2);
        assert_eq!(found.threshold_variance, 6.0 * found.still_variance);
    }

    #[test]
    fn a_longer_minimum_rejects_more() {
        let (samples, _) = recording(&holds());
        let strict = Detector {
            min_static_s: 2.7,
            ..Detector::default()
        };
        let found = detect(RATE, &samples, &strict).unwrap();
        assert_eq!(found.positions().len(), 6, "the 3 s hold is rejected too");
    }

    /// Still until sample 500, a ramp on x to sample 599, still from 600.
    fn step() -> Vec<[f64; 3]> {
        let mut samples = vec![[0.0, 0.0, 1.0]; 500];
        samples.extend((0..100).map(|i| [f64::from(i) / 100.0, 0.0, 1.0]));
        samples.extend(vec![[1.0, 0.0, 1.0]; 300]);
        samples
    }

    #[test]
    fn interval_edges_are_half_a_window_from_the_motion() {
        // Window 100 samples: sample t's window is [t − 50, t + 50). The
        // ramp's first change is sample 501 (sample 500 is still 0): quiet
        // while t + 50 ≤ 501, so the first interval is [0, 452); the last
        // windows to see sample 599 end at t = 649, so the second is
        // [650, 900).
        let found = detect(RATE, &step(), &Detector::default()).unwrap();
        assert_eq!(found.still_variance, 0.0);
        let edges: Vec<(usize, usize)> = found.intervals.iter().map(|i| (i.start, i.end)).collect();
        assert_eq!(edges, [(0, 452), (650, 900)]);
        let mean = found.intervals[1].mean;
        assert!((mean[0] - 1.0).abs() < 1e-12 && mean[1] == 0.0 && (mean[2] - 1.0).abs() < 1e-12);
        // 250 samples: kept at a minimum of exactly 2.5 s, rejected above.
        let at = |min_static_s| Detector {
            min_static_s,
            ..Detector::default()
        };
        let kept = detect(RATE, &step(), &at(2.5)).unwrap();
        assert_eq!(kept.intervals[1].rejected, None);
        let rejected = detect(RATE, &step(), &at(2.51)).unwrap();
        assert_eq!(rejected.intervals[1].rejected, Some(Rejection::TooShort));
    }

    #[test]
    fn the_still_variance_is_the_sample_variance_summed_over_the_axes() {
        let (samples, _) = recording(&holds());
        let found = detect(RATE, &samples, &Detector::default()).unwrap();
        // Two-pass sample variance of the first 3 s, independently.
        let first = &samples[..300];
        let want: f64 = (0..3)
            .map(|m| {
                let mean = first.iter().map(|u| u[m]).sum::<f64>() / 300.0;
                first.iter().map(|u| (u[m] - mean).powi(2)).sum::<f64>() / 299.0
            })
            .sum();
        assert!((found.still_variance / want - 1.0).abs() < 1e-9);
    }

    #[test]
    fn the_floor_is_a_millionth_of_the_range_squared() {
        assert_eq!(
            floor(&[[1.0, 2.0, 3.0], [1.0, 4.0, 3.0], [0.0, 2.0, 3.5]]),
            4e-12
        );
        assert_eq!(floor(&[[5.0, 5.0, 5.0]; 3]), 0.0);
    }

    #[test]
    fn the_shortest_recording_is_the_still_period_and_one_window() {
        // 300 samples of still period and a window of 100: 400 is enough.
        let found = detect(RATE, &[[0.0, 0.0, 1.0]; 400], &Detector::default()).unwrap();
        assert_eq!(found.intervals.len(), 1);
        assert_eq!((found.intervals[0].start, found.intervals[0].end), (0, 400));
    }

    #[test]
    fn bad_recordings_are_refused() {
        let d = Detector::default();
        assert_eq!(
            detect(0.0, &[[0.0; 3]; 1000], &d),
            Err(DetectError::Parameter { name: "rate_hz" })
        );
        let bad = Detector {
            window_s: -1.0,
            ..d
        };
        assert_eq!(
            detect(RATE, &[[0.0; 3]; 1000], &bad),
            Err(DetectError::Parameter { name: "window_s" })
        );
        assert_eq!(
            detect(RATE, &[[0.0; 3]; 350], &d),
            Err(DetectError::TooShort {
                seconds: 3.5,
                still_s: 3.0
            })
        );
        let mut nan = vec![[0.0; 3]; 1000];
        nan[17][2] = f64::INFINITY;
        assert_eq!(
            detect(RATE, &nan, &d),
            Err(DetectError::NotFinite { index: 17 })
        );
    }
}
