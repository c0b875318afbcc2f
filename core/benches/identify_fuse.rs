//! Criterion benchmark: identify + fuse the paper's six-run submission, and
//! the quality flags and uncertainty budget computed beside it.

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
    use accelcal_core::quality::assess;
    use accelcal_core::uncertainty::{ARCSEC, Stand, budget};
    let test = paper::paper_tumble();
    let cal = test.calibrate(2).unwrap();
    let stand = Stand {
        angle_std_rad: 2.0 * ARCSEC,
        gravity_rel_std: 1e-5,
    };
    c.bench_function("paper six runs: quality flags + uncertainty budget", |b| {
        b.iter(|| {
            let q = assess(black_box(&test), black_box(&cal));
            let model = model_uncertainty(&test, &q.lack_of_fit);
            black_box(
                budget(
                    &test,
                    &cal.fused.coefficients,
                    &cal.fused.std_errors,
                    stand,
                    2.0,
                    &model,
                )
                .unwrap(),
            )
        })
    });
}

criterion_group!(benches, identify_and_fuse, quality_and_budget);
criterion_main!(benches);
