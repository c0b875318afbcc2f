//! The CSV submission layout (RFC 4180, read with the `csv` crate), read into
//! the same [`Draft`] as JSON.
//!
//! ```text
//! # sensor_id: ACC-0042
//! # unit: mA
//! # model: k0 ki kp
//! # batches: 2
//! run,angle_deg,direction,output
//! 1,0,cw,0.005341914
//! 1,0,ccw,0.005679272
//! 1,90,cw,1.215466211
//! ...
//! ```
//!
//! * Before the header, `# key: value` lines carry the submission's other
//!   fields (`sensor_id`, `station_id`, `performed_at`, `unit`, `model` —
//!   terms separated by spaces or commas —, `mount`, `batches`, `notes`,
//!   `sensor_type`, the stand as `stand_id`, `stand_angle_std_arcsec`,
//!   `stand_gravity_rel_std`, and the standards used as `standard_stand`,
//!   `standard_thermometer`, `standard_gravity`); an unknown key is refused
//!   like an unknown JSON field. A `#` line without a colon is a comment; blank lines are skipped.
//! * The first other line is the header. Columns, in any order: `run` (or
//!   `test`), the position as `angle_deg` or as `a_i`, `a_p`, `a_o` (or
//!   both), optional `label`, optional `direction` (informational),
//!   optional `temperature_c` (the run's, the same on each of its rows, or
//!   one per position for a chamber that drifts: the same on each row of a
//!   position, the run's then their mean), and
//!   `output` (or `mean`, `std`, `count`). Fields may be double-quoted, with `""` for a quote and line
//!   breaks inside quotes.
//! * After the header every line is data: a run named `#1` or a label
//!   starting with `#` is a value like any other.
//! * A station that averages on board gives `mean`, `std` (sample standard
//!   deviation) and `count` columns instead of `output`: each row is then
//!   one run's summary at one position, and a run has one row per position.
//! * Each row is one sample. Positions are numbered in order of first
//!   appearance (indexed by a hash of angle, components and label), runs
//!   likewise; every run must have samples at every position. The limits on
//!   positions, runs and samples are checked while reading.
//! * A UTF-8 byte order mark and CR, LF or CRLF line ends are accepted.
//!
//! Problems with the layout or a row name the CSV line; problems with a
//! metadata value point at the field (`/batches`).

use accelcal_core::Term;

mod rows;

use super::FIELDS;
use super::draft::{Draft, Slot, StandDraft, StandardsDraft};
use super::json::{angle_std, gravity_std, mount, performed_at, term};
use super::node::{Scalar, keep};
use crate::domain::field::{Errors, Loc};
use crate::domain::limits::*;
use crate::domain::text::{Chars, echo};

/// The columns a CSV header may name.
pub const COLUMNS: &[&str] = &[
    "run",
    "test",
    "angle_deg",
    "a_i",
    "a_p",
    "a_o",
    "label",
    "direction",
    "temperature_c",
    "output",
    "mean",
    "std",
    "count",
];

/// The submission fields a `# key: value` line may set: all but the two the
/// rows themselves make up, the `stand` object, whose members are set by
/// `stand_id`, `stand_angle_std_arcsec` and `stand_gravity_rel_std`, and the
/// `standards` object, whose members are `standard_stand`,
/// `standard_thermometer` and `standard_gravity`.
pub fn metadata_keys() -> impl Iterator<Item = &'static str> {
    FIELDS
        .iter()
        .copied()
        .filter(|k| !matches!(*k, "positions" | "runs" | "stand" | "standards"))
        .chain(STAND_KEYS)
        .chain(STANDARD_KEYS)
}

/// The metadata keys of the `standards` object's members.
const STANDARD_KEYS: [&str; 3] = ["standard_stand", "standard_thermometer", "standard_gravity"];

/// The metadata keys of the `stand` object's members.
const STAND_KEYS: [&str; 3] = [
    "stand_id",
    "stand_angle_std_arcsec",
    "stand_gravity_rel_std",
];

pub(super) fn at_line(errors: &mut Errors, line: usize, detail: impl std::fmt::Display) {
    errors.add(Loc::Root, format!("CSV line {line}: {detail}"));
}

/// Reads a CSV submission; `Err` when the body is not UTF-8.
pub fn read(bytes: &[u8]) -> Result<Draft, std::str::Utf8Error> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let text = std::str::from_utf8(bytes)?;
    // Every line end becomes LF, so lines count alike: CR-only line ends
    // (old spreadsheets), and CRLF (Windows), whose lines the csv crate
    // numbers one short after the first (rust-csv issue #395: it counts a
    // line only when it consumes the `\n` of a terminator it ended at `\r`).
    let text: std::borrow::Cow<'_, str> = match (text.contains('\r'), text.contains('\n')) {
        (false, _) => text.into(),
        (true, true) => text.replace("\r\n", "\n").into(),
        (true, false) => text.replace('\r', "\n").into(),
    };
    let mut draft = Draft::default();
    let (header_line, header_at) = metadata(&text, &mut draft);
    match header_at {
        Some(offset) => rows::rows(&text[offset..], header_line, &mut draft),
        None if draft.errors.is_empty() => {
            at_line(
                &mut draft.errors,
                header_line.max(1),
                "no header line and no samples",
            );
        }
        None => {}
    }
    Ok(draft)
}

