//! Schemas of the wire shapes whose Rust types live in the pure core or are
//! read by hand (the submission), built from the limits the checks use.

use serde_json::Value;
use utoipa::openapi::schema::{
    AdditionalProperties, AllOfBuilder, AnyOfBuilder, ArrayBuilder, ObjectBuilder, Schema,
    SchemaType, Type,
};
use utoipa::openapi::{KnownFormat, Ref, RefOr, SchemaFormat};
use utoipa::{PartialSchema, ToSchema};

use crate::domain::limits::*;
use crate::domain::schema::{line, marker_schema, nullable, of_type, text};

pub(super) fn reference(name: &str) -> RefOr<Schema> {
    RefOr::Ref(Ref::from_schema_name(name))
}

fn array(items: impl Into<RefOr<Schema>>) -> ArrayBuilder {
    let items: RefOr<Schema> = items.into();
    ArrayBuilder::new().items(items)
}

fn number(bound: f64) -> ObjectBuilder {
    of_type(Type::Number)
        .minimum(Some(-bound))
        .maximum(Some(bound))
}

fn closed(o: ObjectBuilder) -> ObjectBuilder {
    o.schema_type(SchemaType::new(Type::Object))
        .additional_properties(Some(AdditionalProperties::<Schema>::FreeForm(false)))
}

/// A position's members, closed, with `required` one of them.
fn position_with(required: &str) -> ObjectBuilder {
    closed(ObjectBuilder::new())
        .property("angle_deg", number(MAX_ANGLE_DEG))
        .property(
            "a",
            array(number(MAX_GRAVITY_COMPONENT))
                .min_items(Some(3))
                .max_items(Some(3)),
        )
        .property("label", nullable(text(MAX_LABEL_CHARS).into()))
        .required(required)
}

marker_schema!(
    /// A position by angle or by gravity components: two closed shapes,
    /// each naming every member, so that generated clients type a position
    /// literal as one of them (a bare `required` beside the members is read
    /// by some generators as an object with no members at all).
    PositionInSchema => RefOr::T(Schema::AnyOf(AnyOfBuilder::new()
        .description(Some(
            "A position by dividing-head angle (with the mount) or by explicit gravity \
             components (norm 0.9–1.1 g); with both, they must agree.",
        ))
        .item(position_with("angle_deg"))
        .item(position_with("a"))
        .build()))
);

marker_schema!(
    /// A body passed as it is (a CSV submission, a stored submission):
    /// bytes, so that generated clients neither parse nor re-encode it.
    RawBodySchema => of_type(Type::String)
        .format(Some(SchemaFormat::KnownFormat(KnownFormat::Binary)))
        .build()
        .into()
);

marker_schema!(
    /// A position's reading in one run: its samples, or their summary.
    ReadingInSchema => RefOr::T(Schema::AnyOf(AnyOfBuilder::new()
        .description(Some(
            "The samples at one position of one run, or — from a station that averages on \
             board — their mean, sample standard deviation (divisor n − 1) and count; a \
             summary's samples are not counted against the limits on samples.",
        ))
        .item(array(number(MAX_READING)).min_items(Some(1)).max_items(Some(MAX_SAMPLES)))
        .item(closed(ObjectBuilder::new())
            .property("mean", number(MAX_READING))
            .property("std", of_type(Type::Number)
                .minimum(Some(0.0))
                .maximum(Some(MAX_READING))
                .description(Some("Sample standard deviation; 0 when `count` is 1.")))
            .property("count", of_type(Type::Integer)
                .minimum(Some(1.0))
                .maximum(Some(MAX_SUMMARY_COUNT as f64)))
            .required("mean")
            .required("std")
            .required("count"))
        .build()))
);

marker_schema!(
    /// One run's readings.
    RunInSchema => closed(ObjectBuilder::new())
        .property("temperature_c", crate::domain::schema::run_temperature())
        .property(
            "readings",
            array(reference("ReadingIn"))
                .description(Some("One reading per position, in position order."))
                .min_items(Some(1))
                .max_items(Some(MAX_POSITIONS)),
        )
        .required("readings")
        .build()
        .into()
);

