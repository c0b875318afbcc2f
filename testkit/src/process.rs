//! Starting and stopping the real `accelcal` binary, as the process tests
//! and the benchmarks do.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

/// The admin token the processes accept.
pub const ADMIN: &str = "process-NJ8jG8uhd77gq4gmAqCmcXBKONroNBXNc-aSb0rumWw";

/// The `accelcal` binary cargo built beside the running test or benchmark
/// (`target/<profile>/accelcal`, the parent of its `deps/`), or the one
/// `ACCELCAL_BENCH_BIN` names (a benchmark's "before").
pub fn binary() -> std::path::PathBuf {
    if let Some(bin) = std::env::var_os("ACCELCAL_BENCH_BIN") {
        return bin.into();
    }
    let exe = std::env::current_exe().expect("the test's own path");
    let deps = exe.parent().expect("the test's directory");
    let profile = if deps.ends_with("deps") {
        deps.parent().expect("the profile's directory")
    } else {
        deps
    };
    let bin = profile.join("accelcal");
    assert!(
        bin.exists(),
        "{} is not built: cargo builds it for the accelcal package's own tests and benchmarks",
        bin.display()
    );
    bin
}

/// A running `accelcal serve`.
pub struct Server {
    /// The process.
    pub child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// Every log line so far.
    pub log: Arc<Mutex<Vec<String>>>,
}

impl Server {
    /// Starts the binary on `db` (debug logging) and waits until it listens.
    pub fn start(db: impl AsRef<std::ffi::OsStr>) -> Server {
        Self::start_with(db, &[], "debug")
    }

    /// Starts the binary on `db` with extra `serve` flags and a `RUST_LOG`
    /// filter, and waits until it listens.
    pub fn start_with(db: impl AsRef<std::ffi::OsStr>, flags: &[&str], rust_log: &str) -> Server {
        let bin = binary();
        let mut child = Command::new(bin)
            .args(["serve", "--listen", "127.0.0.1:0", "--log-format", "json"])
            .args(["--shutdown-grace", "10"])
            .args(flags)
            .arg("--database")
            .arg(db)
            .env("ACCELCAL_ADMIN_TOKEN", ADMIN)
            .env("RUST_LOG", rust_log)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the binary starts");
        let stderr = child.stderr.take().unwrap();
        let log = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = mpsc::channel();
        let sink = log.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line)
                    && v["message"] == "accelcal listening"
                {
                    let _ = tx.send(v["address"].as_str().unwrap_or_default().to_owned());
                }
                sink.lock().unwrap().push(line);
            }
        });
        let address = rx
            .recv_timeout(Duration::from_secs(30))
            .unwrap_or_else(|_| panic!("the server did not start: {:?}", log.lock().unwrap()));
        Server {
            child,
            base: format!("http://{address}"),
            log,
        }
    }

    /// The whole log as one string.
    pub fn log_text(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    /// GET `path` with the admin token; the JSON answer.
    pub async fn get_json(&self, path: &str) -> serde_json::Value {
        reqwest::Client::new()
            .get(format!("{}{path}", self.base))
            .bearer_auth(ADMIN)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap()
    }

    /// SIGKILL, no warning.
    pub fn kill9(&mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// SIGTERM.
    pub fn terminate(&self) {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: kill(2) with a valid signal number on our own child.
        let rc = unsafe { libc::kill(pid, libc::SIGTERM) };
        assert_eq!(rc, 0, "kill(SIGTERM) failed");
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Signs in to the pages with `token` as a browser does (the sign-in
/// form's cookie and CSRF value, then the form), and returns the `Cookie`
/// header of the session opened.
pub async fn sign_in(base: &str, token: &str) -> String {
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let cookie = |res: &reqwest::Response, name: &str| {
        res.headers()
            .get_all("set-cookie")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .find_map(|v| {
                v.split(';')
                    .next()?
                    .strip_prefix(&format!("{name}="))
                    .map(str::to_owned)
            })
            .unwrap_or_else(|| panic!("no {name} cookie"))
    };
    let form = client.get(format!("{base}/ui/login")).send().await.unwrap();
    let csrf = cookie(&form, "accelcal_login");
    let res = client
        .post(format!("{base}/ui/login"))
        .header("cookie", format!("accelcal_login={csrf}"))
        .form(&[("token", token), ("csrf", &csrf), ("next", "/ui/sensors")])
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 303, "signed in");
    format!("accelcal_session={}", cookie(&res, "accelcal_session"))
}
