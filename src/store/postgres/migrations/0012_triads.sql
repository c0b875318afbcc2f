-- Version 12 (issue 30): triad calibrations. A triad's elements (b, S,
-- T and their standard errors, JSON; see `TriadElements` in
-- src/store/records.rs) sit beside the single-axis columns, which keep the
-- per-axis model and empty coefficient maps. NULL for a single-axis
-- calibration. Every element inside b, S, T and their standard errors must
-- be a number (serde_json writes a NaN as null); b, S and T must be there.
ALTER TABLE calibrations ADD COLUMN triad json,
    ADD CONSTRAINT "a triad's elements must be finite numbers" CHECK (
        triad IS NULL OR (
            json_typeof(triad) IS NOT DISTINCT FROM 'object'
            AND json_typeof(triad -> 'b') IS NOT DISTINCT FROM 'array'
            AND json_typeof(triad -> 'S') IS NOT DISTINCT FROM 'array'
            AND json_typeof(triad -> 'T') IS NOT DISTINCT FROM 'array'
            AND NOT jsonb_path_exists(triad::jsonb,
                'strict $.* ? (@.type() == "array")[*] ? (@.type() != "number" && @.type() != "array")')
            AND NOT jsonb_path_exists(triad::jsonb,
                'strict $.* ? (@.type() == "array")[*] ? (@.type() == "array")[*] ? (@.type() != "number")')
        )
    );
