//! `GET /v1/backup`: a consistent copy of a SQLite database, taken while the
//! service runs. The served file is this process's alone (no other process
//! may open it while it runs), so an online backup goes through the service.

use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::auth::require;
use super::problem::Problem;
use crate::domain::auth::{Principal, Role};
use crate::domain::timestamp::Timestamp;

/// `GET /v1/backup` (admin): the whole SQLite database as one file.
#[utoipa::path(
    get,
    path = "/v1/backup",
    tag = "operations",
    operation_id = "getBackup",
    summary = "A consistent copy of the SQLite database, taken while the service runs.",
    description = "SQLite only (`VACUUM INTO`: one read transaction, writes go on). \
        Save it with `curl -fo copy.db`; restore it with the service stopped. \
        PostgreSQL answers 501: back it up with `pg_dump`.",
    responses(
        (status = 200, description = "The database file.", content((String = "application/vnd.sqlite3"))),
        (status = 403, response = super::openapi::Forbidden),
        (status = 501, response = super::openapi::ProblemResponse),
        super::openapi::Always,
    )
)]
pub async fn backup(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Response, Problem> {
    require(&principal, Role::Admin)?;
    let Some(copy) = state.store.backup().await? else {
        return Err(Problem::not_implemented(
            "this database is PostgreSQL: back it up with pg_dump",
        ));
    };
    // Open, then unlink: the open file is read to its end, and nothing is
    // left behind even if the client goes away.
    let file = std::fs::File::open(copy.path()).map_err(|e| {
        tracing::error!(error = %e, "the backup copy could not be reopened");
        Problem::internal()
    })?;
    let len = file.metadata().map(|m| m.len()).ok();
    drop(copy);
    let stream = tokio_util::io::ReaderStream::new(tokio::fs::File::from_std(file));
    let name = format!(
        "attachment; filename=\"accelcal-{}.db\"",
        Timestamp::now().to_string().replace(':', "")
    );
    let mut res = Body::from_stream(stream).into_response();
    let headers = res.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/vnd.sqlite3"),
    );
    if let Ok(v) = HeaderValue::from_str(&name) {
        headers.insert(header::CONTENT_DISPOSITION, v);
    }
    if let Some(n) = len {
        headers.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
    }
    Ok(res)
}
