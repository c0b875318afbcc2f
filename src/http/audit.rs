//! `GET /v1/audit`: the audit trail (issue 28 item 6), for reviewers and
//! admins, filtered by object, actor and time, in sequence order.
//!
//! Each entry carries its `prev` and `hash` ([`crate::domain::audit`]), so
//! that anyone can check a page against the documented canonical form;
//! `accelcal audit verify` checks the whole chain in the database. On
//! PostgreSQL the store seals pending entries before it reads
//! (`store::postgres::seal`), so a page holds every act committed before
//! the request.

use axum::Json;
use axum::extract::State;
use serde::Deserialize;
use utoipa::IntoParams;

use super::AppState;
use super::auth::require;
use super::page::Page;
use super::problem::Problem;
use super::query::{Params, instant, limit};
use crate::domain::audit::AuditEntry;
use crate::domain::auth::{Principal, Role};
use crate::store::AuditQuery;

/// Longest `object` or `actor` filter, in characters.
const MAX_FILTER_CHARS: usize = 200;

/// The query of `GET /v1/audit`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct AuditParams {
    /// Only entries about this object, e.g. `calibrations/{id}`.
    #[param(value_type = Option<String>, min_length = 1, max_length = 200)]
    object: Option<String>,
    /// Only entries by this token id or holder.
    #[param(value_type = Option<String>, min_length = 1, max_length = 200)]
    actor: Option<String>,
    /// Only entries at or after this instant (RFC 3339).
    #[param(value_type = Option<String>, format = DateTime)]
    from: Option<String>,
    /// Only entries at or before this instant (RFC 3339).
    #[param(value_type = Option<String>, format = DateTime)]
    to: Option<String>,
    /// The `next` cursor of the previous page (the last sequence number it
    /// held).
    #[param(value_type = Option<String>, pattern = "^[0-9]{1,18}$")]
    after: Option<String>,
    /// Page size.
    #[param(value_type = Option<u32>, minimum = 1, maximum = 500, default = 50)]
    limit: Option<String>,
}

/// A filter: 1 to [`MAX_FILTER_CHARS`] characters, compared as it is (one
/// that names nothing matches nothing).
fn filter(name: &str, raw: Option<String>) -> Result<Option<String>, Problem> {
    raw.map(|s| {
        if (1..=MAX_FILTER_CHARS).contains(&s.chars().count()) {
            Ok(s)
        } else {
            Err(Problem::bad_parameter(
                name,
                format!("must be 1 to {MAX_FILTER_CHARS} characters"),
            ))
        }
    })
    .transpose()
}

impl AuditParams {
    fn store_query(self) -> Result<(AuditQuery, usize), Problem> {
        let limit = limit(self.limit.as_deref())?;
        let after = match self.after.as_deref() {
            None => 0,
            Some(a) => a.parse::<i64>().ok().filter(|n| *n >= 0).ok_or_else(|| {
                Problem::bad_parameter("after", "must be a sequence number (0 or more)")
            })?,
        };
        Ok((
            AuditQuery {
                object: filter("object", self.object)?,
                actor: filter("actor", self.actor)?,
                from: instant("from", self.from.as_deref())?,
                to: instant("to", self.to.as_deref())?,
                after,
                limit: limit + 1,
            },
            limit,
        ))
    }
}

/// `GET /v1/audit`.
#[utoipa::path(
    get,
    path = "/v1/audit",
    tag = "audit",
    operation_id = "listAudit",
    summary = "The audit trail, in sequence order (reviewer or admin).",
    params(AuditParams),
    responses(
        (status = 200, description = "One page.", body = super::openapi::AuditPageSchema),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        super::openapi::Always,
    )
)]
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
    Params(q): Params<AuditParams>,
) -> Result<Json<Page<AuditEntry>>, Problem> {
    require(&principal, Role::Reviewer)?;
    let (query, limit) = q.store_query()?;
    let entries = state.store.audit(query).await?;
    let entries = entries.into_iter().map(AuditEntry::from).collect();
    Ok(Json(Page::from_overfetch(
        entries,
        limit,
        |e: &AuditEntry| e.seq.to_string(),
    )))
}
