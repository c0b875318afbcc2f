//! Criterion benchmark: identify + fuse the paper's six-run submission.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};

#[path = "../tests/suite/common/mod.rs"]
mod common;

fn identify_and_fuse(c: &mut Criterion) {
    let test = common::paper_tumble();
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

criterion_group!(benches, identify_and_fuse);
criterion_main!(benches);
