//! Throwaway PostgreSQL databases for tests: each test gets a database of
//! its own, created on the server named by `ACCELCAL_TEST_POSTGRES_URL`
//! (default: the local server, `postgres://postgres@127.0.0.1:5432/test`)
//! and dropped when the test is done. When the server is not there the test
//! fails, saying how to start it — it never skips.

use tokio_postgres::NoTls;

/// The server tests use, as an administrator's URL.
pub fn admin_url() -> String {
    std::env::var("ACCELCAL_TEST_POSTGRES_URL")
        .ok()
        .filter(|u| !u.is_empty())
        .unwrap_or_else(|| "postgres://postgres@127.0.0.1:5432/test".into())
}

/// `url` with its database replaced by `name`.
pub fn with_database(url: &str, name: &str) -> String {
    let (base, query) = url
        .split_once('?')
        .map_or((url, None), |(b, q)| (b, Some(q)));
    let prefix = base.rsplit_once('/').map_or(base, |(p, _)| p);
    match query {
        Some(q) => format!("{prefix}/{name}?{q}"),
        None => format!("{prefix}/{name}"),
    }
}

async fn admin() -> tokio_postgres::Client {
    let url = admin_url();
    let (client, conn) = tokio_postgres::connect(&url, NoTls).await.unwrap_or_else(|e| {
        panic!(
            "the tests need PostgreSQL at {url} ({e}); start it with \
             `pg_ctlcluster --skip-systemctl-redirect 15 main start` or set ACCELCAL_TEST_POSTGRES_URL"
        )
    });
    tokio::spawn(conn);
    client
}

/// A database of its own, dropped (with its connections) when this is.
pub struct TestDb {
    /// Its URL.
    pub url: String,
    /// Its name.
    pub name: String,
}

impl TestDb {
    /// Creates a fresh, empty database.
    pub async fn create() -> TestDb {
        let name = format!("accelcal_t_{}", uuid::Uuid::now_v7().simple());
        admin()
            .await
            .batch_execute(&format!("CREATE DATABASE {name}"))
            .await
            .unwrap();
        TestDb {
            url: with_database(&admin_url(), &name),
            name,
        }
    }

    /// Creates a fresh database from a synchronous context.
    pub fn create_blocking() -> TestDb {
        std::thread::spawn(|| {
            tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap()
                .block_on(TestDb::create())
        })
        .join()
        .unwrap()
    }

    /// A plain client on this database.
    pub async fn client(&self) -> tokio_postgres::Client {
        let (client, conn) = tokio_postgres::connect(&self.url, NoTls).await.unwrap();
        tokio::spawn(conn);
        client
    }
}

impl Drop for TestDb {
    fn drop(&mut self) {
        let name = self.name.clone();
        // On a thread of its own: Drop may run inside a runtime.
        let _ = std::thread::spawn(move || {
            tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap()
                .block_on(async {
                    let _ = admin()
                        .await
                        .batch_execute(&format!("DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
                        .await;
                })
        })
        .join();
    }
}

#[test]
fn the_database_is_replaced_in_the_url() {
    assert_eq!(
        with_database(
            "postgres://postgres@127.0.0.1:5432/test?sslmode=disable",
            "x"
        ),
        "postgres://postgres@127.0.0.1:5432/x?sslmode=disable"
    );
    assert_eq!(
        with_database("postgres://u@h/test", "y"),
        "postgres://u@h/y"
    );
}

/// The `host:port` of a URL, and the URL with it replaced by `authority`.
pub fn split_authority(url: &str) -> (String, impl Fn(&str) -> String + '_) {
    let scheme_end = url.find("://").map_or(0, |i| i + 3);
    let rest = &url[scheme_end..];
    let end = rest.find(['/', '?']).unwrap_or(rest.len());
    let authority = &rest[..end];
    let host_at = authority.rfind('@').map_or(0, |i| i + 1);
    let host = &authority[host_at..];
    let host_port = if host.contains(':') {
        host.to_owned()
    } else {
        format!("{host}:5432")
    };
    let replace = move |with: &str| {
        format!(
            "{}{}{with}{}",
            &url[..scheme_end],
            &authority[..host_at],
            &rest[end..]
        )
    };
    (host_port, replace)
}

/// A TCP relay in front of the database server, which a test can cut (every
/// connection dropped, new ones refused) and restore: the database becoming
/// unreachable and coming back, without stopping the shared server.
pub struct Relay {
    /// Where it listens.
    pub addr: std::net::SocketAddr,
    cut: std::sync::Arc<std::sync::atomic::AtomicBool>,
    live: std::sync::Arc<std::sync::Mutex<Vec<tokio::task::AbortHandle>>>,
    accept: tokio::task::JoinHandle<()>,
}

impl Relay {
    /// A relay to `target` (`host:port`).
    pub async fn start(target: String) -> Relay {
        use std::sync::atomic::Ordering;
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let cut = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let live = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let (c, l) = (cut.clone(), live.clone());
        let accept = tokio::spawn(async move {
            while let Ok((mut inbound, _)) = listener.accept().await {
                if c.load(Ordering::SeqCst) {
                    continue; // dropped: the database is unreachable
                }
                let target = target.clone();
                let task = tokio::spawn(async move {
                    if let Ok(mut outbound) = tokio::net::TcpStream::connect(&target).await {
                        let _ = tokio::io::copy_bidirectional(&mut inbound, &mut outbound).await;
                    }
                });
                l.lock().unwrap().push(task.abort_handle());
            }
        });
        Relay {
            addr,
            cut,
            live,
            accept,
        }
    }

    /// Drops every connection and refuses new ones.
    pub fn cut(&self) {
        self.cut.store(true, std::sync::atomic::Ordering::SeqCst);
        for t in self.live.lock().unwrap().drain(..) {
            t.abort();
        }
    }

    /// Lets connections through again.
    pub fn restore(&self) {
        self.cut.store(false, std::sync::atomic::Ordering::SeqCst);
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.accept.abort();
        self.cut();
    }
}

#[test]
fn the_authority_is_replaced_in_the_url() {
    let (target, with) = split_authority("postgres://postgres@127.0.0.1:5432/test?sslmode=disable");
    assert_eq!(target, "127.0.0.1:5432");
    assert_eq!(
        with("127.0.0.1:9"),
        "postgres://postgres@127.0.0.1:9/test?sslmode=disable"
    );
    let (target, with) = split_authority("postgres://localhost/x");
    assert_eq!(
        (target.as_str(), with("h:1").as_str()),
        ("localhost:5432", "postgres://h:1/x")
    );
}
