//! Query strings read into `#[serde(deny_unknown_fields)]` structs, refusing
//! unknown and repeated parameters with a 400 that names the parameter.
//!
//! (axum's `Query<T>` is the same idea, but its rejection does not say which
//! parameter was at fault; this one keeps serde's path to it.)

use axum::extract::FromRequestParts;
use axum::http::request::Parts;
use serde::de::DeserializeOwned;
use serde_path_to_error::Segment;

use super::problem::Problem;
use crate::domain::limits::{DEFAULT_PAGE, MAX_PAGE};
use crate::domain::timestamp::Timestamp;

/// A query string read as `T`.
pub struct Params<T>(pub T);

impl<S: Send + Sync, T: DeserializeOwned> FromRequestParts<S> for Params<T> {
    type Rejection = Problem;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Problem> {
        parse(parts.uri.query().unwrap_or_default()).map(Params)
    }
}

/// The query string `query` read as `T` (what [`Params`] does).
pub fn parse<T: DeserializeOwned>(query: &str) -> Result<T, Problem> {
    parse_pairs(form_urlencoded::parse(query.as_bytes()))
}

/// The query string `query` read as `T` after taking out the parameter
/// `name`, answered beside it (given once at most): for an operation whose
/// query is a shared set of parameters and one of its own.
pub fn parse_but<T: DeserializeOwned>(
    query: &str,
    name: &str,
) -> Result<(T, Option<String>), Problem> {
    let mut taken = None;
    let mut rest = form_urlencoded::Serializer::new(String::new());
    for (k, v) in form_urlencoded::parse(query.as_bytes()) {
        if k == name {
            if taken.is_some() {
                return Err(Problem::bad_parameter(name, "is given more than once"));
            }
            taken = Some(v.into_owned());
        } else {
            rest.append_pair(&k, &v);
        }
    }
    let parsed = parse(&rest.finish()).map_err(|mut p| {
        // An unknown parameter is told every parameter there is: `name`
        // too.
        if p.detail.contains("is not known here; expected ") {
            p.detail = format!("{}, or `{name}`", p.detail);
        }
        p
    })?;
    Ok((parsed, taken))
}

fn parse_pairs<T: DeserializeOwned>(pairs: form_urlencoded::Parse<'_>) -> Result<T, Problem> {
    let de = serde_urlencoded::Deserializer::new(pairs);
    serde_path_to_error::deserialize(de).map_err(|e| {
        // serde_urlencoded's messages carry no position or input.
        let msg = e.inner().to_string();
        let named = |lead: &str| {
            msg.strip_prefix(lead)
                .and_then(|rest| rest.split_once('`'))
                .map(|(name, _)| name.to_owned())
        };
        if let Some(name) = named("unknown field `") {
            let expected = msg.split_once(", expected ").map_or("", |(_, e)| e);
            return Problem::bad_parameter(
                &name,
                format!("is not known here; expected {expected}"),
            );
        }
        if let Some(name) = named("duplicate field `") {
            return Problem::bad_parameter(&name, "is given more than once");
        }
        if let Some(name) = named("missing field `") {
            return Problem::bad_parameter(&name, "is required");
        }
        let name = e
            .path()
            .iter()
            .find_map(|s| match s {
                Segment::Map { key } => Some(key.clone()),
                _ => None,
            })
            .unwrap_or_else(|| "query".to_owned());
        Problem::bad_parameter(&name, format!("is malformed: {msg}"))
    })
}

/// The page size: `limit`, 1 to [`MAX_PAGE`], default [`DEFAULT_PAGE`].
pub fn limit(raw: Option<&str>) -> Result<usize, Problem> {
    match raw {
        None => Ok(DEFAULT_PAGE),
        Some(s) => s
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=MAX_PAGE).contains(n))
            .ok_or_else(|| {
                Problem::bad_parameter("limit", format!("must be an integer from 1 to {MAX_PAGE}"))
            }),
    }
}

/// An RFC 3339 instant parameter.
pub fn instant(name: &str, raw: Option<&str>) -> Result<Option<Timestamp>, Problem> {
    raw.map(|s| Timestamp::parse(s).map_err(|e| Problem::bad_parameter(name, e)))
        .transpose()
}
