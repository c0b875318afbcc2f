-- Version 19 (issue 45): a single axis's temperature model, stored with
-- its calibration (JSON: the set points and every coefficient's
-- polynomial; see `ThermalModel` in src/domain/thermal.rs). NULL for any
-- other calibration. Its `coefficients` and `std_errors` are the model at
-- its reference temperature. Added last: a NULL costs nothing to read, and
-- only a temperature model's row reads past its large columns.
ALTER TABLE calibrations ADD COLUMN thermal TEXT
    CHECK (thermal IS NULL OR (json_valid(thermal) AND json_type(thermal) = 'object'
        AND json_type(thermal, '$.coefficients') = 'object'
        AND json_type(thermal, '$.set_points') = 'array'));
