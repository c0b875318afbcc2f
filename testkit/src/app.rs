//! A real server on a free port, in the test's own process, over a fresh
//! database of either engine, and a client that speaks to it over HTTP.

use std::path::PathBuf;

use accelcal::startup::{Application, Config};
use reqwest::{Client, Response, StatusCode};
use serde_json::{Value, json};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// The admin token every test server accepts.
pub const ADMIN: &str = "test-mFNzQPlRPKFPdbVaGHjUexynZqfxk07a7Fyxt0k4vls";

/// The paper's six tests as a JSON submission.
pub fn paper() -> Value {
    serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap()
}

/// The paper's Table 1 as CSV with metadata lines.
pub fn paper_csv() -> String {
    format!(
        "# sensor_id: PAPER-CSV\n# model: k0 ki kp\n# batches: 2\n{}",
        include_str!("../../core/tests/data/table1.csv")
    )
}

/// A small valid submission for `sensor`, with `runs` noisy runs of the
/// model U = k0 + ki·a_i + kp·a_p: each position's two samples (cw, ccw)
/// scatter about its value as much as the values scatter about the model,
/// so the model fits (no lack of fit).
pub fn submission(sensor: &str, performed_at: &str, runs: usize) -> Value {
    let (k0, ki, kp) = (-8.4e-4, -1.216, 6.2e-3);
    let runs: Vec<Value> = (0..runs)
        .map(|j| {
            let readings: Vec<Value> = [(0.0, 1.0), (-1.0, 0.0), (0.0, -1.0), (1.0, 0.0)]
                .iter()
                .enumerate()
                .map(|(p, (ai, ap))| {
                    let noise = 1e-6 * (j as f64 * 1.7 + p as f64 * 2.9).sin();
                    let scatter = 1e-6 * (j as f64 * 2.3 + p as f64 * 1.1).cos();
                    let u = k0 + ki * ai + kp * ap + noise;
                    json!([u - scatter, u + scatter])
                })
                .collect();
            json!({ "readings": readings })
        })
        .collect();
    json!({
        "sensor_id": sensor,
        "performed_at": performed_at,
        "unit": "mA",
        "positions": [{"angle_deg": 0}, {"angle_deg": 90}, {"angle_deg": 180}, {"angle_deg": 270}],
        "runs": runs,
        "batches": 2
    })
}

/// A submission whose outputs hold a term its model lacks: six runs on
/// eight positions (45° steps) of U = k0 + ki·a_i + kp·a_p + 3e-3·a_i²,
/// two samples a position with independent 1e-6 noise, model `k0 ki kp`.
/// The misfit is the same in every run: lack of fit, with `kii` unmodelled.
pub fn misfit_submission(sensor: &str) -> Value {
    let mut body = submission(sensor, "2026-01-01T00:00:00Z", 6);
    let angles = [0, 45, 90, 135, 180, 225, 270, 315];
    body["positions"] = json!(angles.map(|d| json!({"angle_deg": d})));
    let (k0, ki, kp, kii) = (-8.4e-4, -1.216, 6.2e-3, 3e-3);
    for (j, run) in body["runs"].as_array_mut().unwrap().iter_mut().enumerate() {
        let readings: Vec<Value> = angles
            .iter()
            .enumerate()
            .map(|(p, d)| {
                let th = f64::from(*d).to_radians();
                let a_i = -th.sin();
                let u = k0 + ki * a_i + kp * th.cos() + kii * a_i * a_i;
                let k = (j * 8 + p) as f64;
                json!([u + 1e-6 * (k * 1.3).sin(), u + 1e-6 * (k * 2.1 + 0.4).cos()])
            })
            .collect();
        run["readings"] = json!(readings);
    }
    body
}

/// The engine a test's server runs on: API tests take it as a parameter
/// (`#[values(Sqlite, Postgres)] engine: Engine`, with `rstest`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// A SQLite file in a temporary directory.
    Sqlite,
    /// A database of its own on the test PostgreSQL server.
    Postgres,
}

/// A fresh database, removed when dropped. A PostgreSQL database is reached
/// through a [`crate::pg::Relay`], so that a test can make it unreachable.
pub struct Database {
    /// Its URL (a file path for SQLite).
    pub url: String,
    _dir: Option<tempfile::TempDir>,
    relay: Option<crate::pg::Relay>,
    _pg: Option<crate::pg::TestDb>,
}

