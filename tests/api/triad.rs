//! Triads through the API (issue 30): `POST /v1/identify/triad` from known
//! orientations, from static positions of unknown orientation and from a
//! recording; each against synthetic triads with known `b`, `S` and `T`,
//! the known-orientation rows against three single-axis identifications
//! bit for bit, every refusal, and the exports.

use reqwest::StatusCode;
use reqwest::header::CONTENT_TYPE;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

/// `b` and `S` with every element distinct, in m/s² and m/s² per g.
pub(crate) fn truth() -> ([f64; 3], [[f64; 3]; 3]) {
    (
        [0.12, -0.21, 0.053],
        [
            [9.81, 0.031, -0.022],
            [0.014, 9.79, 0.043],
            [-0.035, 0.027, 9.83],
        ],
    )
}

fn outputs(g: [f64; 3]) -> [f64; 3] {
    let (b, s) = truth();
    [0, 1, 2].map(|m| b[m] + (0..3).map(|k| s[m][k] * g[k]).sum::<f64>())
}

/// A deterministic scatter in [−1, 1].
fn wobble(k: usize) -> f64 {
    ((k as f64) * 12.9898).sin() * 0.5 + ((k as f64) * 78.233).cos() * 0.5
}

/// Standard normal draws, reproducible: xorshift64* and Box–Muller.
struct Gauss(u64);

impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

pub(crate) fn faces() -> Vec<[f64; 3]> {
    vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ]
}

