//! OpenAPI schemas of the wire shapes whose Rust types live in the pure core
//! (which stays free of schema derives): terms, models, coefficient maps,
//! gravity components, and the string classes of [`super::text`].
//!
//! Each is a marker type implementing utoipa's `ToSchema`, built from the
//! same constants the validation uses, so the contract cannot drift from the
//! checks.

use accelcal_core::Term;
use serde_json::json;
use utoipa::openapi::schema::{
    AdditionalProperties, AnyOfBuilder, ArrayBuilder, ObjectBuilder, Schema, SchemaType, Type,
};
use utoipa::openapi::{Ref, RefOr};
use utoipa::{PartialSchema, ToSchema};

use super::limits::{
    GRAVITY_M_S2, MAX_ANGLE_STD_ARCSEC, MAX_BATCHES, MAX_CROSS_G, MAX_DESCRIPTION_CHARS,
    MAX_GRAVITY_COMPONENT, MAX_GRAVITY_REL_STD, MAX_HOLDER_CHARS, MAX_ID_CHARS, MAX_LABEL_CHARS,
    MAX_NOTES_CHARS, MAX_OUTPUTS, MAX_READING, MAX_RUNS, MAX_TEMPERATURE_STD_C, MAX_UNIT_CHARS,
};
use super::limits::{MAX_COVERAGE_FACTOR, MAX_INTERVAL_DAYS, MIN_COVERAGE_FACTOR};

/// Implements `ToSchema` for a marker type from a schema expression; the
/// schema's name is the type's without a `Schema` suffix.
macro_rules! marker_schema {
    ($(#[$doc:meta])* $name:ident => $build:expr) => {
        $(#[$doc])*
        pub struct $name;
        impl PartialSchema for $name {
            fn schema() -> RefOr<Schema> {
                $build
            }
        }
        impl ToSchema for $name {
            fn name() -> std::borrow::Cow<'static, str> {
                std::borrow::Cow::Borrowed(stringify!($name).trim_end_matches("Schema"))
            }
        }
    };
}

pub(crate) use marker_schema;

fn reference<T: ToSchema>() -> RefOr<Schema> {
    RefOr::Ref(Ref::from_schema_name(T::name()))
}

/// `{"type": <kind>}` with nothing else.
pub fn of_type(kind: Type) -> ObjectBuilder {
    ObjectBuilder::new().schema_type(SchemaType::new(kind))
}

/// `anyOf: [schema, {type: null}]`: a value that may also be `null`.
pub fn nullable(schema: RefOr<Schema>) -> RefOr<Schema> {
    RefOr::T(Schema::AnyOf(
        AnyOfBuilder::new()
            .item(schema)
            .item(of_type(Type::Null))
            .build(),
    ))
}

fn numbers(bound: f64, (min, max): (usize, usize), nullable: bool) -> ArrayBuilder {
    let kind = if nullable {
        SchemaType::from_iter([Type::Array, Type::Null])
    } else {
        SchemaType::new(Type::Array)
    };
    ArrayBuilder::new()
        .schema_type(kind)
        .items(
            of_type(Type::Number)
                .minimum(Some(-bound))
                .maximum(Some(bound)),
        )
        .min_items(Some(min))
        .max_items(Some(max))
}

/// `outputs` of a compensation.
pub fn outputs() -> utoipa::openapi::schema::Schema {
    utoipa::openapi::schema::OneOfBuilder::new()
        .item(
            numbers(MAX_READING, (1, MAX_OUTPUTS), false)
                .description(Some("A single-axis sensor's: one output each.")),
        )
        .item(
            ArrayBuilder::new()
                .items(numbers(MAX_READING, (3, 3), false))
                .min_items(Some(1))
                .max_items(Some(MAX_OUTPUTS))
                .description(Some("A triad's: one triple [u_x, u_y, u_z] each.")),
        )
        .build()
        .into()
}

/// `a_p`, `a_o` of a compensation.
pub fn cross_axis() -> ArrayBuilder {
    numbers(MAX_CROSS_G, (1, MAX_OUTPUTS), true)
}

/// `values` of a fusion: per term, the per-run values.
pub fn fuse_values() -> ObjectBuilder {
    of_type(Type::Object)
        .min_properties(Some(1))
        .property_names(Some(TermSchema::schema()))
        .additional_properties(Some(AdditionalProperties::RefOr(
            numbers(MAX_READING, (2, MAX_RUNS), false).build().into(),
        )))
}

/// `batches`, optional.
pub fn batches() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Integer, Type::Null]))
        .minimum(Some(1.0))
        .maximum(Some(MAX_BATCHES as f64))
}

/// An identifier or `null`.
pub fn nullable_identifier() -> RefOr<Schema> {
    nullable(reference::<Identifier>())
}