impl Database {
    /// A fresh, empty database on `engine`.
    pub async fn fresh(engine: Engine) -> Database {
        match engine {
            Engine::Sqlite => {
                let dir = tempfile::tempdir().unwrap();
                Database {
                    url: dir.path().join("accelcal.db").to_str().unwrap().to_owned(),
                    _dir: Some(dir),
                    relay: None,
                    _pg: None,
                }
            }
            Engine::Postgres => {
                let db = crate::pg::TestDb::create().await;
                let url = db.url.clone();
                let (target, through) = crate::pg::split_authority(&url);
                let relay = crate::pg::Relay::start(target).await;
                let url = through(&relay.addr.to_string());
                Database {
                    url,
                    _dir: None,
                    relay: Some(relay),
                    _pg: Some(db),
                }
            }
        }
    }

    /// Makes the database unavailable: the SQLite file moved aside, the
    /// PostgreSQL server unreachable. [`Database::restore`] undoes it.
    pub fn cut(&self) {
        match &self.relay {
            Some(r) => r.cut(),
            None => std::fs::rename(&self.url, format!("{}.aside", self.url)).unwrap(),
        }
    }

    /// Makes the database available again.
    pub fn restore(&self) {
        match &self.relay {
            Some(r) => r.restore(),
            None => std::fs::rename(format!("{}.aside", self.url), &self.url).unwrap(),
        }
    }
}

/// A running server.
pub struct TestApp {
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// Its database's URL (a file path for SQLite).
    pub database: String,
    /// A client.
    pub client: Client,
    /// The server's admission budgets (to observe what it has taken in).
    pub admission: accelcal::http::stack::Admission,
    stop: Option<oneshot::Sender<()>>,
    task: Option<JoinHandle<anyhow::Result<()>>>,
    owned: Option<Database>,
}

impl TestApp {
    /// A server on a fresh database of `engine`.
    pub async fn spawn(engine: Engine) -> TestApp {
        Self::configured(engine, |_| {}).await
    }

    /// A server on a fresh database of `engine`, its test configuration
    /// changed by `f`.
    pub async fn configured(engine: Engine, f: impl FnOnce(&mut Config)) -> TestApp {
        let db = Database::fresh(engine).await;
        let mut config = Config::for_tests(&db.url, ADMIN);
        f(&mut config);
        let mut app = Self::spawn_with(config).await;
        app.owned = Some(db);
        app
    }

    /// A server on the given database.
    pub async fn spawn_on(database: &str) -> TestApp {
        Self::spawn_with(Config::for_tests(database, ADMIN)).await
    }

    /// A server with a custom configuration.
    pub async fn spawn_with(config: Config) -> TestApp {
        let database = config.database.clone();
        let app = Application::build(config).await.expect("server builds");
        let base = format!("http://127.0.0.1:{}", app.port());
        let admission = app.admission();
        let (tx, rx) = oneshot::channel::<()>();
        let task = tokio::spawn(app.run_until_stopped(async {
            let _ = rx.await;
        }));
        TestApp {
            base,
            database,
            client: Client::new(),
            admission,
            stop: Some(tx),
            task: Some(task),
            owned: None,
        }
    }

    /// The SQLite file (tests of SQLite's own failure modes).
    pub fn db_path(&self) -> PathBuf {
        assert!(!self.database.starts_with("postgres"), "a SQLite-only test");
        PathBuf::from(&self.database)
    }

    /// Stops the server gracefully and waits for it; keeps the database.
    pub async fn stop(&mut self) {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
        if let Some(task) = self.task.take() {
            task.await.unwrap().unwrap();
        }
    }

    /// Its database (the one [`TestApp::configured`] made for it).
    pub fn db(&self) -> &Database {
        self.owned
            .as_ref()
            .expect("a server on a database of its own")
    }

    /// Takes the database (so a restarted server can reuse it).
    pub fn take_database(&mut self) -> Option<Database> {
        self.owned.take()
    }

    /// `url` relative to the server.
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// GET with a token.
    pub async fn get(&self, path: &str, token: &str) -> Response {
        self.client
            .get(self.url(path))
            .bearer_auth(token)
            .send()
            .await
            .unwrap()
    }

    /// GET with a token; the JSON answer.
    pub async fn get_json(&self, path: &str, token: &str) -> Value {
        self.get(path, token).await.json().await.unwrap()
    }

    /// The actions of the audit trail's entries on `object` (such as
    /// `calibrations/<id>`), oldest first, as an admin reads them.
    pub async fn trail_actions(&self, object: &str) -> Vec<String> {
        self.trail(object)
            .await
            .iter()
            .map(|e| e["action"].as_str().unwrap().to_owned())
            .collect()
    }

    /// The audit trail's entries about `object`, in order.
    pub async fn trail(&self, object: &str) -> Vec<Value> {
        let trail = self
            .get_json(&format!("/v1/audit?object={object}"), ADMIN)
            .await;
        trail["items"]
            .as_array()
            .unwrap_or_else(|| panic!("no trail for {object}: {trail}"))
            .clone()
    }

