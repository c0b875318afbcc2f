-- The calibrations table rebuilt with its two large columns last, and one
-- index per sensor and time instead of two.
--
-- A row's columns are stored in order, and a row larger than a page
-- continues on overflow pages: with `result` (a few kilobytes) and
-- `submission` before the columns that migration 4 appended, every read of
-- a summary (history, the sensor's latest, the previous calibration)
-- followed the row's overflow chain to reach its verdict and due date.
-- The descending index duplicated the ascending one (SQLite walks an index
-- either way) and cost every insert its own index page.
--
-- Counted by benches/sqlite_pages.py (64 sensors of 40 calibrations): a
-- 20-row history read 43.1 pages before and 22.0 after; a submission sent
-- alone wrote 21.9 pages (WAL and checkpoint) before and 18.2 after.
--
-- Run with foreign keys off (see migrations.rs), as SQLite's procedure for
-- rebuilding a table requires; the references are checked before commit.

CREATE TABLE calibrations_rebuilt (
    id            TEXT PRIMARY KEY,      -- UUIDv7, time-ordered
    sensor_id     TEXT NOT NULL,
    station_id    TEXT,
    performed_at  TEXT NOT NULL,
    received_at   TEXT NOT NULL,
    unit          TEXT NOT NULL,
    model         TEXT NOT NULL,         -- JSON array of term names
    runs          INTEGER NOT NULL,
    coefficients  TEXT NOT NULL,         -- fused, JSON object
    std_errors    TEXT NOT NULL,         -- fused, JSON object
    expanded      TEXT,                  -- expanded uncertainties, JSON object
    content_type  TEXT NOT NULL,
    submitted_by  TEXT NOT NULL,         -- principal (token id)
    sensor_type   TEXT,
    verdict       TEXT CHECK (verdict IN ('pass', 'conditional', 'fail')),
    due_at        TEXT,
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

CREATE TRIGGER calibrations_immutable
BEFORE UPDATE ON calibrations
BEGIN
    SELECT RAISE(ABORT, 'calibrations: a stored calibration never changes');
END;
