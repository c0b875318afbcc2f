//! The signatures table: its columns, and a signature appended — by a
//! review's act ([`super::reviews`]) and by a hold ([`super::holds`]).

use rusqlite::{Connection, params};
use uuid::Uuid;

use super::rows;
use crate::domain::review::Signature;
use crate::store::StoreError;

/// The columns of `rows::signature`.
pub(super) const SIGNATURE_COLUMNS: &str =
    "seq, action, state, meaning, token_id, role, holder, signed_at, comment, superseded_by";

/// Appends a signature.
pub(super) fn insert(conn: &Connection, id: Uuid, s: &Signature) -> Result<(), StoreError> {
    rows::execute(
        conn,
        &format!(
            "INSERT INTO signatures (calibration_id, {SIGNATURE_COLUMNS}) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)"
        ),
        params![
            id.to_string(),
            s.seq,
            s.action.as_str(),
            s.state.as_str(),
            s.meaning,
            s.token_id,
            s.role.as_str(),
            s.holder,
            s.signed_at.to_string(),
            s.comment,
            s.superseded_by.map(|u| u.to_string())
        ],
    )?;
    Ok(())
}
