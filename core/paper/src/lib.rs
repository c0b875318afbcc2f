//! The paper's tables as data, and a check of a value against a figure
//! printed to a given number of digits: shared by accelcal-core's tests and
//! its benchmarks (a crate of its own, so that neither includes the other's
//! files).

use accelcal_core::{Model, Mount, Position, Run, TumbleTest};

/// Table 1 of the paper: `(test, angle_deg, [a_i, a_p, a_o], direction, output)`.
pub fn table1() -> Vec<(usize, f64, [f64; 3], String, f64)> {
    include_str!("../../tests/data/table1.csv")
        .lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let num = |k: usize| f[k].parse::<f64>().unwrap();
            (
                f[0].parse().unwrap(),
                num(1),
                [num(2), num(3), num(4)],
                f[5].to_owned(),
                num(6),
            )
        })
        .collect()
}

/// Table 2 of the paper: per-test `(K0, K1, α)`.
pub fn table2() -> Vec<[f64; 3]> {
    include_str!("../../tests/data/table2.csv")
        .lines()
        .skip(1)
        .map(|line| {
            let f: Vec<f64> = line
                .split(',')
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            [f[0], f[1], f[2]]
        })
        .collect()
}

/// The paper's six tests as a tumble test: positions from the table's angles
/// (pendulum mount), each run's cw and ccw outputs as the samples.
pub fn paper_tumble() -> TumbleTest {
    let rows = table1();
    let angles = [0.0, 90.0, 180.0, 270.0];
    let positions = angles
        .iter()
        .map(|d| Position::from_angle(*d, Mount::Pendulum, None))
        .collect();
    let runs = (1..=6)
        .map(|test| {
            Run::from_samples(
                angles
                    .iter()
                    .map(|d| {
                        rows.iter()
                            .filter(|r| r.0 == test && r.1 == *d)
                            .map(|r| r.4)
                            .collect()
                    })
                    .collect(),
            )
        })
        .collect();
    TumbleTest::new(Model::pendulum(), positions, runs).unwrap()
}

/// Asserts that `value` rounds to `printed` at the printed precision: the
/// difference is at most half a unit in the last printed digit.
#[track_caller]
pub fn assert_printed(value: f64, printed: &str) {
    let target: f64 = printed.parse().unwrap();
    let (mantissa, exponent) = match printed.find(['e', 'E']) {
        Some(k) => (&printed[..k], printed[k + 1..].parse::<i32>().unwrap()),
        None => (printed, 0),
    };
    let decimals = mantissa.split('.').nth(1).map_or(0, str::len) as i32;
    let half_unit = 0.5 * 10f64.powi(exponent - decimals);
    assert!(
        (value - target).abs() <= half_unit * (1.0 + 1e-9),
        "{value:e} does not round to the printed {printed} (±{half_unit:e})"
    );
}
