-- Version 17 (issue 45): a single axis's temperature model, stored with
-- its calibration (JSON: the set points and every coefficient's
-- polynomial; see `ThermalModel` in src/domain/thermal.rs). NULL for any
-- other calibration. Its `coefficients` and `std_errors` are the model at
-- its reference temperature. Every number is checked finite before it is
-- written (serde_json would write a NaN as null, which does not read back
-- as a number).
ALTER TABLE calibrations ADD COLUMN thermal json,
    ADD CONSTRAINT "a temperature model must be an object" CHECK (
        thermal IS NULL OR (
            json_typeof(thermal) IS NOT DISTINCT FROM 'object'
            AND json_typeof(thermal -> 'coefficients') IS NOT DISTINCT FROM 'object'
            AND json_typeof(thermal -> 'set_points') IS NOT DISTINCT FROM 'array'
        )
    );
