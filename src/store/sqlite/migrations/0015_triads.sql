-- Version 15 (issue 30): triad calibrations. A triad's elements (b, S,
-- T and their standard errors, JSON; see `TriadElements` in
-- src/store/records.rs) sit beside the single-axis columns, which keep the
-- per-axis model and empty coefficient maps. NULL for a single-axis
-- calibration. Every element inside b, S, T and their standard errors must
-- be a number (serde_json writes a NaN as null); b, S and T must be there.
ALTER TABLE calibrations ADD COLUMN triad TEXT;

CREATE TRIGGER calibrations_finite_triad
BEFORE INSERT ON calibrations
WHEN NEW.triad IS NOT NULL AND (
    json_type(NEW.triad) IS NOT 'object'
    OR json_type(NEW.triad, '$.b') IS NOT 'array'
    OR json_type(NEW.triad, '$.S') IS NOT 'array'
    OR json_type(NEW.triad, '$.T') IS NOT 'array'
    OR EXISTS (SELECT 1 FROM json_tree(NEW.triad) t
        WHERE (t.path <> '$' AND t.type NOT IN ('real', 'integer', 'array'))
           OR (t.path = '$' AND t.key IN ('b', 'S', 'T') AND t.type <> 'array')))
BEGIN
    SELECT RAISE(ABORT, 'calibrations: a triad''s elements must be finite numbers');
END;
