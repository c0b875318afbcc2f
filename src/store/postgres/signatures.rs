//! The signatures table: its columns, and a signature appended — by a
//! review's act ([`super::reviews`]) and by a hold ([`super::holds`]).

use deadpool_postgres::Transaction;
use uuid::Uuid;

use super::errors::map;
use crate::domain::review::Signature;
use crate::store::StoreError;

/// The columns of `rows::signature`.
pub(super) const SIGNATURE_COLUMNS: &str =
    "seq, action, state, meaning, token_id, role, holder, signed_at, comment, superseded_by";

/// Appends signature `s` to calibration `id`'s.
pub(super) async fn insert(
    tx: &Transaction<'_>,
    id: Uuid,
    s: &Signature,
) -> Result<(), StoreError> {
    let seq = i32::try_from(s.seq).map_err(|e| StoreError::corrupt("signatures", e))?;
    tx.execute(
        &format!(
            "INSERT INTO signatures (calibration_id, {SIGNATURE_COLUMNS}) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11)"
        ),
        &[
            &id,
            &seq,
            &s.action.as_str(),
            &s.state.as_str(),
            &s.meaning,
            &s.token_id,
            &s.role.as_str(),
            &s.holder,
            &s.signed_at.datetime(),
            &s.comment,
            &s.superseded_by,
        ],
    )
    .await
    .map_err(map)?;
    Ok(())
}
