-- Sensor types, and what the metrology adds to calibrations and sensors.
-- A calibration records the type in force, its verdict and its due date
-- (its result document holds the whole decision, immutable); a sensor
-- records its assigned type and its latest calibration's verdict and due
-- date, from which its status is computed.

CREATE TABLE sensor_types (
    type_id     TEXT PRIMARY KEY,
    definition  TEXT NOT NULL,      -- JSON: label, limits, decision_rule, coverage_factor, interval_days
    updated_at  TEXT NOT NULL
) STRICT;

ALTER TABLE calibrations ADD COLUMN sensor_type TEXT;
ALTER TABLE calibrations ADD COLUMN verdict TEXT CHECK (verdict IN ('pass', 'conditional', 'fail'));
ALTER TABLE calibrations ADD COLUMN due_at TEXT;

ALTER TABLE sensors ADD COLUMN sensor_type TEXT REFERENCES sensor_types (type_id);
ALTER TABLE sensors ADD COLUMN latest_verdict TEXT;
ALTER TABLE sensors ADD COLUMN latest_due_at TEXT;

CREATE INDEX calibrations_by_sensor_ascending
    ON calibrations (sensor_id, performed_at, id);

-- The expanded uncertainty of every fused coefficient (JSON map, as in the
-- result's `uncertainty`), for plots of a sensor's history.
ALTER TABLE calibrations ADD COLUMN expanded TEXT;

CREATE TRIGGER calibrations_finite_expanded
BEFORE INSERT ON calibrations
WHEN NEW.expanded IS NOT NULL
  AND EXISTS (SELECT 1 FROM json_each(NEW.expanded) WHERE type NOT IN ('real', 'integer'))
BEGIN
    SELECT RAISE(ABORT, 'calibrations: expanded uncertainties must be finite numbers');
END;
