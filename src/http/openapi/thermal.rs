//! Schemas of a temperature model's body and of a single axis's and a
//! triad's temperature models (`POST /v1/identify/thermal`,
//! `/v1/identify/thermal/triad`), whose polynomial is a type of the pure
//! core.

use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, OneOfBuilder, Schema, Type};
use utoipa::{PartialSchema, ToSchema};

use super::schemas::reference;
use crate::domain::schema::{marker_schema, of_type};

fn numbers() -> ArrayBuilder {
    ArrayBuilder::new().items(of_type(Type::Number))
}

marker_schema!(
    /// One coefficient's polynomial over temperature,
    /// `c(T) = Σ a_d (T − T_ref)^d`.
    PolynomialSchema => ObjectBuilder::new()
        .property("reference_c", of_type(Type::Number))
        .property("degree", of_type(Type::Integer).minimum(Some(0.0)).maximum(Some(3.0)))
        .property("coefficients", numbers())
        .property("std_uncertainties", numbers())
        .property("covariance", ArrayBuilder::new().items(numbers()))
        .property("chi2", of_type(Type::Number).minimum(Some(0.0)))
        .property("dof", of_type(Type::Integer).minimum(Some(1.0)))
        .property("inflation", of_type(Type::Number).minimum(Some(1.0)))
        .property("range_c", numbers().min_items(Some(2)).max_items(Some(2)))
        .property("selection", ArrayBuilder::new().items(ObjectBuilder::new()
            .property("f", of_type(Type::Number))
            .property("df1", of_type(Type::Integer))
            .property("df2", of_type(Type::Integer))
            .property("p_value", of_type(Type::Number))
            .property("alpha", of_type(Type::Number))
            .required("f").required("df1").required("df2").required("p_value").required("alpha")))
        .required("reference_c").required("degree").required("coefficients")
        .required("std_uncertainties").required("covariance").required("chi2").required("dof")
        .required("inflation").required("range_c").required("selection")
        .build()
        .into()
);

marker_schema!(
    /// A single axis's temperature model: its set points, each identified
    /// and fused, and each coefficient's polynomial.
    ThermalModelSchema => ObjectBuilder::new()
        .property("sensor_id", of_type(Type::String))
        .property("unit", of_type(Type::String))
        .property("tolerance_k", of_type(Type::Number).minimum(Some(0.0)))
        .property("selection", of_type(Type::String).enum_values(Some(["backward", "forward", "fixed"])))
        .property("set_points", ArrayBuilder::new().items(ObjectBuilder::new()
            .property("temperature_c", of_type(Type::Number))
            .property("runs", ArrayBuilder::new().items(of_type(Type::Integer).minimum(Some(0.0))))
            .property("batches", of_type(Type::Integer).minimum(Some(1.0)))
            .property("coefficients", reference("CoefficientMap"))
            .property("std_errors", reference("CoefficientMap"))
            .required("temperature_c").required("runs").required("batches")
            .required("coefficients").required("std_errors")))
        .property("coefficients", ObjectBuilder::new()
            .additional_properties(Some(reference("Polynomial"))))
        .property("fitted_with", fitted_with())
        .property("thermometer_std_c", of_type(Type::Number).minimum(Some(0.0))
            .description(Some("The named thermometer's standard uncertainty, K: a coefficient read \
                at a temperature adds u_T · |dc/dT| to its budget. Absent without one.")))
        .required("sensor_id").required("unit").required("tolerance_k").required("selection")
        .required("set_points").required("coefficients")
        .build()
        .into()
);

/// The fit's parameters as they were asked (query parameters of the
/// route; those not given absent).
fn fitted_with() -> ObjectBuilder {
    ObjectBuilder::new().description(Some(
        "The fit's parameters as asked (`tolerance_k`, `reference_c`, `degree`, `selection`, \
         `min_span_k`, `max_condition`; those not given absent): what a reprocessing of the \
         stored model fits with again.",
    ))
}

