-- accelcal on PostgreSQL, version 1: the same records as the SQLite engine
-- (src/store/sqlite/migrations), in PostgreSQL's own types.
--
-- * Identifiers are COLLATE "C": byte order, as SQLite's, so lists page in
--   the same order on both engines.
-- * Coefficient maps are `json` (not `jsonb`): their text, and so the order
--   of their keys (model order), is kept as written.
-- * Result documents are text and submissions bytea, byte for byte.

CREATE TABLE sensor_types (
    type_id     text COLLATE "C" PRIMARY KEY,
    definition  json NOT NULL,
    updated_at  timestamptz NOT NULL
);

CREATE TABLE calibrations (
    id            uuid PRIMARY KEY,
    sensor_id     text COLLATE "C" NOT NULL,
    station_id    text,
    performed_at  timestamptz NOT NULL,
    received_at   timestamptz NOT NULL,
    unit          text NOT NULL,
    model         json NOT NULL,
    runs          integer NOT NULL CHECK (runs >= 1),
    coefficients  json NOT NULL,
    std_errors    json NOT NULL,
    expanded      json,
    result        text NOT NULL,
    submission    bytea NOT NULL,
    content_type  text NOT NULL,
    submitted_by  text NOT NULL,
    sensor_type   text COLLATE "C",
    verdict       text CHECK (verdict IN ('pass', 'conditional', 'fail')),
    due_at        timestamptz
);

CREATE INDEX calibrations_by_sensor_time ON calibrations (sensor_id, performed_at, id);

-- Nothing non-finite is stored (JSON has no NaN: serde writes null), and a
-- stored calibration never changes.
CREATE FUNCTION accelcal_all_numbers(j json) RETURNS boolean
    LANGUAGE sql IMMUTABLE
    AS $$ SELECT coalesce(bool_and(json_typeof(value) = 'number'), true) FROM json_each(j) $$;

CREATE FUNCTION accelcal_calibrations_finite() RETURNS trigger
    LANGUAGE plpgsql
    AS $$
BEGIN
    IF NOT accelcal_all_numbers(NEW.coefficients) OR NOT accelcal_all_numbers(NEW.std_errors) THEN
        RAISE EXCEPTION 'calibrations: fused coefficients and standard errors must be finite numbers'
            USING ERRCODE = 'check_violation';
    END IF;
    IF NEW.expanded IS NOT NULL AND NOT accelcal_all_numbers(NEW.expanded) THEN
        RAISE EXCEPTION 'calibrations: expanded uncertainties must be finite numbers'
            USING ERRCODE = 'check_violation';
    END IF;
    RETURN NEW;
END $$;

CREATE TRIGGER calibrations_finite_numbers BEFORE INSERT ON calibrations
    FOR EACH ROW EXECUTE FUNCTION accelcal_calibrations_finite();

CREATE FUNCTION accelcal_calibrations_immutable() RETURNS trigger
    LANGUAGE plpgsql
    AS $$
BEGIN
    RAISE EXCEPTION 'calibrations: a stored calibration never changes'
        USING ERRCODE = 'integrity_constraint_violation';
END $$;

CREATE TRIGGER calibrations_immutable BEFORE UPDATE ON calibrations
    FOR EACH ROW EXECUTE FUNCTION accelcal_calibrations_immutable();

CREATE TABLE sensors (
    sensor_id              text COLLATE "C" PRIMARY KEY,
    calibration_count      bigint NOT NULL,
    first_performed_at     timestamptz NOT NULL,
    latest_performed_at    timestamptz NOT NULL,
    latest_calibration_id  uuid NOT NULL REFERENCES calibrations (id),
    sensor_type            text COLLATE "C" REFERENCES sensor_types (type_id),
    latest_verdict         text,
    latest_due_at          timestamptz
);

CREATE TABLE tokens (
    id           uuid PRIMARY KEY,
    secret_hash  bytea NOT NULL,
    role         text NOT NULL CHECK (role IN ('reader', 'station', 'admin')),
    station_id   text,
    label        text,
    created_at   timestamptz NOT NULL,
    revoked_at   timestamptz
);

-- Idempotency keys: a lease (`locked_until`, `holder`) while the first
-- request runs, then the calibration it stored.
CREATE TABLE idempotency_keys (
    principal       text NOT NULL,
    key             text NOT NULL,
    request_hash    bytea NOT NULL,
    calibration_id  uuid REFERENCES calibrations (id),
    locked_until    timestamptz,
    holder          uuid,
    created_at      timestamptz NOT NULL,
    PRIMARY KEY (principal, key)
);

CREATE INDEX idempotency_keys_by_age ON idempotency_keys (created_at);

CREATE TABLE sessions (
    id_hash          bytea PRIMARY KEY,
    principal        text NOT NULL,
    credential_hash  bytea NOT NULL,
    csrf             text NOT NULL,
    created_at       timestamptz NOT NULL,
    expires_at       timestamptz NOT NULL
);

CREATE INDEX sessions_by_expiry ON sessions (expires_at);