/// A label or `null`.
pub fn nullable_label() -> RefOr<Schema> {
    nullable(line(MAX_LABEL_CHARS).into())
}

/// A description or `null` (one line, at most 256 characters).
pub fn nullable_description() -> RefOr<Schema> {
    nullable(description().into())
}

/// A token holder's name, or null (one line, at most 128 characters).
pub fn nullable_holder() -> RefOr<Schema> {
    nullable(line(MAX_HOLDER_CHARS).into())
}

/// An output unit (one line, at most 32 characters).
pub fn unit() -> ObjectBuilder {
    line(MAX_UNIT_CHARS)
}

marker_schema!(
    /// A model term name.
    TermSchema => of_type(Type::String)
        .enum_values(Some(Term::ALL.iter().map(|t| t.name())))
        .description(Some(
            "Model terms (regressors): k0 (1), ki (a_i), kp (a_p), ko (a_o), kio (a_i·a_o), \
             kop (a_o·a_p), kpi (a_p·a_i), kii (a_i²), kpp (a_p²), koo (a_o²), kiii (a_i³).",
        ))
        .build()
        .into()
);

marker_schema!(
    /// A model: distinct terms, in column order.
    ModelSchema => ArrayBuilder::new()
        .items(reference::<TermSchema>())
        .min_items(Some(1))
        .max_items(Some(Term::ALL.len()))
        .unique_items(true)
        .build()
        .into()
);

marker_schema!(
    /// Values keyed by term name, in model order.
    CoefficientMap => of_type(Type::Object)
        .description(Some("Values keyed by term name, in model order."))
        .property_names(Some(TermSchema::schema()))
        .additional_properties(Some(AdditionalProperties::RefOr(of_type(Type::Number).into())))
        .build()
        .into()
);

marker_schema!(
    /// Values keyed by term name that may be `null`.
    NullableCoefficientMap => of_type(Type::Object)
        .property_names(Some(TermSchema::schema()))
        .additional_properties(Some(AdditionalProperties::RefOr(
            ObjectBuilder::new()
                .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
                .build()
                .into(),
        )))
        .build()
        .into()
);

marker_schema!(
    /// Gravity components `[a_i, a_p, a_o]` in g.
    GravitySchema => ArrayBuilder::new()
        .description(Some("Gravity components [a_i, a_p, a_o] in g."))
        .items(
            of_type(Type::Number)
                .minimum(Some(-MAX_GRAVITY_COMPONENT))
                .maximum(Some(MAX_GRAVITY_COMPONENT)),
        )
        .min_items(Some(3))
        .max_items(Some(3))
        .build()
        .into()
);

marker_schema!(
    /// An identifier: `sensor_id`, `station_id`.
    Identifier => of_type(Type::String)
        .min_length(Some(1))
        .max_length(Some(MAX_ID_CHARS))
        .pattern(Some("^[A-Za-z0-9][A-Za-z0-9._:-]*$"))
        .examples([json!("ACC-0042")])
        .build()
        .into()
);

/// A line of text (no control characters) of at most `max` characters.
pub fn line(max: usize) -> ObjectBuilder {
    of_type(Type::String)
        .min_length(Some(1))
        .max_length(Some(max))
        .pattern(Some(r"^[^\u0000-\u001F\u007F-\u009F]+$"))
}

/// Free text (no control characters but tab and line breaks).
pub fn text(max: usize) -> ObjectBuilder {
    of_type(Type::String)
        .min_length(Some(1))
        .max_length(Some(max))
        .pattern(Some(
            r"^[^\u0000-\u0008\u000B\u000C\u000E-\u001F\u007F-\u009F]+$",
        ))
}

/// Free text that says something: as [`text`], with at least one
/// character that is not white space (what [`crate::domain::review`]
/// requires of a comment or reason).
pub fn said(max: usize) -> ObjectBuilder {
    text(max).pattern(Some(SAID))
}

/// The pattern of [`said`]: text with no control characters but tab and
/// line breaks, at least one of its characters not white space.
pub const SAID: &str = r"^[^\u0000-\u0008\u000B\u000C\u000E-\u001F\u007F-\u009F]*[^\s\u0000-\u001F\u007F-\u009F][^\u0000-\u0008\u000B\u000C\u000E-\u001F\u007F-\u009F]*$";

/// A review's comment, or null.
pub fn nullable_comment() -> RefOr<Schema> {
    nullable(said(super::limits::MAX_COMMENT_CHARS).into())
}

/// A withdrawal's or supersession's reason.
pub fn reason() -> ObjectBuilder {
    said(super::limits::MAX_COMMENT_CHARS)
}

marker_schema!(
    /// A decision rule.
    RuleSchema => of_type(Type::String)
        .enum_values(Some(["simple", "guarded"]))
        .description(Some(
            "simple: pass when min ≤ value ≤ max; guarded (ILAC-G8): pass when \
             min + U ≤ value ≤ max − U, fail beyond min − U or max + U, else conditional.",
        ))
        .build()
        .into()
);