/// Six runs on the six faces, two samples a position, scattered by 2e-3.
/// The detail of the one refusal of `recording`, at `/recording` (422).
pub(crate) async fn recording_refused(app: &TestApp, recording: Value) -> String {
    let p = problem(
        triad(app, &json!({ "recording": recording })).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/recording"], "{p}");
    p["errors"][0]["detail"].as_str().unwrap().to_owned()
}

pub(crate) fn known_body() -> Value {
    let runs: Vec<Value> = (0..6)
        .map(|j| {
            let samples: Vec<Value> = faces()
                .iter()
                .enumerate()
                .map(|(p, g)| {
                    let u = outputs(*g);
                    let s = |k: usize| {
                        [0, 1, 2].map(|m| u[m] + 2e-3 * wobble(1 + j * 100 + p * 10 + k * 3 + m))
                    };
                    json!([s(0), s(1)])
                })
                .collect();
            json!({ "samples": samples })
        })
        .collect();
    json!({"sensor_id": "IMU-7", "unit": "m/s2", "orientations": "six_faces", "runs": runs, "batches": 2})
}

pub(crate) async fn triad(app: &TestApp, body: &Value) -> reqwest::Response {
    app.post("/v1/identify/triad", ADMIN, body).await
}

pub(crate) fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

#[tokio::test]
async fn known_orientations_give_b_and_s_and_each_row_is_a_single_axis_identification() {
    let app = TestApp::spawn(Sqlite).await;
    let mut body = known_body();
    let stand = json!({"angle_std_arcsec": 30.0, "gravity_rel_std": 2e-5});
    body["stand"] = stand.clone();
    let res = triad(&app, &body).await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["method"], "known_orientations");
    assert_eq!(r["model"], "u = b + S g");
    let (b, s) = truth();
    for m in 0..3 {
        let se = f(&r["b_std_errors"][m]);
        assert!(se > 0.0);
        assert!((f(&r["b"][m]) - b[m]).abs() < 4.0 * se + 1e-12, "b{m}");
        for k in 0..3 {
            let se = f(&r["S_std_errors"][m][k]);
            assert!(se > 0.0);
            assert!((f(&r["S"][m][k]) - s[m][k]).abs() < 4.0 * se, "S{m}{k}");
        }
    }
    // T is S's inverse; the scale factors are the rows' norms.
    for i in 0..3 {
        for j in 0..3 {
            let p: f64 = (0..3).map(|k| f(&r["T"][i][k]) * f(&r["S"][k][j])).sum();
            assert!((p - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
        }
        let norm = (0..3).map(|k| f(&r["S"][i][k]).powi(2)).sum::<f64>().sqrt();
        assert_eq!(f(&r["scale_factors"][i]), norm);
    }
    // Non-orthogonality of x and y: 90° minus the angle between the rows.
    let dot: f64 = (0..3).map(|k| f(&r["S"][0][k]) * f(&r["S"][1][k])).sum();
    let want = 90.0
        - (dot / (f(&r["scale_factors"][0]) * f(&r["scale_factors"][1])))
            .acos()
            .to_degrees();
    assert!((f(&r["non_orthogonality_deg"][0]) - want).abs() < 1e-12);

    // Each row is what the single-axis method gives for that axis, with
    // positions (a_i, a_p, a_o) = (g_m, g_m+1, g_m+2): bit for bit.
    for m in 0..3 {
        let positions: Vec<Value> = faces()
            .iter()
            .map(|g| json!({"a": [g[m], g[(m + 1) % 3], g[(m + 2) % 3]]}))
            .collect();
        let runs: Vec<Value> = body["runs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|run| {
                let readings: Vec<Value> = run["samples"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|at| {
                        json!(
                            at.as_array()
                                .unwrap()
                                .iter()
                                .map(|u| u[m].clone())
                                .collect::<Vec<_>>()
                        )
                    })
                    .collect();
                json!({ "readings": readings })
            })
            .collect();
        let single = json!({
            "sensor_id": format!("IMU-7-{m}"), "performed_at": "2026-06-01T00:00:00Z", "unit": "m/s2",
            "model": ["k0", "ki", "kp", "ko"], "positions": positions, "runs": runs, "batches": 2,
            "stand": stand
        });
        let one = app.post("/v1/identify", ADMIN, &single).await;
        assert_eq!(one.status(), StatusCode::OK);
        let one: Value = one.json().await.unwrap();
        let c = &one["fused"]["coefficients"];
        assert_eq!(r["b"][m], c["k0"], "axis {m}");
        assert_eq!(r["S"][m][m], c["ki"]);
        assert_eq!(r["S"][m][(m + 1) % 3], c["kp"]);
        assert_eq!(r["S"][m][(m + 2) % 3], c["ko"]);
        assert_eq!(r["axes"][m]["fused"]["coefficients"], *c);
        assert_eq!(r["S_std_errors"][m][m], one["fused"]["std_errors"]["ki"]);
        // …and so are its uncertainty budget (with the same stand) and its
        // quality warnings; b's and S's expanded uncertainties are the
        // budget's, element by element.
        assert_eq!(r["axes"][m]["uncertainty"], one["uncertainty"], "axis {m}");
        assert_eq!(r["axes"][m]["quality"], one["quality"], "axis {m}");
        let u = |t: &str| one["uncertainty"]["terms"][t]["expanded"].clone();
        assert_eq!(r["b_expanded"][m], u("k0"));
        assert_eq!(r["S_expanded"][m][m], u("ki"));
        assert_eq!(r["S_expanded"][m][(m + 1) % 3], u("kp"));
        assert_eq!(r["S_expanded"][m][(m + 2) % 3], u("ko"));
        assert!(
            f(&u("ki")) > 2.0 * f(&one["fused"]["std_errors"]["ki"]),
            "the stand counts"
        );
        // Each element's coverage is that term's, as the single axis states it.
        let axis = ["x", "y", "z"][m];
        for (term, name) in [
            ("k0", format!("b_{axis}")),
            ("ki", format!("S_{axis}{axis}")),
        ] {
            let b = &one["uncertainty"]["terms"][term];
            let c = &r["coverage"][&name];
            assert_eq!(
                (
                    &c["combined"],
                    &c["effective_dof"],
                    &c["coverage_factor"],
                    &c["coverage_probability"]
                ),
                (
                    &b["combined"],
                    &b["effective_dof"],
                    &b["coverage_factor"],
                    &b["coverage_probability"]
                ),
                "{name}"
            );
        }
    }
    assert_eq!(
        (&r["coverage_probability"], &r["coverage_factor"]),
        (&json!(0.9545), &Value::Null)
    );

    // Exports: PX4 carries b and T's diagonal; json and c carry T whole.
    let res = app
        .post("/v1/identify/triad?export=px4", ADMIN, &body)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.headers()[CONTENT_TYPE], "text/plain; charset=utf-8");
    let px4 = res.text().await.unwrap();
    assert!(
        px4.contains(&format!("1\t1\tCAL_ACC0_XOFF\t{:.9}\t9", f(&r["b"][0]))),
        "{px4}"
    );
    let scale = 9.80665 * f(&r["T"][2][2]);
    assert!(
        px4.contains(&format!("CAL_ACC0_ZSCALE\t{scale:.9}\t9")),
        "{px4}"
    );
    assert!(px4.contains("NOT CARRIED"));
    let res = app
        .post("/v1/identify/triad?export=json", ADMIN, &body)
        .await;
    let exported: Value = res.json().await.unwrap();
    assert_eq!(exported["T"], r["T"]);
    assert_eq!(exported["compensation"], "g = T (u - b), T = S^-1");
    let c = app
        .post("/v1/identify/triad?export=c", ADMIN, &body)
        .await
        .text()
        .await
        .unwrap();
    assert!(c.contains(&format!("{:.12e}", f(&r["T"][0][1]))));
    let p = problem(
        app.post("/v1/identify/triad?export=csv", ADMIN, &body)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("export"), "{p}");
    let mut lsb = body.clone();
    lsb["unit"] = json!("LSB");
    let p = problem(
        app.post("/v1/identify/triad?export=ardupilot", ADMIN, &lsb)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("m/s²"), "{p}");
}

