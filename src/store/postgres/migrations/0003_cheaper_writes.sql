-- Version 3: the same guarantees for less of the server's CPU per stored
-- calibration (measured under load: the finiteness trigger and pglz were a
-- fifth of PostgreSQL's time per insert; BENCHMARKS.md).
--
-- * Nothing non-finite is stored: checked by CHECK constraints evaluated in
--   C (jsonpath) instead of a PL/pgSQL trigger calling an SQL function. The
--   constraints' names are their messages. NOT VALID: rows already stored
--   passed the trigger, so the table is not scanned again under its lock;
--   every new row is checked.
-- * Result documents and submissions are compressed with lz4 where the
--   server was built with it (Debian's and the official images are); pglz
--   otherwise, as before. Rows already stored keep their compression.

DROP TRIGGER calibrations_finite_numbers ON calibrations;
DROP FUNCTION accelcal_calibrations_finite();
DROP FUNCTION accelcal_all_numbers(json);

ALTER TABLE calibrations
    ADD CONSTRAINT "fused coefficients and standard errors must be finite numbers" CHECK (
        json_typeof(coefficients) = 'object' AND json_typeof(std_errors) = 'object'
        AND NOT jsonb_path_exists(coefficients::jsonb, 'strict $.* ? (@.type() != "number")')
        AND NOT jsonb_path_exists(std_errors::jsonb, 'strict $.* ? (@.type() != "number")')
    ) NOT VALID,
    ADD CONSTRAINT "expanded uncertainties must be finite numbers" CHECK (
        expanded IS NULL OR (
            json_typeof(expanded) = 'object'
            AND NOT jsonb_path_exists(expanded::jsonb, 'strict $.* ? (@.type() != "number")')
        )
    ) NOT VALID;

DO $$
BEGIN
    IF EXISTS (SELECT 1 FROM pg_settings
               WHERE name = 'default_toast_compression' AND 'lz4' = ANY (enumvals)) THEN
        ALTER TABLE calibrations
            ALTER COLUMN result SET COMPRESSION lz4,
            ALTER COLUMN submission SET COMPRESSION lz4;
    END IF;
END
$$;
