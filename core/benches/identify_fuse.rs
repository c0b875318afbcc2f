//! Criterion benchmark: identify + fuse the paper's six-run submission, and
//! the quality flags and uncertainty budget computed beside it; a triad
//! from 24 known orientations, and one Levenberg–Marquardt solve for a
//! triad of unknown orientations from 40 positions (issue 30).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};

use accelcal_paper as paper;

fn identify_and_fuse(c: &mut Criterion) {
    let test = paper::paper_tumble();
    c.bench_function("paper six runs: identify + fuse (2 batches)", |b| {
        b.iter(|| black_box(&test).calibrate(black_box(2)).unwrap())
    });
    c.bench_function(
        "paper six runs: validate + factorise + identify + fuse",
        |b| {
            b.iter(|| {
                let t = accelcal_core::TumbleTest::new(
                    test.model().clone(),
                    test.positions().to_vec(),
                    test.runs().to_vec(),
                )
                .unwrap();
                black_box(t.calibrate(2).unwrap())
            })
        },
    );
}

/// What a submission adds beside the numbers: the quality flags (lack of
/// fit, noisy runs, batch floors, unmodelled-term tests: one more
/// factorisation per candidate term) and the uncertainty budget.
fn quality_and_budget(c: &mut Criterion) {
    use accelcal_core::adequacy::model_uncertainty;
    use accelcal_core::coverage::Coverage;
    use accelcal_core::quality::assess;
    use accelcal_core::uncertainty::{ARCSEC, Stand, budget};
    let test = paper::paper_tumble();
    let cal = test.calibrate(2).unwrap();
    let stand = Stand {
        angle_std_rad: 2.0 * ARCSEC,
        gravity_rel_std: 1e-5,
        ..Stand::default()
    };
    c.bench_function("paper six runs: quality flags + uncertainty budget", |b| {
        b.iter(|| {
            let q = assess(black_box(&test), black_box(&cal));
            let model = model_uncertainty(&test, &q.lack_of_fit);
            black_box(
                budget(
                    &test,
                    &cal.fused.coefficients,
                    (&cal.fused.std_errors, &cal.fused.dof),
                    stand,
                    Coverage::default(),
                    &model,
                )
                .unwrap(),
            )
        })
    });
}

/// A triad with every element of `S` distinct: its outputs at `g`, with a
/// small deterministic scatter `e`.
fn triad_outputs(g: [f64; 3], e: f64) -> [f64; 3] {
    let b = [0.12, -0.21, 0.053];
    let s = [
        [9.81, 0.031, -0.022],
        [0.014, 9.79, 0.043],
        [-0.035, 0.027, 9.83],
    ];
    [0, 1, 2].map(|m| b[m] + (0..3).map(|k| s[m][k] * g[k]).sum::<f64>() + e)
}

fn triads(c: &mut Criterion) {
    use accelcal_core::gravity_fit::fit;
    use accelcal_core::triad::{TriadRun, TriadTest, six_faces};
    // The 24 orientations of a cube (each face up, four turns about the
    // vertical), four runs of two samples, fused in two batches.
    let positions: Vec<[f64; 3]> = six_faces()
        .into_iter()
        .flat_map(|g| std::iter::repeat_n(g, 4))
        .collect();
    let runs: Vec<TriadRun> = (0..4)
        .map(|j| TriadRun {
            samples: positions
                .iter()
                .enumerate()
                .map(|(p, g)| {
                    (0..2)
                        .map(|k| triad_outputs(*g, 1e-3 * ((j * 97 + p * 13 + k * 7) as f64).sin()))
                        .collect()
                })
                .collect(),
        })
        .collect();
    c.bench_function(
        "triad, 24 orientations x 4 runs: validate + identify + fuse",
        |b| {
            b.iter(|| {
                let t = TriadTest::new(black_box(&positions), black_box(&runs)).unwrap();
                black_box(t.calibrate(2).unwrap())
            })
        },
    );
    // 40 positions of unknown orientation along a golden-angle spiral.
    let means: Vec<[f64; 3]> = (0..40)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / 40.0;
            let r = (1.0 - z * z).sqrt();
            let a = k as f64 * 2.399_963_229_728_653;
            triad_outputs([r * a.cos(), r * a.sin(), z], 1e-3 * (k as f64 * 1.7).sin())
        })
        .collect();
    c.bench_function(
        "triad, 40 positions of unknown orientation: ellipsoid + Levenberg-Marquardt",
        |b| b.iter(|| black_box(fit(black_box(&means)).unwrap())),
    );
}

criterion_group!(benches, identify_and_fuse, quality_and_budget, triads);
criterion_main!(benches);
