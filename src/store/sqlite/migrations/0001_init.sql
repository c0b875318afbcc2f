-- accelcal schema, version 1.
-- Timestamps are canonical UTC RFC 3339 text with six fractional digits,
-- so text order is time order. JSON columns hold compact JSON text.

CREATE TABLE calibrations (
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
    result        TEXT NOT NULL,         -- the whole result document
    submission    BLOB NOT NULL,         -- the submitted body, byte for byte
    content_type  TEXT NOT NULL,
    submitted_by  TEXT NOT NULL          -- principal (token id)
) STRICT;

CREATE INDEX calibrations_by_sensor_time
    ON calibrations (sensor_id, performed_at DESC, id DESC);

CREATE TABLE sensors (
    sensor_id              TEXT PRIMARY KEY,
    calibration_count      INTEGER NOT NULL,
    first_performed_at     TEXT NOT NULL,
    latest_performed_at    TEXT NOT NULL,
    latest_calibration_id  TEXT NOT NULL REFERENCES calibrations (id)
) STRICT;

CREATE TABLE tokens (
    id           TEXT PRIMARY KEY,
    secret_hash  BLOB NOT NULL,
    role         TEXT NOT NULL CHECK (role IN ('reader', 'station', 'admin')),
    station_id   TEXT,
    label        TEXT,
    created_at   TEXT NOT NULL,
    revoked_at   TEXT
) STRICT;