fn triple(items: RefOr<Schema>) -> ArrayBuilder {
    ArrayBuilder::new()
        .items(items)
        .min_items(Some(3))
        .max_items(Some(3))
}

fn polynomials() -> ArrayBuilder {
    ArrayBuilder::new()
        .items(reference("Polynomial"))
        .min_items(Some(3))
        .max_items(Some(3))
}

marker_schema!(
    /// A triad's temperature model: its set points, each calibrated and
    /// fused, and each element of `b` and `S` (row by row) with its
    /// polynomial.
    TriadThermalModelSchema => ObjectBuilder::new()
        .property("sensor_id", ObjectBuilder::new().schema_type(
            utoipa::openapi::schema::SchemaType::from_iter([Type::String, Type::Null])))
        .property("unit", of_type(Type::String))
        .property("method", of_type(Type::String)
            .enum_values(Some(["known_orientations", "gravity_magnitude"]))
            .description(Some("How each set point was calibrated: runs at known orientations, or \
                static positions fitted from the gravity magnitude (S_xy, S_xz, S_yz zero by the \
                frame convention, their polynomials exactly zero).")))
        .property("tolerance_k", of_type(Type::Number).minimum(Some(0.0)))
        .property("selection", of_type(Type::String).enum_values(Some(["backward", "forward", "fixed"])))
        .property("set_points", ArrayBuilder::new().items(ObjectBuilder::new()
            .property("temperature_c", of_type(Type::Number))
            .property("runs", ArrayBuilder::new().items(of_type(Type::Integer).minimum(Some(0.0)))
                .description(Some("Its runs, or its static positions (indices).")))
            .property("batches", of_type(Type::Integer).minimum(Some(1.0)))
            .property("b", triple(of_type(Type::Number).into()))
            .property("b_std_errors", triple(of_type(Type::Number).into()))
            .property("S", triple(triple(of_type(Type::Number).into()).into()))
            .property("S_std_errors", triple(triple(of_type(Type::Number).into()).into()))
            .property("axes_dof", triple(ObjectBuilder::new()
                .description(Some("One axis's fused degrees of freedom by single-axis term (k0 of \
                    b_m; ki, kp, ko of row m of S); an infinite ν left out."))
                .additional_properties(Some(of_type(Type::Number).minimum(Some(0.0)))).into()))
            .required("temperature_c").required("runs").required("batches")
            .required("b").required("b_std_errors").required("S").required("S_std_errors")))
        .property("fitted_with", fitted_with())
        .property("b", polynomials())
        .property("S", triple(polynomials().into()))
        .property("thermometer_std_c", of_type(Type::Number).minimum(Some(0.0))
            .description(Some("The named thermometer's standard uncertainty, K: an element read \
                at a temperature adds u_T · |de/dT| to its budget. Absent without one.")))
        .required("sensor_id").required("unit").required("tolerance_k").required("selection")
        .required("set_points").required("b").required("S")
        .build()
        .into()
);

marker_schema!(
    /// A temperature model's JSON body: runs sent whole (each with its
    /// `temperature_c`), or stored calibrations named by id.
    ThermalBodySchema => RefOr::T(Schema::OneOf(OneOfBuilder::new()
        .description(Some("A single-axis submission whose runs carry their temperatures, or a \
            body naming two to 64 stored single-axis calibrations of the sensor, each tumbled \
            at its own temperature (`calibrations`: their ids)."))
        .item(reference("Submission"))
        .item(reference("FromCalibrations"))
        .build()))
);

marker_schema!(
    /// A triad's temperature model's JSON body: a triad body whose runs,
    /// static positions or recording carry their temperatures, or stored
    /// triad calibrations named by id.
    TriadThermalBodySchema => RefOr::T(Schema::OneOf(OneOfBuilder::new()
        .description(Some("A triad body whose runs (static positions, recording samples) \
            carry their temperatures, or a body naming two to 64 stored triad calibrations of \
            the sensor, each tumbled at one temperature (`calibrations`: their ids)."))
        .item(reference("TriadBody"))
        .item(reference("FromCalibrations"))
        .build()))
);
