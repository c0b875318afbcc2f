-- Version 15 (issue 30): triad calibrations. A triad's elements (b, S,
-- T and their standard errors, JSON; see `TriadElements` in
-- src/store/records.rs) sit beside the single-axis columns, which keep the
-- per-axis model and empty coefficient maps; NULL for a single-axis
-- calibration. The table is rebuilt as migration 7 did, so that the new
-- column comes before the two large ones: a summary's read of it never
-- follows a row's overflow chain. Every element inside b, S, T and their
-- standard errors must be a number (serde_json writes a NaN as null), and
-- b, S and T must be there.
--
-- Run with foreign keys off (see migrations.rs); the references are
-- checked before commit.

CREATE TABLE calibrations_rebuilt (
    id            TEXT PRIMARY KEY,      -- UUIDv7, time-ordered
    sensor_id     TEXT NOT NULL,
    station_id    TEXT,
    performed_at  TEXT NOT NULL,
    received_at   TEXT NOT NULL,
    unit          TEXT NOT NULL,
    model         TEXT NOT NULL,         -- JSON array of term names
    runs          INTEGER NOT NULL,
    coefficients  TEXT NOT NULL,         -- fused, JSON object (empty for a triad)
    std_errors    TEXT NOT NULL,         -- fused, JSON object (empty for a triad)
    expanded      TEXT,                  -- expanded uncertainties, JSON object
    content_type  TEXT NOT NULL,
    submitted_by  TEXT NOT NULL,         -- principal (token id)
    sensor_type   TEXT,
    verdict       TEXT CHECK (verdict IN ('pass', 'conditional', 'fail')),
    due_at        TEXT,
    triad         TEXT,                  -- a triad's elements, JSON object
    result        TEXT NOT NULL,         -- the whole result document
    submission    BLOB NOT NULL          -- the submitted body, byte for byte
) STRICT;

INSERT INTO calibrations_rebuilt (id, sensor_id, station_id, performed_at, received_at, unit,
    model, runs, coefficients, std_errors, expanded, content_type, submitted_by, sensor_type,
    verdict, due_at, result, submission)
SELECT id, sensor_id, station_id, performed_at, received_at, unit,
    model, runs, coefficients, std_errors, expanded, content_type, submitted_by, sensor_type,
    verdict, due_at, result, submission
FROM calibrations ORDER BY rowid;

-- Drops the old table's indexes and triggers with it.
DROP TABLE calibrations;
ALTER TABLE calibrations_rebuilt RENAME TO calibrations;

CREATE INDEX calibrations_by_sensor_time ON calibrations (sensor_id, performed_at, id);

CREATE TRIGGER calibrations_finite_numbers
BEFORE INSERT ON calibrations
WHEN EXISTS (SELECT 1 FROM json_each(NEW.coefficients) WHERE type NOT IN ('real', 'integer'))
  OR EXISTS (SELECT 1 FROM json_each(NEW.std_errors) WHERE type NOT IN ('real', 'integer'))
BEGIN
    SELECT RAISE(ABORT, 'calibrations: fused coefficients and standard errors must be finite numbers');
END;

CREATE TRIGGER calibrations_finite_expanded
BEFORE INSERT ON calibrations
WHEN NEW.expanded IS NOT NULL
  AND EXISTS (SELECT 1 FROM json_each(NEW.expanded) WHERE type NOT IN ('real', 'integer'))
BEGIN
    SELECT RAISE(ABORT, 'calibrations: expanded uncertainties must be finite numbers');
END;

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

CREATE TRIGGER calibrations_immutable
BEFORE UPDATE ON calibrations
BEGIN
    SELECT RAISE(ABORT, 'calibrations: a stored calibration never changes');
END;
