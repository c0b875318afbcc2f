//! The OpenAPI 3.1 contract, generated from the handlers' `#[utoipa::path]`
//! annotations and the request and response types, printed by
//! `accelcal openapi`, committed as `openapi.yaml` (a test fails when the
//! two differ) and served at `GET /openapi.yaml`.
//!
//! The result document's parts are types of the pure core, which carries no
//! schema derives; their schemas are built here by hand, from the same
//! constants the validation uses. schemathesis checks every answer of the
//! running server against them.

mod responses;
mod schemas;
mod thermal;

use std::sync::LazyLock;

use serde_json::{Value, json};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

pub use self::responses::*;
pub use self::schemas::*;
pub use self::thermal::*;
use crate::domain::schema::{
    CoefficientMap, GravitySchema, Identifier, ModelSchema, NullableCoefficientMap, TermSchema,
};

/// The document, generated once.
pub static OPENAPI: LazyLock<String> = LazyLock::new(document);

/// Bearer authentication for every operation but the probes.
struct Bearer;

impl Modify for Bearer {
    fn modify(&self, doc: &mut utoipa::openapi::OpenApi) {
        let scheme = HttpBuilder::new()
            .scheme(HttpAuthScheme::Bearer)
            .description(Some("A token from `POST /v1/tokens`, `accelcal token create` or `ACCELCAL_ADMIN_TOKEN`."))
            .build();
        doc.components
            .get_or_insert_with(Default::default)
            .add_security_scheme("bearer", SecurityScheme::Http(scheme));
    }
}

/// The document's source: everything but the paths, which come from the
/// routes themselves ([`super::api_routes`], [`super::probe_routes`]).
#[derive(OpenApi)]
#[openapi(
    info(
        title = "accelcal",
        description = include_str!("../docs/api.md"),
        license(name = "MIT OR Apache-2.0", identifier = "MIT OR Apache-2.0"),
    ),
    servers((url = "http://127.0.0.1:8080")),
    security(("bearer" = [])),
    tags((name = "calibrations"), (name = "review"), (name = "sensors"), (name = "sensor-types"), (name = "standards"), (name = "customers"), (name = "compute"), (name = "tokens"), (name = "audit"), (name = "events"), (name = "webhooks"), (name = "operations"), (name = "health")),
    components(
        schemas(
            TermSchema, ModelSchema, CoefficientMap, NullableCoefficientMap, GravitySchema, Identifier,
            MountSchema, PositionInSchema, ReadingInSchema, RunInSchema, SubmissionSchema, RawBodySchema, RunResultSchema,
            MeanEstimateSchema, BatchSchema, FusedEstimateSchema, EstimatesSchema, NormalizedSchema,
            PositionOutSchema, CalibrationResultSchema, StoredCalibrationSchema, StoredResultSchema, CorrectionSchema, SensorPageSchema,
            CalibrationPageSchema, AuditPageSchema, crate::domain::audit::AuditEntry, super::problem::ProblemBody, crate::domain::field::FieldError,
            TermBudgetSchema, UncertaintySchema, TermDecisionSchema, DecisionSchema, AsFoundSchema,
            SensitivitySchema, QualitySchema, StandOutSchema, TermStabilitySchema,
            PolynomialSchema, ThermalModelSchema, TriadThermalModelSchema, ThermalBodySchema, TriadThermalBodySchema,
            crate::domain::thermal::combine::FromCalibrations,
            crate::domain::standards::UsedStandard, crate::domain::review::Supersedes,
            crate::domain::schema::RuleSchema, crate::domain::schema::VerdictSchema,
            crate::domain::webhooks::Payload,
        ),
        responses(
            ProblemResponse, BadRequest, Unauthorized, Forbidden, NotFound, TooLarge,
            UnsupportedMediaType, Invalid, NotUsable, StateConflict, Incomplete, WrongKind, NotCarried,
            PreconditionFailed, Unavailable,
        ),
    ),
    modifiers(&Bearer),
)]
pub struct ApiDoc;

/// The document as YAML, deterministic (keys sorted), with the version of
/// this build and the JSON Schema conditional utoipa has no builder for:
/// only a station token may be bound to a station, and a rejection needs
/// its comment.
pub fn document() -> String {
    let mut doc = ApiDoc::openapi();
    doc.merge(super::api_routes().into_openapi());
    doc.merge(super::probe_routes().into_openapi());
    doc.info.version = env!("CARGO_PKG_VERSION").to_owned();
    // serde_norway's mappings keep insertion order: the document reads in
    // the order of the OpenAPI structs, maps (paths, schemas) sorted.
    let mut value = serde_norway::to_value(&doc).unwrap_or_default();
    let conditional = |v: Value| serde_norway::to_value(v).unwrap_or_default();
    if let Some(map) = value
        .get_mut("components")
        .and_then(|c| c.get_mut("schemas"))
        .and_then(|s| s.get_mut("TokenRequest"))
        .and_then(|t| t.as_mapping_mut())
    {
        map.insert(
            "if".into(),
            conditional(json!({"properties": {"role": {"enum": ["reader", "admin"]}}})),
        );
        map.insert(
            "then".into(),
            conditional(json!({"properties": {"station_id": {"type": "null"}}})),
        );
    }
    // A rejection says why: `comment` is required with `reject`.
    if let Some(map) = value
        .get_mut("components")
        .and_then(|c| c.get_mut("schemas"))
        .and_then(|s| s.get_mut("ReviewBody"))
        .and_then(|t| t.as_mapping_mut())
    {
        map.insert(
            "if".into(),
            conditional(
                json!({"properties": {"decision": {"const": "reject"}}, "required": ["decision"]}),
            ),
        );
        map.insert(
            "then".into(),
            conditional(
                json!({"required": ["comment"], "properties": {"comment": {"type": "string"}}}),
            ),
        );
    }
    fix_links(&mut value);
    serde_norway::to_string(&value).unwrap_or_default()
}

/// utoipa 5 writes a link's `operationId` as `operation_id` (and the like);
/// the specification's names are camel case.
fn fix_links(value: &mut serde_norway::Value) {
    use serde_norway::Value as Y;
    match value {
        Y::Mapping(map) => {
            if let Some(Y::Mapping(links)) = map.get_mut("links") {
                for (_, link) in links.iter_mut() {
                    if let Y::Mapping(fields) = link {
                        for (from, to) in [
                            ("operation_id", "operationId"),
                            ("operation_ref", "operationRef"),
                            ("request_body", "requestBody"),
                        ] {
                            if let Some(v) = fields.remove(from) {
                                fields.insert(to.into(), v);
                            }
                        }
                    }
                }
            }
            for (_, v) in map.iter_mut() {
                fix_links(v);
            }
        }
        Y::Sequence(items) => items.iter_mut().for_each(fix_links),
        _ => {}
    }
}
