-- Version 18 (issue 45): a triad's temperature model is kept in the same
-- `thermal` column as a single axis's (JSON: the set points and the
-- polynomials of every element of `b` and `S`; see `TriadThermalModel` in
-- src/domain/thermal/triad.rs), its calibration's `triad` elements being
-- the model at its reference temperature. The check now admits either
-- shape. NOT VALID: every row written before satisfies the stricter rule it
-- replaces, so they need no scan; every row written from now on is checked.
ALTER TABLE calibrations DROP CONSTRAINT "a temperature model must be an object",
    ADD CONSTRAINT "a temperature model must be an object" CHECK (
        thermal IS NULL OR (
            json_typeof(thermal) IS NOT DISTINCT FROM 'object'
            AND json_typeof(thermal -> 'set_points') IS NOT DISTINCT FROM 'array'
            AND (
                json_typeof(thermal -> 'coefficients') IS NOT DISTINCT FROM 'object'
                OR (
                    json_typeof(thermal -> 'b') IS NOT DISTINCT FROM 'array'
                    AND json_typeof(thermal -> 'S') IS NOT DISTINCT FROM 'array'
                )
            )
        )
    ) NOT VALID;
