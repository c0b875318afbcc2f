//! A stored calibration as the pages and documents read it: its result
//! document of either kind, its state and signatures, and its instants as
//! the pages print them.

use super::format::instant;
use super::result::ResultDoc;
use crate::domain::timestamp::Timestamp;
use crate::http::problem::Problem;
use crate::http::{AppState, path_id};

/// A stored result document of either kind.
pub enum StoredDoc {
    /// A single-axis calibration's.
    Axis(Box<ResultDoc>),
    /// A triad's.
    Triad(Box<super::triad_result::TriadDoc>),
}

/// Reads a stored result document of either kind (404 for an unknown id).
pub async fn load_stored(state: &AppState, raw_id: &str) -> Result<StoredDoc, Problem> {
    let id = path_id(raw_id, "calibration")?;
    let bytes = state
        .store
        .calibration_result(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    let read = if is_triad(&bytes) {
        serde_json::from_slice(&bytes).map(|d| StoredDoc::Triad(Box::new(d)))
    } else {
        serde_json::from_slice(&bytes).map(|d| StoredDoc::Axis(Box::new(d)))
    };
    read.map_err(|e| {
        tracing::error!(calibration_id = %id, error = %e, "a stored result does not read back");
        Problem::internal()
    })
}

/// Whether a stored result is a triad's (`"kind": "triad"`): those are
/// not single-axis result documents.
pub fn is_triad(result: &[u8]) -> bool {
    #[derive(serde::Deserialize)]
    struct Kind {
        kind: Option<String>,
    }
    serde_json::from_slice::<Kind>(result).is_ok_and(|k| k.kind.as_deref() == Some("triad"))
}

/// A calibration's state and signatures.
pub async fn record(
    state: &AppState,
    raw_id: &str,
) -> Result<
    (
        crate::domain::review::State,
        Vec<crate::domain::review::Signature>,
    ),
    Problem,
> {
    let id = path_id(raw_id, "calibration")?;
    let summary = state
        .store
        .calibration_summary(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    Ok((summary.state, state.store.signatures(id).await?))
}

/// A stored instant, as the pages print it.
pub fn when(text: &str) -> String {
    Timestamp::parse(text).map_or_else(|_| text.to_owned(), |t| instant(&t))
}
