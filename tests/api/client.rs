//! `accelcal submit`'s client against a scripted server: it retries 408,
//! 409, 429 and — once the server has answered — a refused connection
//! (failing fast on one before), honours `Retry-After`, keeps its
//! content-derived key across attempts, and gives up on a final error.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use accelcal::client::{Retry, Upload, idempotency_key, submit};
use axum::http::{HeaderMap, StatusCode};
use axum::routing::post;

use accelcal_testkit::eventually;

/// A server answering each attempt with the next status of `script`
/// (`Retry-After: 1` on 429), recording the keys it saw.
async fn scripted(
    script: Vec<u16>,
) -> (String, Arc<Mutex<Vec<String>>>, tokio::task::JoinHandle<()>) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    let keys = Arc::new(Mutex::new(Vec::new()));
    let seen = keys.clone();
    let next = Arc::new(AtomicU32::new(0));
    let app = axum::Router::new().route(
        "/v1/calibrations",
        post(move |headers: HeaderMap| {
            let (script, seen, next) = (script.clone(), seen.clone(), next.clone());
            async move {
                let key = headers["idempotency-key"].to_str().unwrap().to_owned();
                seen.lock().unwrap().push(key);
                let n = next.fetch_add(1, Ordering::SeqCst) as usize;
                let status = StatusCode::from_u16(script[n.min(script.len() - 1)]).unwrap();
                let mut h = HeaderMap::new();
                if status == StatusCode::TOO_MANY_REQUESTS {
                    h.insert("retry-after", "1".parse().unwrap());
                }
                (status, h, format!("{{\"attempt\": {}}}", n + 1))
            }
        }),
    );
    let task = tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    (base, keys, task)
}

fn upload(url: String, retries: Arc<Mutex<Vec<Retry>>>) -> Upload {
    Upload {
        url,
        token: "t".into(),
        body: b"{\"sensor_id\": \"C-1\"}".to_vec(),
        content_type: "application/json",
        attempts: 6,
        backoff: Duration::from_millis(10),
        on_retry: Some(Arc::new(move |r: &Retry| {
            retries.lock().unwrap().push(r.clone())
        })),
    }
}

#[tokio::test]
async fn transient_answers_are_retried_with_the_same_key() {
    let (base, keys, _server) = scripted(vec![408, 409, 429, 503, 201]).await;
    let retries = Arc::new(Mutex::new(Vec::new()));
    let u = upload(base, retries.clone());
    let answer = submit(&u).await.unwrap();
    assert_eq!(answer.status, 201);
    assert_eq!(answer.attempts, 5);
    assert_eq!(answer.body, "{\"attempt\": 5}");
    let reasons: Vec<String> = retries
        .lock()
        .unwrap()
        .iter()
        .map(|r| r.reason.clone())
        .collect();
    assert_eq!(reasons.len(), 4);
    for (reason, code) in reasons.iter().zip(["408", "409", "429", "503"]) {
        assert!(reason.starts_with(code), "{reason}");
    }
    // 429 said Retry-After: 1, which the client honoured.
    assert!(retries.lock().unwrap()[2].wait >= Duration::from_secs(1));
    let keys = keys.lock().unwrap();
    assert!(
        keys.iter().all(|k| *k == idempotency_key(&u.body)),
        "{keys:?}"
    );
}

#[tokio::test]
async fn a_final_error_is_returned_not_retried() {
    let (base, keys, _server) = scripted(vec![422]).await;
    let retries = Arc::new(Mutex::new(Vec::new()));
    let answer = submit(&upload(base, retries.clone())).await.unwrap();
    assert_eq!(answer.status, 422);
    assert_eq!(answer.attempts, 1);
    assert!(retries.lock().unwrap().is_empty());
    assert_eq!(keys.lock().unwrap().len(), 1);
}

/// A refused connection before the server ever answered fails at once
/// (nothing listens there); after it answered (a restart), it is retried
/// until the server is back.
#[tokio::test]
async fn a_refused_connection_fails_fast_unless_the_server_answered_before() {
    let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let retries = Arc::new(Mutex::new(Vec::new()));
    let start = std::time::Instant::now();
    let err = submit(&upload(format!("http://{addr}"), retries.clone()))
        .await
        .unwrap_err()
        .to_string();
    assert!(start.elapsed() < Duration::from_secs(2));
    assert!(
        err.contains("cannot connect") && err.contains("accelcal serve"),
        "{err}"
    );
    assert!(retries.lock().unwrap().is_empty(), "not retried");

    // The server answers 503, then goes away (a restart), then is back.
    let (base, _, server) = scripted(vec![503]).await;
    let mut u = upload(base.clone(), retries.clone());
    u.attempts = 60;
    let client = tokio::spawn(async move { submit(&u).await });
    eventually(Duration::from_secs(5), "a 503 to be answered", || async {
        (!retries.lock().unwrap().is_empty()).then_some(())
    })
    .await;
    server.abort();
    let _ = server.await;
    let addr = base.trim_start_matches("http://").to_owned();
    eventually(Duration::from_secs(10), "a refused attempt", || async {
        retries
            .lock()
            .unwrap()
            .iter()
            .any(|r| r.reason.starts_with("no answer"))
            .then_some(())
    })
    .await;
    let listener = tokio::net::TcpListener::bind(&addr).await.unwrap();
    let app = axum::Router::new().route(
        "/v1/calibrations",
        post(|| async { (StatusCode::CREATED, "{}") }),
    );
    tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    let answer = client.await.unwrap().unwrap();
    assert_eq!(answer.status, 201);
}

#[tokio::test]
async fn giving_up_says_so() {
    let (base, keys, _server) = scripted(vec![503]).await;
    let mut u = upload(base, Arc::new(Mutex::new(Vec::new())));
    u.attempts = 2;
    let answer = submit(&u).await.unwrap();
    assert_eq!((answer.status.as_u16(), answer.attempts), (503, 2));
    assert_eq!(keys.lock().unwrap().len(), 2);
}
