-- Version 9 (issue 28): a token may name the person who holds it, and the
-- role `reviewer` exists. SQLite cannot change a CHECK constraint, so the
-- table is rebuilt with the same rows.
CREATE TABLE tokens_new (
    id           TEXT PRIMARY KEY,
    secret_hash  BLOB NOT NULL,
    role         TEXT NOT NULL CHECK (role IN ('reader', 'station', 'reviewer', 'admin')),
    station_id   TEXT,
    label        TEXT,
    created_at   TEXT NOT NULL,
    revoked_at   TEXT,
    holder       TEXT
) STRICT;
INSERT INTO tokens_new (id, secret_hash, role, station_id, label, created_at, revoked_at)
    SELECT id, secret_hash, role, station_id, label, created_at, revoked_at FROM tokens;
DROP TABLE tokens;
ALTER TABLE tokens_new RENAME TO tokens;