marker_schema!(
    /// A tumble-test submission.
    SubmissionSchema => closed(ObjectBuilder::new())
        .property("sensor_id", reference("Identifier"))
        .property("station_id", nullable(reference("Identifier")))
        .property("performed_at", ObjectBuilder::new()
            .schema_type(SchemaType::from_iter([Type::String, Type::Null]))
            .format(Some(SchemaFormat::KnownFormat(KnownFormat::DateTime)))
            .description(Some("RFC 3339; default the time received; from 1970 to a day ahead.")))
        .property("unit", nullable(line(MAX_UNIT_CHARS).description(Some("Unit of the outputs (default \"output\").")).into()))
        .property("model", nullable(reference("Model")))
        .property("mount", nullable(reference("Mount")))
        .property("positions", array(reference("PositionIn")).min_items(Some(1)).max_items(Some(MAX_POSITIONS)))
        .property("runs", array(reference("RunIn")).min_items(Some(1)).max_items(Some(MAX_RUNS)))
        .property("batches", ObjectBuilder::new()
            .schema_type(SchemaType::from_iter([Type::Integer, Type::Null]))
            .description(Some("Fusion batches (default 2); each needs at least two runs. Not used for a single run."))
            .minimum(Some(1.0))
            .maximum(Some(MAX_BATCHES as f64)))
        .property("notes", nullable(text(MAX_NOTES_CHARS).into()))
        .property("sensor_type", nullable(reference("Identifier")))
        .property("stand", nullable(closed(ObjectBuilder::new())
            .description(Some("The tumble stand's systematic uncertainties (1σ); each defaults to 0."))
            .property("id", nullable(reference("Identifier")))
            .property("angle_std_arcsec", ObjectBuilder::new()
                .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
                .minimum(Some(0.0)).maximum(Some(MAX_ANGLE_STD_ARCSEC)))
            .property("gravity_rel_std", ObjectBuilder::new()
                .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
                .minimum(Some(0.0)).maximum(Some(MAX_GRAVITY_REL_STD)))
            .build().into()))
        .property("standards", nullable(closed(ObjectBuilder::new())
            .description(Some("The reference standards used, by id (GET /v1/standards): the stand, and optionally a \
                thermometer and a local gravity value. Each must be of its role's kind and in calibration at \
                `performed_at`; the stand's indexing error and the gravity value's relative uncertainty then \
                come from the registry, so `stand` may not be given beside it."))
            .property("stand", reference("Identifier"))
            .property("thermometer", nullable(reference("Identifier")))
            .property("gravity", nullable(reference("Identifier")))
            .required("stand")
            .build().into()))
        .property("item_received_at", ObjectBuilder::new()
            .schema_type(SchemaType::from_iter([Type::String, Type::Null]))
            .format(Some(SchemaFormat::KnownFormat(KnownFormat::DateTime)))
            .description(Some("When the laboratory received the item (the sensor): not after `performed_at`, not in the future.")))
        .property("item_condition", nullable(line(MAX_DESCRIPTION_CHARS).description(Some("The item's condition on receipt.")).into()))
        .required("sensor_id")
        .required("positions")
        .required("runs")
        .examples([serde_json::from_str::<Value>(include_str!("../../../examples/paper-4-runs.json")).unwrap_or(Value::Null)])
        .build()
        .into()
);

marker_schema!(
    /// The mount.
    MountSchema => of_type(Type::String)
        .enum_values(Some(["pendulum", "gate"]))
        .description(Some("pendulum: a = (−sin θ, cos θ, 0); gate: a = (−sin θ, 0, cos θ)."))
        .build()
        .into()
);

marker_schema!(
    /// One run's identification.
    RunResultSchema => ObjectBuilder::new()
        .property("coefficients", reference("CoefficientMap"))
        .property("std_errors", nullable(reference("CoefficientMap")))
        .property("residuals", array(of_type(Type::Number)))
        .property("residual_rms", of_type(Type::Number).minimum(Some(0.0)))
        .property("dof", of_type(Type::Integer).minimum(Some(0.0)))
        .required("coefficients").required("std_errors").required("residuals")
        .required("residual_rms").required("dof")
        .build()
        .into()
);

marker_schema!(
    /// The arithmetic mean across runs, with eq. 8 about it (null for a
    /// single run).
    MeanEstimateSchema => ObjectBuilder::new()
        .property("coefficients", reference("CoefficientMap"))
        .property("dispersion", nullable(reference("CoefficientMap")))
        .property("relative_dispersion", nullable(reference("NullableCoefficientMap")))
        .required("coefficients").required("dispersion").required("relative_dispersion")
        .build()
        .into()
);

