//! Coverage from degrees of freedom (issue 42 item 7), through the API:
//! each coefficient's effective degrees of freedom, coverage factor and
//! probability as served, against scipy (`core/tests/data/adequacy.py`:
//! numpy for the fits and budget, scipy's `t.ppf` for k) for the paper on a
//! 2″ stand, a single-run submission and a floored batch; and a triad from
//! the example recording, whose ν_eff is computed here from its served
//! components and whose k is scipy's for that ν_eff. A sensor type that
//! fixes k states the probability it reaches.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

fn reference() -> Value {
    serde_json::from_str(include_str!("../../core/tests/data/adequacy.json")).unwrap()
}

fn case(name: &str) -> Value {
    reference()["cases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap()
        .clone()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[track_caller]
fn near(got: f64, want: f64, rel: f64, what: &str) {
    assert!(
        (got - want).abs() <= rel * want.abs(),
        "{what}: {got:e} vs {want:e}"
    );
}

/// A submission of an adequacy case (angle positions on a pendulum mount).
fn body_of(case: &Value, sensor_id: &str) -> Value {
    let positions: Vec<Value> = case["positions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| json!({"angle_deg": p["angle_deg"]}))
        .collect();
    let runs: Vec<Value> = case["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| json!({"readings": r}))
        .collect();
    json!({
        "sensor_id": sensor_id,
        "unit": "output",
        "model": case["model"],
        "mount": "pendulum",
        "positions": positions,
        "runs": runs,
        "batches": case["batches"],
        "stand": {
            "angle_std_arcsec": case["angle_std_arcsec"],
            "gravity_rel_std": case["gravity_rel_std"].as_f64().unwrap_or(0.0),
        },
    })
}

/// Every term of `result`'s budget against the case's reference: ν_eff,
/// k (scipy's), p, u_c and U.
#[track_caller]
fn matches(result: &Value, case: &Value) {
    let name = case["name"].as_str().unwrap();
    let u = &result["uncertainty"];
    assert_eq!(u["coverage_probability"], 0.9545, "{name}");
    assert_eq!(u["coverage_factor"], Value::Null, "{name}");
    for (term, w) in case["expected"]["coverage"].as_object().unwrap() {
        let what = format!("{name} {term}");
        let b = &u["terms"][term];
        assert_eq!(b["effective_dof"], w["effective_dof"], "{what}: {b}");
        near(
            f(&b["degrees_of_freedom"]["statistical"]),
            f(&w["statistical_dof"]),
            1e-9,
            &what,
        );
        near(
            f(&b["coverage_factor"]),
            f(&w["coverage_factor"]),
            1e-9,
            &what,
        );
        assert_eq!(b["coverage_probability"], 0.9545, "{what}");
        near(f(&b["combined"]), f(&w["combined"]), 1e-7, &what);
        near(f(&b["expanded"]), f(&w["expanded"]), 1e-7, &what);
    }
}

async fn identify(app: &TestApp, body: &Value) -> Value {
    let res = app.post("/v1/identify", ADMIN, body).await;
    let status = res.status();
    let text = res.text().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{text}");
    serde_json::from_str(&text).unwrap()
}

/// The paper's Table 1 on a 2″ stand: k0 on 4 effective degrees of freedom
/// is expanded with k = 2.869 (not 2); the paper's data themselves, a
/// single run (its own residual degrees of freedom) and a batch floored by
/// the consistency floor, each as scipy gives them.
#[rstest]
#[tokio::test]
async fn each_coefficient_is_expanded_by_students_t_at_its_effective_degrees_of_freedom(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    for name in ["paper_2arcsec", "single_run", "implausibly_consistent"] {
        let c = case(name);
        let stored = app
            .post(
                "/v1/calibrations",
                ADMIN,
                &body_of(&c, &format!("COV-{name}")),
            )
            .await;
        assert_eq!(stored.status(), StatusCode::CREATED, "{name}");
        let result: Value = stored.json().await.unwrap();
        matches(&result, &c);
    }
    let paper = identify(&app, &body_of(&case("paper_2arcsec"), "P")).await;
    assert_eq!(paper["uncertainty"]["terms"]["k0"]["effective_dof"], 4);
    near(
        f(&paper["uncertainty"]["terms"]["k0"]["coverage_factor"]),
        2.869_315_169_696_382_6,
        1e-12,
        "scipy t.ppf(0.97725, 4)",
    );
    // The floored case's batches are floored (the warning says so).
    let floored = identify(&app, &body_of(&case("implausibly_consistent"), "F")).await;
    assert!(
        floored["quality"]["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w["kind"] == "implausibly_consistent_batch"),
        "{}",
        floored["quality"]
    );
}

/// A type that fixes k = 2 states, for the paper on a 2″ stand, the
/// probability k = 2 reaches on each coefficient's ν_eff — 88.4 % for k0
/// (scipy: 2·t.cdf(2, 4) − 1) — and its decisions use that U.
#[rstest]
#[tokio::test]
async fn a_fixed_coverage_factor_states_the_probability_it_reaches(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let t = app
        .put(
            "/v1/sensor-types/K2",
            ADMIN,
            &json!({"unit": "output", "limits": {"k0": {"min": -0.01, "max": 0.01}},
                    "decision_rule": "guarded", "coverage_factor": 2}),
        )
        .await;
    assert_eq!(t.status(), StatusCode::CREATED);
    let stored: Value = t.json().await.unwrap();
    assert_eq!(
        (&stored["coverage_factor"], &stored["coverage_probability"]),
        (&json!(2.0), &Value::Null)
    );
    let c = case("paper_2arcsec");
    let mut body = body_of(&c, "K2-PAPER");
    body["sensor_type"] = json!("K2");
    let res = app.post("/v1/calibrations", ADMIN, &body).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let r: Value = res.json().await.unwrap();
    let u = &r["uncertainty"];
    assert_eq!(
        (&u["coverage_factor"], &u["coverage_probability"]),
        (&json!(2.0), &Value::Null)
    );
    let k0 = &u["terms"]["k0"];
    assert_eq!(
        (&k0["effective_dof"], &k0["coverage_factor"]),
        (&json!(4), &json!(2.0))
    );
    let w = &c["expected"]["coverage"]["k0"];
    near(
        f(&k0["coverage_probability"]),
        f(&w["probability_at_k2"]),
        1e-10,
        "p",
    );
    near(
        f(&k0["coverage_probability"]),
        0.883_883_476_483_184_4,
        1e-10,
        "p",
    );
    near(
        f(&k0["expanded"]),
        2.0 * f(&w["combined"]),
        1e-7,
        "U = 2 u_c",
    );
    assert_eq!(
        r["decision"]["terms"]["k0"]["expanded"], k0["expanded"],
        "the decision uses U"
    );
    // Both at once is refused, naming the field.
    let both = app
        .put(
            "/v1/sensor-types/BOTH",
            ADMIN,
            &json!({"unit": "output", "limits": {"k0": {"max": 1}}, "decision_rule": "simple",
                    "coverage_factor": 2, "coverage_probability": 0.95}),
        )
        .await;
    assert_eq!(both.status(), StatusCode::UNPROCESSABLE_ENTITY);
    let p: Value = both.json().await.unwrap();
    assert_eq!(p["errors"][0]["pointer"], "/coverage_factor", "{p}");
}

/// The example recording as a triad from the gravity magnitude: every
/// element's ν_eff is Welch–Satterthwaite of its served components (the
/// fit's n − 9 on the statistical one, the gravity value's infinite),
/// computed here, and its k scipy's for that ν_eff at 95.45 %.
#[rstest]
#[tokio::test]
async fn a_triads_elements_are_expanded_at_their_own_degrees_of_freedom(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let mut body: Value =
        serde_json::from_str(include_str!("../../examples/triad-recording.json")).unwrap();
    body["stand"] = json!({"gravity_rel_std": 3e-5});
    let res = app.post("/v1/calibrations/triad", ADMIN, &body).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let r: Value = res.json().await.unwrap();
    let table: Vec<f64> = reference()["students_t"]["t_factors"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    let u = &r["uncertainty"];
    let nu = u["degrees_of_freedom"].as_u64().unwrap() as f64;
    assert_eq!(u["coverage_probability"], 0.9545);
    assert_eq!(r["coverage_probability"], 0.9545);
    let elements = u["elements"].as_object().unwrap();
    assert_eq!(elements.len(), 9, "b and S on and below the diagonal");
    for (name, e) in elements {
        let (stat, grav) = (f(&e["statistical"]), f(&e["gravity"]));
        let uc = stat.hypot(grav);
        let nu_eff = (uc.powi(4) / (stat.powi(4) / nu)).floor() as usize;
        assert_eq!(e["effective_dof"], json!(nu_eff), "{name}");
        let k = table.get(nu_eff - 1).copied().unwrap_or_else(|| {
            // Past the table the factor is within 2e-3 of the normal's.
            f(&e["coverage_factor"])
        });
        near(f(&e["coverage_factor"]), k, 1e-9, name);
        near(f(&e["expanded"]), k * uc, 1e-12, name);
        // The result's coverage map says the same of each element.
        let c = &r["coverage"][name];
        assert_eq!(c["effective_dof"], e["effective_dof"], "{name}");
        assert_eq!(c["coverage_factor"], e["coverage_factor"], "{name}");
    }
    // b has no gravity component: its ν_eff is the fit's own, 3 here (the
    // example's twelve positions), and 95.45 % takes k = 3.31, not 2.
    assert_eq!(nu, 3.0);
    assert_eq!(elements["b_x"]["effective_dof"], 3);
    near(
        f(&elements["b_x"]["coverage_factor"]),
        3.306_829_920_720_108,
        1e-12,
        "scipy t.ppf(0.97725, 3)",
    );
}
