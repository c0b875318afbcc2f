//! A stored calibration as the pages and documents read it: its result
//! document of any kind, its state and signatures, and its instants as the
//! pages print them.

use super::format::instant;
use super::result::ResultDoc;
use crate::domain::timestamp::Timestamp;
use crate::http::problem::Problem;
use crate::http::{AppState, path_id};

/// A stored result document of any kind.
pub enum StoredDoc {
    /// A single-axis calibration's.
    Axis(Box<ResultDoc>),
    /// A triad's.
    Triad(Box<super::triad_result::TriadDoc>),
    /// A temperature model's.
    Thermal(Box<super::thermal_result::ThermalDoc>),
    /// A triad's temperature model's.
    ThermalTriad(Box<super::thermal_result::ThermalTriadDoc>),
}

impl StoredDoc {
    /// The calibration's id.
    pub fn id(&self) -> uuid::Uuid {
        match self {
            StoredDoc::Axis(d) => d.id,
            StoredDoc::Triad(d) => d.id,
            StoredDoc::Thermal(d) => d.id,
            StoredDoc::ThermalTriad(d) => d.id,
        }
    }

    /// Its sensor.
    pub fn sensor_id(&self) -> &str {
        match self {
            StoredDoc::Axis(d) => &d.sensor_id,
            StoredDoc::Triad(d) => &d.sensor_id,
            StoredDoc::Thermal(d) => &d.sensor_id,
            StoredDoc::ThermalTriad(d) => &d.sensor_id,
        }
    }
}

/// A stored result document's bytes (404 for an unknown id).
async fn result_of(state: &AppState, raw_id: &str) -> Result<(uuid::Uuid, bytes::Bytes), Problem> {
    let id = path_id(raw_id, "calibration")?;
    let bytes = state
        .store
        .calibration_result(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    Ok((id, bytes))
}

/// The 500 of a stored result `id` that does not read back.
fn unreadable(id: uuid::Uuid, e: serde_json::Error) -> Problem {
    tracing::error!(calibration_id = %id, error = %e, "a stored result does not read back");
    Problem::internal()
}

/// Reads a stored result document of any kind (404 for an unknown id).
pub async fn load_stored(state: &AppState, raw_id: &str) -> Result<StoredDoc, Problem> {
    let (id, bytes) = result_of(state, raw_id).await?;
    read(id, &bytes)
}

/// Stored result `bytes` of calibration `id`, by its kind.
fn read(id: uuid::Uuid, bytes: &[u8]) -> Result<StoredDoc, Problem> {
    let read = match kind(bytes).as_deref() {
        Some("thermal") => serde_json::from_slice(bytes).map(|d| StoredDoc::Thermal(Box::new(d))),
        Some("thermal_triad") => {
            serde_json::from_slice(bytes).map(|d| StoredDoc::ThermalTriad(Box::new(d)))
        }
        Some("triad") => serde_json::from_slice(bytes).map(|d| StoredDoc::Triad(Box::new(d))),
        _ => serde_json::from_slice(bytes).map(|d| StoredDoc::Axis(Box::new(d))),
    };
    read.map_err(|e| unreadable(id, e))
}

/// A stored result's `kind` (`"triad"`, `"thermal"`), none for a single
/// axis's result document.
fn kind(result: &[u8]) -> Option<String> {
    #[derive(serde::Deserialize)]
    struct Kind {
        kind: Option<String>,
    }
    serde_json::from_slice::<Kind>(result).ok()?.kind
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