marker_schema!(
    /// One fusion batch.
    BatchSchema => ObjectBuilder::new()
        .property("runs", array(of_type(Type::Integer).minimum(Some(0.0))))
        .property("mean", reference("CoefficientMap"))
        .property("std", reference("CoefficientMap"))
        .required("runs").required("mean").required("std")
        .build()
        .into()
);

marker_schema!(
    /// The batch-estimation fusion, with eq. 8 about it; for a single run,
    /// the run itself (no batches, eq. 8 null, and `note` says so).
    FusedEstimateSchema => ObjectBuilder::new()
        .property("batches", array(reference("Batch")))
        .property("coefficients", reference("CoefficientMap"))
        .property("std_errors", reference("CoefficientMap"))
        .property("dispersion", nullable(reference("CoefficientMap")))
        .property("relative_dispersion", nullable(reference("NullableCoefficientMap")))
        .property("note", of_type(Type::String).description(Some("Present for a single run: why there are no batches and no eq. 8.")))
        .required("batches").required("coefficients").required("std_errors")
        .required("dispersion").required("relative_dispersion")
        .build()
        .into()
);

marker_schema!(
    /// Mean and fused estimates.
    EstimatesSchema => ObjectBuilder::new()
        .property("mean", reference("MeanEstimate"))
        .property("fused", reference("FusedEstimate"))
        .required("mean").required("fused")
        .build()
        .into()
);

marker_schema!(
    /// Input-referred values from the fused coefficients.
    NormalizedSchema => ObjectBuilder::new()
        .description(Some("Input-referred values from the fused coefficients, where the terms exist."))
        .property("bias_g", of_type(Type::Number))
        .property("misalignment_p_rad", of_type(Type::Number))
        .property("misalignment_o_rad", of_type(Type::Number))
        .property("second_order_g_per_g2", of_type(Type::Number))
        .property("third_order_g_per_g3", of_type(Type::Number))
        .build()
        .into()
);

marker_schema!(
    /// A resolved position in a result.
    PositionOutSchema => ObjectBuilder::new()
        .property("a", reference("Gravity"))
        .property("angle_deg", of_type(Type::Number))
        .property("label", of_type(Type::String))
        .required("a")
        .build()
        .into()
);

fn date_time() -> ObjectBuilder {
    of_type(Type::String).format(Some(SchemaFormat::KnownFormat(KnownFormat::DateTime)))
}

fn string_or_null() -> ObjectBuilder {
    ObjectBuilder::new().schema_type(SchemaType::from_iter([Type::String, Type::Null]))
}

fn nullable_number() -> ObjectBuilder {
    ObjectBuilder::new().schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
}

fn per_term(item: &str) -> ObjectBuilder {
    of_type(Type::Object)
        .property_names(Some(crate::domain::schema::TermSchema::schema()))
        .additional_properties(Some(AdditionalProperties::RefOr(reference(item))))
}

marker_schema!(
    /// One coefficient's uncertainty budget.
    TermBudgetSchema => ObjectBuilder::new()
        .description(Some("In the coefficient's unit; combined = √(statistical² + indexing² + gravity² + model²), expanded = k × combined, k = t_{(1+p)/2}(ν_eff) for a stated probability p, p = 2·F_t(k; ν_eff) − 1 for a fixed k, ν_eff the Welch–Satterthwaite effective degrees of freedom of the components (GUM G.2b, truncated; null when infinite). `model` is the standard error of the fit to the run-averaged values when lack of fit is flagged, 0 otherwise (absent from results computed before it existed, as are the degrees of freedom, k and p of results computed before each term stated them)."))
        .property("statistical", of_type(Type::Number).minimum(Some(0.0)))
        .property("indexing", of_type(Type::Number).minimum(Some(0.0)))
        .property("gravity", of_type(Type::Number).minimum(Some(0.0)))
        .property("model", of_type(Type::Number).minimum(Some(0.0)))
        .property("combined", of_type(Type::Number).minimum(Some(0.0)))
        .property("degrees_of_freedom", ObjectBuilder::new()
            .description(Some("Each component's degrees of freedom; null where infinite (a Type B component whose certificate states none)."))
            .property("statistical", nullable_number())
            .property("indexing", nullable_number())
            .property("gravity", nullable_number())
            .property("model", nullable_number()))
        .property("effective_dof", ObjectBuilder::new()
            .schema_type(SchemaType::from_iter([Type::Integer, Type::Null]))
            .minimum(Some(1.0)))
        .property("coverage_factor", of_type(Type::Number).exclusive_minimum(Some(0.0)))
        .property("coverage_probability", of_type(Type::Number).exclusive_minimum(Some(0.0)).maximum(Some(1.0)))
        .property("expanded", of_type(Type::Number).minimum(Some(0.0)))
        .required("statistical").required("indexing").required("gravity")
        .required("combined").required("expanded")
        .build()
        .into()
);