    /// The first entry of the audit trail about `object` whose action is
    /// `action`.
    pub async fn trail_entry(&self, object: &str, action: &str) -> Value {
        self.trail(object)
            .await
            .into_iter()
            .find(|e| e["action"] == action)
            .unwrap_or_else(|| panic!("no `{action}` about {object} in the trail"))
    }

    /// POST JSON with a token.
    pub async fn post(&self, path: &str, token: &str, body: &Value) -> Response {
        self.client
            .post(self.url(path))
            .bearer_auth(token)
            .json(body)
            .send()
            .await
            .unwrap()
    }

    /// PUT JSON with a token.
    pub async fn put(&self, path: &str, token: &str, body: &Value) -> Response {
        self.client
            .put(self.url(path))
            .bearer_auth(token)
            .json(body)
            .send()
            .await
            .unwrap()
    }

    /// Submits and expects 201; returns the result.
    pub async fn submit(&self, token: &str, body: &Value) -> Value {
        self.expect(StatusCode::CREATED, "/v1/calibrations", token, body)
            .await
    }

    /// POSTs `body` to `path`, expects `status` (else fails showing the
    /// answer's first 600 characters); returns the answer.
    pub async fn expect(&self, status: StatusCode, path: &str, token: &str, body: &Value) -> Value {
        let res = self.post(path, token, body).await;
        let got = res.status();
        let text = res.text().await.unwrap();
        assert_eq!(got, status, "{path}: {}", text.get(..600).unwrap_or(&text));
        serde_json::from_str(&text).unwrap()
    }

    /// Revokes the token with this id, as the configured admin.
    pub async fn revoke(&self, token_id: &str) {
        let res = self
            .client
            .delete(self.url(&format!("/v1/tokens/{token_id}")))
            .bearer_auth(ADMIN)
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), StatusCode::NO_CONTENT, "revoking {token_id}");
    }

    /// Creates a token with `role` (and station) and returns its secret.
    pub async fn token(&self, role: &str, station: Option<&str>) -> String {
        let mut body = json!({ "role": role });
        if let Some(s) = station {
            body["station_id"] = json!(s);
        }
        let res = self.post("/v1/tokens", ADMIN, &body).await;
        assert_eq!(res.status(), StatusCode::CREATED);
        res.json::<Value>().await.unwrap()["token"]
            .as_str()
            .unwrap()
            .to_owned()
    }
}

impl TestApp {
    /// Creates a token with `role` held by the person `holder` and returns
    /// its secret.
    pub async fn held_token(&self, role: &str, holder: &str, station: Option<&str>) -> String {
        let mut body = json!({ "role": role, "holder": holder });
        if let Some(s) = station {
            body["station_id"] = json!(s);
        }
        let res = self.post("/v1/tokens", ADMIN, &body).await;
        assert_eq!(res.status(), StatusCode::CREATED);
        res.json::<Value>().await.unwrap()["token"]
            .as_str()
            .unwrap()
            .to_owned()
    }
}

impl Drop for TestApp {
    fn drop(&mut self) {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
    }
}

/// Reads a problem answer, checking its media type and shape; returns the body.
pub async fn problem(res: Response, status: StatusCode) -> Value {
    assert_eq!(res.status(), status);
    let ct = res.headers()["content-type"].to_str().unwrap().to_owned();
    assert_eq!(ct, "application/problem+json");
    assert!(res.headers().contains_key("x-request-id"));
    let body: Value = res.json().await.unwrap();
    for key in ["type", "title", "status", "detail", "request_id"] {
        assert!(body.get(key).is_some(), "problem without `{key}`: {body}");
    }
    assert_eq!(body["status"], status.as_u16());
    body
}

/// The pointers of a 422's errors.
pub fn pointers(problem: &Value) -> Vec<String> {
    problem["errors"]
        .as_array()
        .map(|e| {
            e.iter()
                .map(|x| x["pointer"].as_str().unwrap().to_owned())
                .collect()
        })
        .unwrap_or_default()
}

/// Polls `check` until it gives `Some`, or fails after `limit` naming `what`.
pub async fn eventually<T, F: std::future::Future<Output = Option<T>>>(
    limit: std::time::Duration,
    what: &str,
    mut check: impl FnMut() -> F,
) -> T {
    let deadline = std::time::Instant::now() + limit;
    loop {
        if let Some(v) = check().await {
            return v;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "{what} did not happen within {limit:?}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
}

/// Asserts `got` is within `tol` of `want`.
#[track_caller]
pub fn close(got: &Value, want: f64, tol: f64) {
    let g = got
        .as_f64()
        .unwrap_or_else(|| panic!("not a number: {got}"));
    assert!((g - want).abs() <= tol, "{g} vs {want} (±{tol})");
}
