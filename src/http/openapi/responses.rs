//! Reusable problem answers, the sets of them operations share, and parameters.

use std::collections::BTreeMap;
use utoipa::openapi::path::{Parameter, ParameterBuilder, ParameterIn};
use utoipa::openapi::response::{Response, ResponseBuilder};
use utoipa::openapi::schema::{Schema, Type};

use utoipa::openapi::{ContentBuilder, HeaderBuilder, KnownFormat, Ref, RefOr, SchemaFormat};
use utoipa::{IntoParams, IntoResponses, ToResponse};

use super::schemas::reference;
use crate::domain::schema::of_type;

/// Implements `ToResponse` for a reusable problem answer.
macro_rules! problem_response {
    ($name:ident, $description:literal $(, $header:literal => $kind:expr)*) => {
        #[doc = $description]
        pub struct $name;
        impl<'r> ToResponse<'r> for $name {
            fn response() -> (&'r str, RefOr<Response>) {
                let content = ContentBuilder::new().schema(Some(reference("Problem"))).build();
                let response = ResponseBuilder::new()
                    .description($description)
                    .content(crate::http::problem::PROBLEM_JSON, content)
                    $(.header($header, HeaderBuilder::new().schema(of_type($kind)).build()))*
                    .build();
                (stringify!($name).trim_end_matches("Response"), response.into())
            }
        }
    };
}

problem_response!(ProblemResponse, "A problem document.");
problem_response!(BadRequest, "Malformed JSON, query, header or path.");
problem_response!(Unauthorized, "No valid token.", "WWW-Authenticate" => Type::String);
problem_response!(
    Forbidden,
    "The token's role (or station) does not allow this."
);
problem_response!(NotFound, "No such resource.");
problem_response!(TooLarge, "The body exceeds the size limit.");
problem_response!(
    UnsupportedMediaType,
    "Wrong Content-Type or Content-Encoding."
);
problem_response!(
    Invalid,
    "Well-formed but invalid or unidentifiable; `errors` lists the problems (the first 100)."
);
problem_response!(
    NotUsable,
    "Asked `require=usable`, and the coefficients are not usable (failed or overdue): `detail` says why."
);
problem_response!(
    StateConflict,
    "The calibration's state does not allow this (approving a withdrawn one, withdrawing twice): `detail` names the state."
);
problem_response!(
    Incomplete,
    "Either the calibration is not approved (`state-conflict`) or the records lack what a Digital Calibration Certificate needs (`incomplete-record`: the laboratory's name or country, the item's customer): `detail` names what."
);
problem_response!(
    WrongKind,
    "Not for this kind of calibration (`wrong-kind`): single-axis and triad calibrations do not mix (a triad for a sensor id holding single-axis calibrations or the other way round, or a single-axis document asked of a triad), and a temperature model has no certificate yet; `detail` says what to use instead."
);
problem_response!(
    NotCarried,
    "The firmware format asked for cannot carry the temperature model (`not-carried`): PX4 and ArduPilot correct the offset over temperature only, and an element of S changes over the range by more than its expanded uncertainty; `detail` names each such element with its change; export `json` or `c`."
);
problem_response!(
    PreconditionFailed,
    "A conditional write whose `If-Match` or `If-None-Match` does not hold (`precondition-failed`): the record changed since it was read (or exists, or does not); `ETag` is the current one, if any.",
    "ETag" => Type::String
);
problem_response!(Unavailable, "Database unavailable or server at capacity; retry after `Retry-After` seconds.", "Retry-After" => Type::Integer);

/// Implements `IntoResponses` for a set of the reusable problem answers that
/// operations share, each by reference, keyed by status.
macro_rules! problem_set {
    ($(#[$doc:meta])* $name:ident { $($status:literal => $response:ident),+ $(,)? }) => {
        $(#[$doc])*
        pub struct $name;
        impl IntoResponses for $name {
            fn responses() -> BTreeMap<String, RefOr<Response>> {
                BTreeMap::from([$((
                    $status.to_owned(),
                    RefOr::Ref(Ref::from_response_name(<$response as ToResponse>::response().0)),
                )),+])
            }
        }
    };
}

problem_set!(
    /// What every `/v1` operation may answer besides its own: no valid token
    /// (401), unavailable (503), or another problem.
    Always {
        "401" => Unauthorized,
        "503" => Unavailable,
        "default" => ProblemResponse,
    }
);
problem_set!(
    /// What an operation reading a request body may also answer: malformed
    /// (400), the wrong media type or coding (415), invalid content (422).
    BodyProblems {
        "400" => BadRequest,
        "415" => UnsupportedMediaType,
        "422" => Invalid,
    }
);

/// The `If-Match` and `If-None-Match` headers of a conditional write.
pub struct ConditionalHeaders;

impl IntoParams for ConditionalHeaders {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        let header = |name: &str, description: &str, schema| {
            ParameterBuilder::new()
                .name(name)
                .parameter_in(ParameterIn::Header)
                .description(Some(description))
                .schema(Some(schema))
                .build()
        };
        vec![
            header(
                "If-Match",
                "Write only if the record's current entity tag is one of these (as `GET` or the \
                 last write answered it in `ETag`), or, with `*`, only if it exists: a write \
                 based on what was read never replaces what someone else wrote since (412).",
                // `*`, or strong (or weak, never matching) entity tags
                // of visible ASCII but `"` and `,`, separated by commas.
                of_type(Type::String).max_length(Some(1024)).pattern(Some(
                    r#"^(\*|(W/)?"[!#-+\--~]*"( ?, ?(W/)?"[!#-+\--~]*")*)$"#,
                )),
            ),
            // A write takes only `*` here (400 otherwise): entity tags in
            // `If-None-Match` are for reads.
            header(
                "If-None-Match",
                "`*`: create only — 412 if the record exists. Nothing else is taken on a write (400).",
                of_type(Type::String).enum_values(Some(["*"])),
            ),
        ]
    }
}

/// The `Idempotency-Key` header.
pub struct IdempotencyKeyHeader;

impl IntoParams for IdempotencyKeyHeader {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        vec![
            ParameterBuilder::new()
                .name("Idempotency-Key")
                .parameter_in(ParameterIn::Header)
                .description(Some(
                    "A client-chosen key (1–255 visible ASCII characters) making retries safe.",
                ))
                .schema(Some(
                    of_type(Type::String)
                        .min_length(Some(1))
                        .max_length(Some(255))
                        .pattern(Some(r"^[\x21-\x7E]+$")),
                ))
                .build(),
        ]
    }
}

fn path_param(name: &str, schema: impl Into<RefOr<Schema>>) -> Parameter {
    ParameterBuilder::new()
        .name(name)
        .parameter_in(ParameterIn::Path)
        .required(utoipa::openapi::Required::True)
        .schema(Some(schema))
        .build()
}

/// The `{id}` of a calibration.
pub struct CalibrationIdPath;

impl IntoParams for CalibrationIdPath {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        vec![path_param(
            "id",
            of_type(Type::String).format(Some(SchemaFormat::KnownFormat(KnownFormat::Uuid))),
        )]
    }
}

/// The `{sensor_id}` of a sensor.
pub struct SensorIdPath;

impl IntoParams for SensorIdPath {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        vec![path_param("sensor_id", reference("Identifier"))]
    }
}