/// Directions spread over the sphere (a golden-angle spiral).
pub(crate) fn spiral(n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = k as f64 * 2.399_963_229_728_653;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// `b` and lower-triangular `T`, and outputs `b + T⁻¹ g` by forward
/// substitution.
fn lower() -> ([f64; 3], [[f64; 3]; 3]) {
    (
        [0.021, -0.034, 0.051],
        [
            [1.02, 0.0, 0.0],
            [0.013, 0.985, 0.0],
            [-0.021, 0.008, 1.011],
        ],
    )
}

fn lower_outputs(g: [f64; 3]) -> [f64; 3] {
    let (b, t) = lower();
    let x0 = g[0] / t[0][0];
    let x1 = (g[1] - t[1][0] * x0) / t[1][1];
    let x2 = (g[2] - t[2][0] * x0 - t[2][1] * x1) / t[2][2];
    [x0 + b[0], x1 + b[1], x2 + b[2]]
}

/// The planted `S = T⁻¹` of [`lower`], column `k` being the outputs at
/// `g = e_k` less `b` (forward substitution, not the service's inverse).
pub(crate) fn lower_s() -> [[f64; 3]; 3] {
    let (b, _) = lower();
    let columns = [0, 1, 2].map(|k| {
        let mut e = [0.0; 3];
        e[k] = 1.0;
        lower_outputs(e)
    });
    [0, 1, 2].map(|m| [0, 1, 2].map(|k| columns[k][m] - b[m]))
}

/// Static positions of the [`lower`] triad at `n` spiral directions, three
/// samples each scattered by 2e-4 g, in g.
pub(crate) fn gravity_positions(n: usize, seed: u64) -> Value {
    positions_at(&spiral(n), seed)
}

/// Static positions of the [`lower`] triad at `dirs`, three samples each
/// scattered by 2e-4 g, in g.
pub(crate) fn positions_at(dirs: &[[f64; 3]], seed: u64) -> Value {
    let mut noise = Gauss(seed);
    json!(
        dirs.iter()
            .map(|g| {
                let g = *g;
                let u = lower_outputs(g);
                (0..3)
                    .map(|_| [0, 1, 2].map(|m| u[m] + 2e-4 * noise.next()))
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    )
}

#[tokio::test]
async fn unknown_orientations_give_b_and_t_within_their_standard_errors() {
    let app = TestApp::spawn(Sqlite).await;
    let positions = gravity_positions(30, 0x9e37_79b9_7f4a_7c15);
    let gravity_rel_std = 5e-5;
    let res = triad(
        &app,
        &json!({"unit": "g", "static_positions": positions,
            "stand": {"gravity_rel_std": gravity_rel_std}}),
    )
    .await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["method"], "gravity_magnitude");
    assert_eq!(r["fit"]["degrees_of_freedom"], 21);
    let (b, t) = lower();
    // S = T⁻¹ within its standard errors (propagated from T's covariance);
    // above the diagonal zero by the convention, with a zero error.
    let s = lower_s();
    for m in 0..3 {
        for k in 0..3 {
            let se = f(&r["S_std_errors"][m][k]);
            if k <= m {
                assert!(
                    se > 0.0 && (f(&r["S"][m][k]) - s[m][k]).abs() < 4.0 * se,
                    "S{m}{k}: {} vs {} ± {se}",
                    r["S"][m][k],
                    s[m][k]
                );
            } else {
                assert_eq!((f(&r["S"][m][k]), se), (0.0, 0.0), "S{m}{k}");
            }
        }
    }
    // The budget, element by element: the fit's standard error and the
    // gravity's u·|S_ij| (none on b), combined in quadrature, k = 2.
    let u = &r["uncertainty"];
    assert_eq!(
        (&u["coverage_probability"], &u["coverage_factor"]),
        (&json!(0.9545), &Value::Null)
    );
    assert_eq!(u["degrees_of_freedom"], 21);
    assert_eq!(u["gravity_rel_std"], gravity_rel_std);
    assert_eq!(u["fixed_by_convention"], json!(["S_xy", "S_xz", "S_yz"]));
    let axes = ["x", "y", "z"];
    let elements = u["elements"].as_object().unwrap();
    assert_eq!(elements.len(), 9, "b and S on and below the diagonal");
    for m in 0..3 {
        let e = &elements[&format!("b_{}", axes[m])];
        assert_eq!(f(&e["statistical"]), f(&r["b_std_errors"][m]));
        assert_eq!(
            (f(&e["gravity"]), f(&e["indexing"]), f(&e["model"])),
            (0.0, 0.0, 0.0)
        );
        assert_eq!(f(&e["expanded"]), f(&r["b_expanded"][m]));
        // b: the fit's standard error alone, on its 21 degrees of freedom:
        // scipy's t.ppf(0.97725, 21).
        assert_eq!(e["effective_dof"], 21);
        let k21 = 2.126_313_380_035_578;
        assert!((f(&e["coverage_factor"]) - k21).abs() < 1e-9);
        assert!(
            (f(&e["expanded"]) - k21 * f(&r["b_std_errors"][m])).abs() < 1e-9 * f(&e["expanded"])
        );
        for k in 0..3 {
            let u_s = f(&r["S_expanded"][m][k]);
            if k > m {
                assert_eq!(u_s, 0.0);
                continue;
            }
            let e = &elements[&format!("S_{}{}", axes[m], axes[k])];
            let (stat, grav) = (
                f(&r["S_std_errors"][m][k]),
                gravity_rel_std * f(&r["S"][m][k]).abs(),
            );
            assert_eq!(f(&e["statistical"]), stat);
            assert!((f(&e["gravity"]) - grav).abs() <= 1e-15 * grav, "S{m}{k}");
            let want = f(&e["coverage_factor"]) * (stat * stat + grav * grav).sqrt();
            assert!(
                (u_s - want).abs() <= 1e-12 * want,
                "S{m}{k}: {u_s} vs {want}"
            );
            assert_eq!(f(&e["expanded"]), u_s);
        }
    }
    // A diagonal element's gravity part is of the order of u·1 g/g.
    assert!(f(&elements["S_xx"]["gravity"]) > 4e-5);
    for m in 0..3 {
        let se = f(&r["b_std_errors"][m]);
        assert!(
            se > 0.0 && (f(&r["b"][m]) - b[m]).abs() < 4.0 * se,
            "b{m}: {} vs {} ± {se}",
            r["b"][m],
            b[m]
        );
        for k in 0..3 {
            if k <= m {
                let se = f(&r["T_std_errors"][m][k]);
                assert!(
                    se > 0.0 && (f(&r["T"][m][k]) - t[m][k]).abs() < 4.0 * se,
                    "T{m}{k}"
                );
            } else {
                assert_eq!(f(&r["T"][m][k]), 0.0, "T is lower-triangular");
            }
        }
    }
    assert!(f(&r["fit"]["spread"]) >= f(&r["fit"]["min_spread"]));
    assert!(["converged", "orthogonal"].contains(&r["fit"]["stop"].as_str().unwrap()));
    assert_eq!(r["residuals"].as_array().unwrap().len(), 30);
    // Compensation round-trips: g = T (u − b) has magnitude 1 at every
    // position, and points along the planted direction.
    for (p, g) in spiral(30).into_iter().enumerate() {
        let u = lower_outputs(g);
        let back: Vec<f64> = (0..3)
            .map(|m| {
                (0..3)
                    .map(|k| f(&r["T"][m][k]) * (u[k] - f(&r["b"][k])))
                    .sum()
            })
            .collect();
        for m in 0..3 {
            assert!((back[m] - g[m]).abs() < 2e-3, "position {p}");
        }
    }
}

/// A recording at 50 Hz: an initial still period, then holds at `dirs`,
/// each `hold` seconds, joined by 1.5 s turns.
pub(crate) fn recording(dirs: &[[f64; 3]], hold: f64) -> Vec<[f64; 3]> {
    let rate = 50.0;
    let mut out = Vec::new();
    let mut k = 0usize;
    let mut push = |g: [f64; 3], out: &mut Vec<[f64; 3]>| {
        let u = lower_outputs(g);
        k += 1;
        out.push([0, 1, 2].map(|m| u[m] + 1e-3 * wobble(k * 3 + m)));
    };
    for (i, g) in dirs.iter().enumerate() {
        if i > 0 {
            let from = dirs[i - 1];
            let steps = (1.5 * rate) as usize;
            for s in 0..steps {
                let w = s as f64 / steps as f64;
                let v = [0, 1, 2].map(|m| from[m] * (1.0 - w) + g[m] * w);
                let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                push(v.map(|x| x / n), &mut out);
            }
        }
        let seconds = if i == 0 { 5.0 } else { hold };
        for _ in 0..(seconds * rate) as usize {
            push(*g, &mut out);
        }
    }
    out
}

#[tokio::test]
async fn a_recording_gives_its_static_intervals_and_b_and_t() {
    let app = TestApp::spawn(Sqlite).await;
    let dirs = spiral(12);
    let res = triad(
        &app,
        &json!({"unit": "g", "recording": {"rate_hz": 50, "samples": recording(&dirs, 4.0)}}),
    )
    .await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    let intervals = r["detection"]["intervals"].as_array().unwrap();
    assert_eq!(intervals.len(), 12, "{intervals:?}");
    assert!(intervals.iter().all(|i| i["used"] == true));
    // The first is the initial still period, from the start.
    assert_eq!(f(&intervals[0]["start_s"]), 0.0);
    // Each later hold starts 1.5 s of turning after the previous ends.
    for (i, w) in intervals.iter().enumerate().skip(1) {
        let planted_start = 5.0 + 1.5 + (i as f64 - 1.0) * 5.5;
        assert!(
            (f(&w["start_s"]) - planted_start).abs() <= 0.6,
            "interval {i}: {w}"
        );
    }
    let (b, _) = lower();
    for m in 0..3 {
        assert!((f(&r["b"][m]) - b[m]).abs() < 2e-3, "b{m}");
    }
    assert_eq!(r["detection"]["min_static_s"], 2.0);

    // Too few holds: the refusal says how many and what to change.
    let detail = recording_refused(
        &app,
        json!({"rate_hz": 50, "samples": recording(&dirs[..7], 4.0)}),
    )
    .await;
    assert!(
        detail.contains("only 7 static intervals found")
            && detail.contains("9")
            && detail.contains("3 s"),
        "{detail}"
    );
    // Holds too short for the minimum: found, rejected, said so (all but
    // the initial period and the last hold, which runs to the recording's
    // end and so loses only half a window).
    let p = problem(
        triad(
            &app,
            &json!({"recording": {"rate_hz": 50, "samples": recording(&dirs, 2.5)}}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("10 rejected"),
        "{p}"
    );
}

#[tokio::test]
async fn each_refusal_names_its_field() {
    let app = TestApp::spawn(Sqlite).await;
    let cases: Vec<(Value, Vec<&str>, &str)> = vec![
        (json!({"unit": "g"}), vec![""], "exactly one of"),
        (
            json!({"orientations": "six_faces", "runs": [], "static_positions": []}),
            vec![""],
            "exactly one of",
        ),
        (
            json!({"orientations": "six_faces"}),
            vec!["/runs"],
            "required",
        ),
        (
            json!({"orientations": [[1, 0, 0], [0, 1, 0], [0, 0.5, 0]], "runs": [{"samples": [[[1, 0, 0]], [[0, 1, 0]], [[0, 0.5, 0]]]}]}),
            vec!["/orientations/2"],
            "1 g",
        ),
        (
            json!({"orientations": "six_faces", "runs": [{"samples": [[[1, 0, 0]]]}]}),
            vec!["/runs/0/samples"],
            "has 1 positions; the orientations are 6",
        ),
        (
            json!({"static_positions": vec![vec![[1.0, 0.0, 0.0]]; 8]}),
            vec!["/static_positions"],
            "8 positions",
        ),
        (
            json!({"static_positions": vec![vec![[1.0, 0.0, 0.0]]; 9], "stand": {"angle_std_arcsec": 5}}),
            vec!["/stand/angle_std_arcsec"],
            "no indexing error",
        ),
        (
            json!({"static_positions": vec![vec![[1.0, 0.0, 0.0]]; 9], "stand": {}}),
            vec!["/stand"],
            "must give",
        ),
        (
            json!({"static_positions": vec![vec![[1.0, 0.0, 0.0]]; 9], "stand": {"gravity_rel_std": 0.5}}),
            vec!["/stand/gravity_rel_std"],
            "from 0 to 0.1",
        ),
        (
            json!({"recording": {"rate_hz": 0, "samples": [[0, 0, 1]]}}),
            vec!["/recording/rate_hz"],
            "positive",
        ),
        (
            json!({"recording": {"rate_hz": 50, "samples": [[0, 0, 1]], "detector": {"window_s": -1}}}),
            vec!["/recording/detector/window_s"],
            "from 0.1 to 3600",
        ),
        (
            json!({"recording": {"rate_hz": 50, "samples": vec![[0.0, 0.0, 1.0]; 100]}}),
            vec!["/recording/samples"],
            "initial still period",
        ),
    ];
    for (body, want, says) in cases {
        let p = problem(triad(&app, &body).await, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(pointers(&p), want, "{body}: {p}");
        assert!(p.to_string().contains(says), "{body}: {p}");
    }
    // Directions in one plane (a single-axis turntable) do not determine
    // the model.
    let flat: Vec<Value> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::PI / 6.0;
            json!([lower_outputs([a.cos(), a.sin(), 0.0])])
        })
        .collect();
    let p = problem(
        triad(&app, &json!({"static_positions": flat})).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/static_positions"]);
    assert!(p.to_string().contains("do not span the sphere"), "{p}");
}

#[tokio::test]
async fn csv_carries_each_form_to_the_same_answer() {
    let app = TestApp::spawn(Sqlite).await;
    let example: Value =
        serde_json::from_str(include_str!("../../examples/triad-recording.json")).unwrap();
    let csv_post = |body: String| {
        app.client
            .post(app.url("/v1/identify/triad"))
            .bearer_auth(ADMIN)
            .header(CONTENT_TYPE, "text/csv")
            .body(body)
            .send()
    };
    let mut example = example;
    example["stand"] = json!({"gravity_rel_std": 3e-5});
    let json_answer: Value = triad(&app, &example).await.json().await.unwrap();
    // The recording, its samples written with Rust's shortest round-trip text.
    let mut csv = String::from(
        "# sensor_id: IMU-DEMO-1\n# unit: m/s2\n# rate_hz: 50\n# gravity_rel_std: 3e-5\nu_x,u_y,u_z\n",
    );
    for u in example["recording"]["samples"].as_array().unwrap() {
        csv.push_str(&format!("{},{},{}\n", f(&u[0]), f(&u[1]), f(&u[2])));
    }
    let res = csv_post(csv).await.unwrap();
    assert_eq!(res.status(), StatusCode::OK);
    let csv_answer: Value = res.json().await.unwrap();
    assert_eq!(csv_answer["b"], json_answer["b"]);
    assert_eq!(csv_answer["T"], json_answer["T"]);
    assert_eq!(csv_answer["detection"], json_answer["detection"]);
    assert_eq!(csv_answer["uncertainty"], json_answer["uncertainty"]);
    assert_eq!(csv_answer["uncertainty"]["gravity_rel_std"], 3e-5);
    // Known orientations, one sample a row.
    let body = known_body();
    let mut csv = String::from("# unit: m/s2\n# batches: 2\nrun,g_x,g_y,g_z,u_x,u_y,u_z\n");
    for (j, run) in body["runs"].as_array().unwrap().iter().enumerate() {
        for (g, samples) in faces().iter().zip(run["samples"].as_array().unwrap()) {
            for u in samples.as_array().unwrap() {
                csv.push_str(&format!(
                    "{},{},{},{},{},{},{}\n",
                    j + 1,
                    g[0],
                    g[1],
                    g[2],
                    f(&u[0]),
                    f(&u[1]),
                    f(&u[2])
                ));
            }
        }
    }
    let from_csv: Value = csv_post(csv).await.unwrap().json().await.unwrap();
    let from_json: Value = triad(&app, &body).await.json().await.unwrap();
    assert_eq!(from_csv["S"], from_json["S"]);
    assert_eq!(from_csv["b_std_errors"], from_json["b_std_errors"]);
    // Without known orientations the stand's indexing error has no place.
    let res = csv_post("# angle_std_arcsec: 5\nposition,u_x,u_y,u_z\nA,1,0,0\n".into())
        .await
        .unwrap();
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        p.to_string()
            .contains("`angle_std_arcsec` is not known for this layout"),
        "{p}"
    );
    // A bad line is named.
    let res = csv_post("position,u_x,u_y,u_z\nA,1,0,zero\n".into())
        .await
        .unwrap();
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        p.to_string().contains("CSV line 2: `zero` is not a number"),
        "{p}"
    );
}
