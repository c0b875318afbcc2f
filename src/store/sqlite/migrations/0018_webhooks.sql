-- Version 18 (issue 47 item 3): webhook endpoints and their delivery log.
-- An endpoint's deliveries stand at `cursor` (the last event handled),
-- `failed` attempts at the next, due at `next_attempt_at`; the delivering
-- task holds `lease_holder` until `lease_until`. Times are canonical UTC
-- text, so they compare as they sort.
CREATE TABLE webhooks (
    id              TEXT PRIMARY KEY,
    url             TEXT NOT NULL,
    event_types     TEXT NOT NULL,
    sensors         TEXT NOT NULL,
    description     TEXT,
    secret          TEXT NOT NULL,
    previous_secret TEXT,
    previous_until  TEXT,
    created_at      TEXT NOT NULL,
    updated_at      TEXT NOT NULL,
    cursor          INTEGER NOT NULL CHECK (cursor >= 0),
    failed          INTEGER NOT NULL DEFAULT 0 CHECK (failed >= 0),
    next_attempt_at TEXT NOT NULL,
    lease_holder    TEXT,
    lease_until     TEXT
) STRICT;

CREATE TABLE webhook_deliveries (
    id          INTEGER PRIMARY KEY,
    webhook_id  TEXT NOT NULL REFERENCES webhooks (id) ON DELETE CASCADE,
    event_seq   INTEGER NOT NULL,
    message_id  TEXT NOT NULL,
    attempt     INTEGER NOT NULL,
    at          TEXT NOT NULL,
    outcome     TEXT NOT NULL CHECK (outcome IN ('delivered', 'failed', 'abandoned')),
    status      INTEGER,
    error       TEXT,
    duration_ms INTEGER NOT NULL
) STRICT;

CREATE INDEX webhook_deliveries_by_webhook ON webhook_deliveries (webhook_id, id);

-- The status each sensor was last announced in (a `sensor.status` audit
-- entry) for its due date: the clock's status changes are announced once,
-- whichever replica sees them first.
CREATE TABLE status_announcements (
    sensor_id TEXT PRIMARY KEY,
    status    TEXT NOT NULL,
    due_at    TEXT NOT NULL
) STRICT;