marker_schema!(
    /// The uncertainty budget of every fused coefficient.
    UncertaintySchema => ObjectBuilder::new()
        .description(Some("What the expanded uncertainties hold fixed is one of `coverage_probability` (each term's k then follows from its effective degrees of freedom) and `coverage_factor` (a sensor type's fixed k); the other is null. Results computed before probabilities were stated have `coverage_factor` only."))
        .property("coverage_probability", nullable_number())
        .property("coverage_factor", ObjectBuilder::new()
            .schema_type(SchemaType::from_iter([Type::Number, Type::Null]))
            .exclusive_minimum(Some(0.0)))
        .property("terms", per_term("TermBudget"))
        .required("terms")
        .build()
        .into()
);

marker_schema!(
    /// One coefficient's judgement.
    TermDecisionSchema => ObjectBuilder::new()
        .property("value", of_type(Type::Number))
        .property("min", nullable_number())
        .property("max", nullable_number())
        .property("expanded", of_type(Type::Number).minimum(Some(0.0)))
        .property("verdict", reference("Verdict"))
        .required("value").required("min").required("max").required("expanded").required("verdict")
        .build()
        .into()
);

marker_schema!(
    /// The decision against the sensor type's limits.
    DecisionSchema => ObjectBuilder::new()
        .property("rule", reference("Rule"))
        .property("verdict", reference("Verdict"))
        .property("terms", per_term("TermDecision"))
        .required("rule").required("verdict").required("terms")
        .build()
        .into()
);

marker_schema!(
    /// As found: the previous coefficients' error at each position.
    AsFoundSchema => ObjectBuilder::new()
        .property("previous_calibration_id", of_type(Type::String).format(Some(SchemaFormat::KnownFormat(KnownFormat::Uuid))))
        .property("positions", array(ObjectBuilder::new()
            .property("error_output", of_type(Type::Number))
            .property("error_g", of_type(Type::Number))
            .required("error_output").required("error_g")))
        .property("max_abs_error_g", of_type(Type::Number).minimum(Some(0.0)))
        .required("previous_calibration_id").required("positions").required("max_abs_error_g")
        .build()
        .into()
);

marker_schema!(
    /// One coefficient's temperature sensitivity.
    SensitivitySchema => ObjectBuilder::new()
        .property("per_kelvin", of_type(Type::Number))
        .property("std_error", nullable_number())
        .property("reference_c", of_type(Type::Number))
        .property("value_at_reference", of_type(Type::Number))
        .required("per_kelvin").required("std_error").required("reference_c").required("value_at_reference")
        .build()
        .into()
);

/// The members of an F test: statistic, degrees of freedom, p-value, level.
fn f_test(o: ObjectBuilder) -> ObjectBuilder {
    o.property("f", of_type(Type::Number).minimum(Some(0.0)))
        .property("df1", of_type(Type::Integer).minimum(Some(1.0)))
        .property("df2", of_type(Type::Integer).minimum(Some(1.0)))
        .property(
            "p_value",
            of_type(Type::Number).minimum(Some(0.0)).maximum(Some(1.0)),
        )
        .property(
            "alpha",
            of_type(Type::Number)
                .exclusive_minimum(Some(0.0))
                .maximum(Some(1.0)),
        )
}

fn spread() -> ObjectBuilder {
    ObjectBuilder::new()
        .property("std", nullable_number().minimum(Some(0.0)))
        .property("dof", of_type(Type::Integer).minimum(Some(0.0)))
        .required("std")
        .required("dof")
}