/// Reads the `#` lines before the header into `draft`; gives the header's
/// line number and byte offset (`None` when there is no header).
fn metadata(text: &str, draft: &mut Draft) -> (usize, Option<usize>) {
    let mut offset = 0;
    let mut seen: Vec<&str> = Vec::new();
    for (n, raw) in text.split_inclusive('\n').enumerate() {
        let line = n + 1;
        let trimmed = raw.trim();
        if trimmed.is_empty() {
            offset += raw.len();
            continue;
        }
        let Some(comment) = trimmed.strip_prefix('#') else {
            return (line, Some(offset));
        };
        offset += raw.len();
        let Some((key, value)) = comment.split_once(':') else {
            continue;
        };
        let (key, value) = (key.trim(), value.trim());
        let Some(key) = metadata_keys().find(|k| *k == key) else {
            at_line(
                &mut draft.errors,
                line,
                format!(
                    "unknown field `{}`; expected one of: {}",
                    echo(key),
                    metadata_keys().collect::<Vec<_>>().join(", ")
                ),
            );
            continue;
        };
        if seen.contains(&key) {
            at_line(&mut draft.errors, line, format!("`{key}` is given twice"));
            continue;
        }
        seen.push(key);
        set(draft, key, value);
    }
    (text.split_inclusive('\n').count() + 1, None)
}

/// Sets a metadata field from its text, checked like the JSON member.
fn set(draft: &mut Draft, key: &'static str, value: &str) {
    let root = Loc::Root;
    let at = root.key(key);
    let errors = &mut draft.errors;
    let s = || Scalar::Str(value.to_owned());
    match key {
        "sensor_id" => {
            draft.sensor_id = slot(errors, at, s().string(MAX_ID_CHARS, Chars::Identifier))
        }
        "station_id" => {
            draft.station_id = slot(errors, at, s().string(MAX_ID_CHARS, Chars::Identifier))
        }
        "unit" => draft.unit = slot(errors, at, s().string(MAX_UNIT_CHARS, Chars::Line)),
        "notes" => draft.notes = slot(errors, at, s().string(MAX_NOTES_CHARS, Chars::Text)),
        "mount" => draft.mount = slot(errors, at, mount(s())),
        "performed_at" => draft.performed_at = slot(errors, at, performed_at(s())),
        "sensor_type" => {
            draft.sensor_type = slot(errors, at, s().string(MAX_ID_CHARS, Chars::Identifier))
        }
        "item_received_at" => draft.item_received_at = slot(errors, at, performed_at(s())),
        "item_condition" => {
            draft.item_condition = slot(errors, at, s().string(MAX_DESCRIPTION_CHARS, Chars::Line))
        }
        "stand_id" | "stand_angle_std_arcsec" | "stand_gravity_rel_std" => {
            let mut stand = match std::mem::take(&mut draft.stand) {
                Slot::Value(v) => v,
                _ => StandDraft::default(),
            };
            let number = || {
                value
                    .parse::<f64>()
                    .map_or_else(|_| s(), |x| Scalar::Num(x, None))
            };
            let read = match key {
                "stand_id" => keep(errors, at, s().string(MAX_ID_CHARS, Chars::Identifier))
                    .map(|id| stand.id = Some(id)),
                "stand_angle_std_arcsec" => {
                    keep(errors, at, angle_std(&number())).map(|x| stand.angle_std_arcsec = Some(x))
                }
                _ => keep(errors, at, gravity_std(&number()))
                    .map(|x| stand.gravity_rel_std = Some(x)),
            };
            draft.stand = if read.is_some() {
                Slot::Value(stand)
            } else {
                Slot::Invalid
            };
        }
        "standard_stand" | "standard_thermometer" | "standard_gravity" => {
            let mut standards = match std::mem::take(&mut draft.standards) {
                Slot::Value(v) => v,
                _ => StandardsDraft::default(),
            };
            let id = keep(errors, at, s().string(MAX_ID_CHARS, Chars::Identifier));
            let ok = id.is_some();
            match key {
                "standard_stand" => standards.stand = id,
                "standard_thermometer" => standards.thermometer = id,
                _ => standards.gravity = id,
            }
            draft.standards = if ok {
                Slot::Value(standards)
            } else {
                Slot::Invalid
            };
        }
        "batches" => {
            let v = value
                .parse::<u64>()
                .map_or_else(|_| s(), |n| Scalar::Num(n as f64, Some(n)));
            draft.batches = slot(errors, at, v.integer(1, MAX_BATCHES));
        }
        _ => {
            let mut terms: Vec<Term> = Vec::new();
            let mut ok = true;
            let names: Vec<&str> = value
                .split([',', ' ', '\t'])
                .filter(|t| !t.is_empty())
                .collect();
            if names.is_empty() || names.len() > Term::ALL.len() {
                errors.add(at, format!("must name 1 to {} terms", Term::ALL.len()));
                draft.model = Slot::Invalid;
                return;
            }
            for (k, name) in names.into_iter().enumerate() {
                match term(Scalar::Str(name.to_owned()), &terms) {
                    Ok(t) => terms.push(t),
                    Err(why) => {
                        errors.add(at.index(k), why);
                        ok = false;
                    }
                }
            }
            draft.model = if ok {
                Slot::Value(terms)
            } else {
                Slot::Invalid
            };
        }
    }
}

fn slot<T>(errors: &mut Errors, at: Loc<'_>, read: Result<T, String>) -> Slot<T> {
    Slot::from_read(keep(errors, at, read))
}

#[cfg(test)]
mod tests;