marker_schema!(
    /// A verdict.
    VerdictSchema => of_type(Type::String)
        .enum_values(Some(["pass", "conditional", "fail"]))
        .build()
        .into()
);

/// `limits` of a sensor type: per term, `{min?, max?}`.
pub fn limits() -> ObjectBuilder {
    let limit = of_type(Type::Object)
        .property("min", of_type(Type::Number))
        .property("max", of_type(Type::Number))
        .min_properties(Some(1))
        .additional_properties(Some(AdditionalProperties::<Schema>::FreeForm(false)));
    of_type(Type::Object)
        .property_names(Some(TermSchema::schema()))
        .additional_properties(Some(AdditionalProperties::RefOr(limit.build().into())))
}

/// `coverage_factor`, optional.
pub fn coverage_factor() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
        .minimum(Some(MIN_COVERAGE_FACTOR))
        .maximum(Some(MAX_COVERAGE_FACTOR))
}

/// What an expanded uncertainty holds fixed, as a budget states it: the
/// coverage probability or the coverage factor, the other null.
#[derive(utoipa::ToSchema)]
#[allow(dead_code)]
pub struct CoverageStated {
    /// The coverage probability each coefficient's coverage factor was
    /// chosen for (Student's t at its effective degrees of freedom); null
    /// when the sensor type fixes the factor.
    pub coverage_probability: Option<f64>,
    /// The coverage factor the sensor type fixes; null when a probability
    /// is stated.
    pub coverage_factor: Option<f64>,
}

/// A certificate's `degrees_of_freedom`, optional.
pub fn degrees_of_freedom() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
        .minimum(Some(1.0))
        .maximum(Some(super::limits::MAX_DEGREES_OF_FREEDOM))
}

/// `coverage_probability`, optional.
pub fn coverage_probability() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
        .minimum(Some(super::limits::MIN_COVERAGE_PROBABILITY))
        .maximum(Some(super::limits::MAX_COVERAGE_PROBABILITY))
}

/// `interval_days`, optional.
pub fn interval_days() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Integer, Type::Null]))
        .minimum(Some(1.0))
        .maximum(Some(f64::from(MAX_INTERVAL_DAYS)))
}

/// A label that must be given (one line, at most 64 characters).
pub fn label() -> ObjectBuilder {
    line(MAX_LABEL_CHARS)
}

/// A description (one line, at most 256 characters).
pub fn description() -> ObjectBuilder {
    line(MAX_DESCRIPTION_CHARS)
}

/// Free text of at most 4096 characters.
pub fn notes() -> ObjectBuilder {
    text(MAX_NOTES_CHARS)
}

/// An optional number within `range`.
fn optional_number(min: f64, max: f64) -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
        .minimum(Some(min))
        .maximum(Some(max))
}

/// A tumble stand's indexing error, arcseconds, optional.
pub fn angle_std_arcsec() -> ObjectBuilder {
    optional_number(0.0, MAX_ANGLE_STD_ARCSEC)
}

/// A local gravity value, m/s², optional.
pub fn gravity_m_s2() -> ObjectBuilder {
    optional_number(*GRAVITY_M_S2.start(), *GRAVITY_M_S2.end())
}

/// A relative uncertainty of gravity, optional.
pub fn gravity_rel_std() -> ObjectBuilder {
    optional_number(0.0, MAX_GRAVITY_REL_STD)
}

/// A thermometer's uncertainty, °C, optional.
pub fn temperature_std_c() -> ObjectBuilder {
    optional_number(0.0, MAX_TEMPERATURE_STD_C)
}

/// A plausible temperature, °C.
pub fn celsius() -> ObjectBuilder {
    let range = super::limits::TEMPERATURE_C;
    of_type(Type::Number)
        .minimum(Some(*range.start()))
        .maximum(Some(*range.end()))
}

/// A run's `temperature_c`: the run's, or one per position (a chamber that
/// drifts; the run's is their mean) — a single axis's run and a triad's
/// alike.
pub fn run_temperature() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
    use utoipa::openapi::schema::{AnyOfBuilder, ArrayBuilder, Schema, SchemaType};
    utoipa::openapi::RefOr::T(Schema::AnyOf(
        AnyOfBuilder::new()
            .description(Some(
                "The run's temperature, °C, or one per position (a chamber that drifts; the \
                 run's is their mean); give it for every run or none.",
            ))
            .item(celsius().schema_type(SchemaType::from_iter([Type::Number, Type::Null])))
            .item(
                ArrayBuilder::new()
                    .items(celsius())
                    .min_items(Some(1))
                    .max_items(Some(super::limits::MAX_POSITIONS)),
            )
            .build(),
    ))
}
