//! Conditional writes over HTTP (RFC 9110 §13.1): `If-Match` and
//! `If-None-Match` on a definition's `PUT` become the store's
//! [`Precondition`]; its answer carries the record's `ETag`, and a
//! precondition that does not hold is a 412 `precondition-failed` with the
//! current `ETag`. Entity tags are strong: a weak one (`W/"…"`) never
//! matches a write's `If-Match`.

use axum::Json;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use super::problem::{Kind, Problem};
use crate::store::{Precondition, Put};

/// The longest precondition header read.
const MAX_HEADER: usize = 1024;

/// The one value of header `name`, if sent (twice is a 400).
fn one<'a>(headers: &'a HeaderMap, name: &'static str) -> Result<Option<&'a str>, Problem> {
    let mut values = headers.get_all(name).iter();
    let Some(first) = values.next() else {
        return Ok(None);
    };
    if values.next().is_some() {
        return Err(Problem::bad_parameter(name, "is sent more than once"));
    }
    let text = first
        .to_str()
        .ok()
        .filter(|t| t.len() <= MAX_HEADER)
        .ok_or_else(|| {
            Problem::bad_parameter(name, "must be visible ASCII, at most 1024 characters")
        })?;
    Ok(Some(text.trim()))
}

/// The entity tags of an `If-Match` list: each `"…"` (or `W/"…"`, kept as
/// sent so that it matches nothing), separated by commas.
fn tags(name: &'static str, list: &str) -> Result<Vec<String>, Problem> {
    list.split(',')
        .map(str::trim)
        .map(|t| {
            let opaque = t.strip_prefix("W/").unwrap_or(t);
            let quoted = opaque.len() >= 2 && opaque.starts_with('"') && opaque.ends_with('"');
            if quoted && !opaque[1..opaque.len() - 1].contains('"') {
                Ok(t.to_owned())
            } else {
                Err(Problem::bad_parameter(
                    name,
                    "must be `*` or entity tags in double quotes, separated by commas",
                ))
            }
        })
        .collect()
}

/// What a write's headers require of the record it replaces.
pub fn precondition(headers: &HeaderMap) -> Result<Precondition, Problem> {
    let matches = one(headers, "if-match")?;
    let none = one(headers, "if-none-match")?;
    match (matches, none) {
        (None, None) => Ok(Precondition::Any),
        (Some(_), Some(_)) => Err(Problem::bad_parameter(
            "If-None-Match",
            "is sent with If-Match: send one of them",
        )),
        (Some("*"), None) => Ok(Precondition::Exists),
        (Some(list), None) => Ok(Precondition::Matches(tags("If-Match", list)?)),
        (None, Some("*")) => Ok(Precondition::Absent),
        (None, Some(_)) => Err(Problem::bad_parameter(
            "If-None-Match",
            "on a write takes only `*` (create only)",
        )),
    }
}

/// A record with its `ETag`.
pub fn tagged<T: Serialize>(status: StatusCode, etag: &str, record: T) -> Response {
    let mut res = (status, Json(record)).into_response();
    if let Ok(v) = HeaderValue::from_str(etag) {
        res.headers_mut().insert(header::ETAG, v);
    }
    res
}

/// The answer to a conditional write of a `what` (`standard`, …): 201 or
/// 200 with the record and its `ETag`, or 412 with the current one.
pub fn written<T: Serialize>(put: Put<T>, what: &str) -> Result<Response, Problem> {
    match put {
        Put::Written {
            created,
            record,
            etag,
        } => {
            let status = if created {
                StatusCode::CREATED
            } else {
                StatusCode::OK
            };
            Ok(tagged(status, &etag, record))
        }
        Put::Failed { current } => {
            let detail = match &current {
                Some(tag) => format!(
                    "the {what} is not as the precondition requires: its entity tag is now \
                     {tag} (someone wrote it since you read it, or it exists); GET it again, \
                     and send its ETag in If-Match"
                ),
                None => format!(
                    "there is no such {what}: If-Match requires one (send If-None-Match: * to \
                     create it)"
                ),
            };
            let mut res = Problem::new(Kind::PreconditionFailed, detail).into_response();
            if let Some(v) = current.and_then(|t| HeaderValue::from_str(&t).ok()) {
                res.headers_mut().insert(header::ETAG, v);
            }
            Ok(res)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pre(pairs: &[(&'static str, &str)]) -> Result<Precondition, Problem> {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(*k, HeaderValue::from_str(v).unwrap());
        }
        precondition(&h)
    }

    #[test]
    fn headers_become_preconditions() {
        assert_eq!(pre(&[]).unwrap(), Precondition::Any);
        assert_eq!(pre(&[("if-match", "*")]).unwrap(), Precondition::Exists);
        assert_eq!(
            pre(&[("if-none-match", "*")]).unwrap(),
            Precondition::Absent
        );
        assert_eq!(
            pre(&[("if-match", r#""a", W/"b""#)]).unwrap(),
            Precondition::Matches(vec![r#""a""#.into(), r#"W/"b""#.into()])
        );
        for bad in [
            vec![("if-match", "abc")],
            vec![("if-match", r#""a"b""#)],
            vec![("if-none-match", r#""a""#)],
            vec![("if-match", "*"), ("if-none-match", "*")],
            vec![("if-match", "*"), ("if-match", "*")],
        ] {
            let e = pre(&bad).unwrap_err();
            assert_eq!(e.kind, Kind::Malformed, "{bad:?}");
        }
        // A weak tag never matches a strong one.
        let Precondition::Matches(t) = pre(&[("if-match", r#"W/"abc""#)]).unwrap() else {
            panic!()
        };
        assert!(!Precondition::Matches(t).holds(Some(r#""abc""#)));
    }
}