marker_schema!(
    /// Warnings that never change a number, with the model-adequacy tests
    /// behind them (`pure_error` and `lack_of_fit` are absent from results
    /// computed before they existed).
    QualitySchema => ObjectBuilder::new()
        .property("condition_number", of_type(Type::Number).minimum(Some(1.0)))
        .property("pure_error", spread()
            .description(Some("The scatter of repeated samples within positions, pooled over runs, and per run."))
            .property("runs", array(spread()))
            .required("runs"))
        .property("lack_of_fit", f_test(ObjectBuilder::new())
            .description(Some("`status` `tested` with the F test (F, ν1, ν2, p-value, α), `pure_error_std` and `lack_of_fit_std`; or `not_tested` with `reason`: `no_residual_dof` (as many positions as terms), `no_replicates` (no position has two samples), `no_scatter` (repeated samples identical)."))
            .property("status", of_type(Type::String).enum_values(Some(["tested", "not_tested"])))
            .property("pure_error_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("lack_of_fit_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("reason", of_type(Type::String).enum_values(Some(["no_residual_dof", "no_replicates", "no_scatter"])))
            .required("status"))
        .property("warnings", array(f_test(ObjectBuilder::new())
            .description(Some("`ill_conditioned` (condition_number, terms); `lack_of_fit` (the F test, pure_error_std, lack_of_fit_std); `noisy_run` (run, `test`: `pure_error` when every run has repeated samples — then pure_error_std and others_pure_error_std — else `residual` with residual_std and others_residual_std, and the F test); `implausibly_consistent_batch` (batch, term, std, floor); `unmodelled_term` (term, the F test). Results computed before the F tests existed may hold `noisy_run` with residual_rms and median_residual_rms instead."))
            .property("kind", of_type(Type::String).enum_values(Some(["ill_conditioned", "lack_of_fit", "noisy_run", "implausibly_consistent_batch", "unmodelled_term"])))
            .property("condition_number", of_type(Type::Number))
            .property("terms", array(reference("Term")))
            .property("term", reference("Term"))
            .property("run", of_type(Type::Integer).minimum(Some(0.0)))
            .property("batch", of_type(Type::Integer).minimum(Some(0.0)))
            .property("pure_error_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("lack_of_fit_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("test", of_type(Type::String).enum_values(Some(["pure_error", "residual"])))
            .property("others_pure_error_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("residual_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("others_residual_std", of_type(Type::Number).minimum(Some(0.0)))
            .property("std", of_type(Type::Number).minimum(Some(0.0)))
            .property("floor", of_type(Type::Number).minimum(Some(0.0)))
            .property("residual_rms", of_type(Type::Number))
            .property("median_residual_rms", of_type(Type::Number))
            .required("kind")))
        .required("condition_number").required("warnings")
        .build()
        .into()
);

marker_schema!(
    /// The tumble stand of a submission.
    StandOutSchema => ObjectBuilder::new()
        .property("id", string_or_null())
        .property("angle_std_arcsec", of_type(Type::Number).minimum(Some(0.0)))
        .property("gravity_rel_std", of_type(Type::Number).minimum(Some(0.0)))
        .required("id").required("angle_std_arcsec").required("gravity_rel_std")
        .build()
        .into()
);

marker_schema!(
    /// One coefficient's stability over a sensor's history.
    TermStabilitySchema => ObjectBuilder::new()
        .property("mean", of_type(Type::Number))
        .property("std", nullable_number())
        .property("min", of_type(Type::Number))
        .property("max", of_type(Type::Number))
        .property("drift_per_year", nullable_number())
        .property("drift_std_error", nullable_number())
        .property("drift_t", nullable_number())
        .property("control", ObjectBuilder::new()
            .property("centre", of_type(Type::Number))
            .property("moving_range_mean", nullable_number())
            .property("lower", nullable_number())
            .property("upper", nullable_number())
            .property("out_of_control", array(of_type(Type::String)))
            .required("centre").required("moving_range_mean").required("lower")
            .required("upper").required("out_of_control"))
        .property("latest_change", nullable_number())
        .property("latest_change_expanded", nullable_number())
        .property("latest_change_significant", ObjectBuilder::new().schema_type(SchemaType::from_iter([Type::Boolean, Type::Null])))
        .required("mean").required("std").required("min").required("max")
        .required("drift_per_year").required("drift_std_error").required("drift_t")
        .required("control").required("latest_change").required("latest_change_expanded")
        .required("latest_change_significant")
        .build()
        .into()
);

marker_schema!(
    /// A calibration result.
    CalibrationResultSchema => ObjectBuilder::new()
        .property("method", ObjectBuilder::new()
            .description(Some("The versions of the method that computed this result: accelcal's and its core's \
                (absent from results stored before accelcal 0.2.0)."))
            .property("accelcal", of_type(Type::String))
            .property("core", of_type(Type::String))
            .required("accelcal").required("core"))
        .property("id", of_type(Type::String).format(Some(SchemaFormat::KnownFormat(KnownFormat::Uuid))))
        .property("sensor_id", reference("Identifier"))
        .property("station_id", string_or_null())
        .property("performed_at", date_time())
        .property("received_at", date_time())
        .property("unit", of_type(Type::String))
        .property("model", reference("Model"))
        .property("mount", reference("Mount"))
        .property("batches", of_type(Type::Integer).minimum(Some(1.0)))
        .property("notes", string_or_null())
        .property("positions", array(reference("PositionOut")))
        .property("condition_number", of_type(Type::Number).minimum(Some(1.0)))
        .property("runs", array(reference("RunResult")))
        .property("mean", reference("MeanEstimate"))
        .property("fused", reference("FusedEstimate"))
        .property("normalized", reference("Normalized"))
        .property("sensor_type", string_or_null().description(Some("The sensor type in force (named in the submission, or the sensor's).")))
        .property("stand", nullable(reference("StandOut")))
        .property("item_received_at", of_type(Type::String).format(Some(SchemaFormat::KnownFormat(KnownFormat::DateTime))).description(Some("When the laboratory received the item; absent when the submission did not say.")))
        .property("item_condition", of_type(Type::String).description(Some("The item's condition on receipt; absent when the submission did not say.")))
        .property("standards", array(reference("UsedStandard")).description(Some("The reference standards the submission named, each with the certificate it was in calibration by when the test was performed; absent when it named none.")))
        .property("temperatures_c", array(of_type(Type::Number)).description(Some("The runs' temperatures, when given.")))
        .property("supersedes", reference("Supersedes"))
        .property("uncertainty", reference("Uncertainty"))
        .property("decision", nullable(reference("Decision")))
        .property("as_found", nullable(reference("AsFound")))
        .property("as_found_note", of_type(Type::String).description(Some("Why `as_found` is null although there is a previous calibration (another unit, or no `ki`).")))
        .property("due_at", string_or_null().format(Some(SchemaFormat::KnownFormat(KnownFormat::DateTime))))
        .property("temperature", per_term("Sensitivity").description(Some("Present when the runs were made at two or more temperatures.")))
        .property("quality", reference("Quality"))
        .required("sensor_type").required("stand").required("uncertainty").required("decision")
        .required("as_found").required("due_at").required("quality")
        .required("sensor_id").required("station_id").required("performed_at")
        .required("received_at").required("unit").required("model").required("mount")
        .required("batches").required("notes").required("positions")
        .required("condition_number").required("runs").required("mean").required("fused")
        .required("normalized")
        .build()
        .into()
);

marker_schema!(
    /// A stored calibration: a result with its id.
    StoredCalibrationSchema => RefOr::T(Schema::AllOf(AllOfBuilder::new()
        .item(reference("CalibrationResult"))
        .item(ObjectBuilder::new()
            .property("id", of_type(Type::String).format(Some(SchemaFormat::KnownFormat(KnownFormat::Uuid))))
            .required("id"))
        .build()))
);

marker_schema!(
    /// A stored calibration's result document: single-axis, a triad's
    /// (`kind: triad`), a temperature model's (`kind: thermal`) or a
    /// triad's temperature model's (`kind: thermal_triad`).
    StoredResultSchema => RefOr::T(Schema::OneOf(utoipa::openapi::schema::OneOfBuilder::new()
        .item(reference("StoredCalibration"))
        .item(reference("StoredTriad"))
        .item(reference("StoredThermal"))
        .item(reference("StoredThermalTriad"))
        .build()))
);

marker_schema!(
    /// A corrected submission: a single-axis one to supersede a single-axis
    /// calibration, a triad's body to supersede a triad's.
    CorrectionSchema => RefOr::T(Schema::AnyOf(AnyOfBuilder::new()
        .description(Some("The submission that replaces the calibration, of its kind: \
            a single-axis submission, or a triad's body (as for `POST /v1/calibrations/triad`)."))
        .item(reference("Submission"))
        .item(reference("TriadBody"))
        .build()))
);

fn page(item: &str) -> RefOr<Schema> {
    ObjectBuilder::new()
        .property("items", array(reference(item)))
        .property(
            "next",
            string_or_null().description(Some(
                "Cursor for the next page (`after=`), or null on the last page.",
            )),
        )
        .required("items")
        .required("next")
        .build()
        .into()
}

marker_schema!(
    /// One page of sensors.
    SensorPageSchema => page("SensorSummary")
);

marker_schema!(
    /// One page of a sensor's calibrations.
    CalibrationPageSchema => page("CalibrationSummary")
);

marker_schema!(
    /// One page of the audit trail.
    AuditPageSchema => page("AuditEntry")
);
