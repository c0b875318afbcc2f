-- Sessions of the web pages. Only the SHA-256 of the session cookie is
-- stored; a session names the token it was opened with (or `env-admin`) and
-- the hash of that token's secret, so revoking the token (or changing the
-- configured admin token) ends it at once.

CREATE TABLE sessions (
    id_hash         BLOB PRIMARY KEY,
    principal       TEXT NOT NULL,
    credential_hash BLOB NOT NULL,
    csrf            TEXT NOT NULL,
    created_at      TEXT NOT NULL,
    expires_at      TEXT NOT NULL
) STRICT;

CREATE INDEX sessions_by_expiry ON sessions (expires_at);
