//! `POST /v1/fuse`: mean and batch-estimation fusion of per-run values the
//! caller identified elsewhere (how the paper's Table 2 is reproduced).

use accelcal_core::{Error as CoreError, Estimates, FusionError, TermMap, estimate};
use serde::Deserialize;

use super::field::{Errors, Invalid, Loc};
use super::limits::{DEFAULT_BATCHES, MAX_BATCHES, MAX_READING, MAX_RUNS};

/// The body of a fusion request.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FuseRequest {
    /// Per-run values keyed by term (`{"k0": [...], "ki": [...]}`); every
    /// term needs the same number of values, at least two per batch.
    #[schema(schema_with = crate::domain::schema::fuse_values)]
    pub values: TermMap<Vec<f64>>,
    /// Fusion batches (default 2).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::batches)]
    pub batches: Option<u64>,
}

impl FuseRequest {
    /// Checks the values and fuses them.
    pub fn fuse(self) -> Result<Estimates, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        let values_at = root.key("values");
        if self.values.is_empty() {
            errors.add(values_at, "must name at least one term");
        }
        for (term, xs) in self.values.iter() {
            let at = values_at.key(term.name());
            if !(2..=MAX_RUNS).contains(&xs.len()) {
                errors.add(
                    at,
                    format!("must hold 2 to {MAX_RUNS} values, not {}", xs.len()),
                );
                continue;
            }
            for (k, x) in xs.iter().enumerate() {
                if x.abs() > MAX_READING {
                    errors.add(
                        at.index(k),
                        format!("must be of magnitude at most {MAX_READING:e}"),
                    );
                }
            }
        }
        if let Some(b) = self.batches
            && !(1..=MAX_BATCHES).contains(&b)
        {
            errors.add(
                root.key("batches"),
                format!("must be an integer from 1 to {MAX_BATCHES}"),
            );
        }
        if !errors.is_empty() {
            return Err(errors.into_invalid());
        }
        let batches_given = self.batches.is_some();
        // Model order, whatever order the object had.
        let mut values = self.values.0;
        values.sort_by_key(|(t, _)| *t);
        let batches = self.batches.unwrap_or(DEFAULT_BATCHES) as usize;
        estimate(&TermMap(values), batches).map_err(|e| {
            let pointer = match &e {
                CoreError::ValueCount { term, .. } => values_at.key(term.name()).to_string(),
                CoreError::Fusion {
                    source: FusionError::TooFewRuns { .. } | FusionError::NoBatches,
                    ..
                } if batches_given => root.key("batches").to_string(),
                CoreError::Fusion { term, .. } | CoreError::NonFiniteResult { term, .. } => {
                    values_at.key(term.name()).to_string()
                }
                _ => values_at.to_string(),
            };
            Invalid::one(pointer, e.to_string())
        })
    }
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    fn fuse(body: serde_json::Value) -> Result<Estimates, Invalid> {
        serde_json::from_value::<FuseRequest>(body).unwrap().fuse()
    }

    fn pointers(e: Invalid) -> Vec<String> {
        e.errors.into_iter().map(|e| e.pointer).collect()
    }

    #[test]
    fn values_may_reach_the_magnitude_bound_but_not_pass_it() {
        let over = MAX_READING * (1.0 + f64::EPSILON);
        let e = fuse(json!({"values": {"k0": [1.0, -over, 3.0, over]}})).unwrap_err();
        assert_eq!(pointers(e), ["/values/k0/1", "/values/k0/3"]);
        let at = fuse(json!({"values": {"k0": [1.0, -MAX_READING, 3.0, MAX_READING]}}));
        assert!(at.is_ok(), "{at:?}");
    }

    /// Three values in the default two batches leave a batch of one: the
    /// values are at fault. The same with `batches` given: the batches are.
    #[test]
    fn a_batch_of_one_names_the_values_or_the_batches_given() {
        let e = fuse(json!({"values": {"k0": [1.0, 2.0, 4.0]}})).unwrap_err();
        assert_eq!(pointers(e), ["/values/k0"]);
        let e = fuse(json!({"values": {"k0": [1.0, 2.0, 4.0]}, "batches": 2})).unwrap_err();
        assert_eq!(pointers(e), ["/batches"]);
    }
}
