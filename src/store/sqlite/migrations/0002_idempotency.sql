-- Idempotency keys (IETF draft "The Idempotency-Key HTTP Header Field").
-- A key is scoped to the principal (token) that sent it. While its first
-- request is processed, `locked_until` holds a lease (a crashed process's
-- lease simply expires); once that request stored a calibration,
-- `calibration_id` names it and every retry with the same body replays it.

CREATE TABLE idempotency_keys (
    principal       TEXT NOT NULL,
    key             TEXT NOT NULL,
    request_hash    BLOB NOT NULL,          -- SHA-256 of media type and body
    calibration_id  TEXT REFERENCES calibrations (id),
    locked_until    TEXT,
    created_at      TEXT NOT NULL,
    PRIMARY KEY (principal, key)
) STRICT;

CREATE INDEX idempotency_keys_by_age ON idempotency_keys (created_at);
