-- Version 16 (issue 47 item 3): webhook endpoints and their delivery log.
-- An endpoint's deliveries stand at `cursor` (the last event handled),
-- `failed` attempts at the next, due at `next_attempt_at`; a replica
-- delivering to it holds `lease_holder` until `lease_until`, so one attempt
-- at a time is made per endpoint (and so per event) across replicas.
CREATE TABLE webhooks (
    id              text PRIMARY KEY,
    url             text NOT NULL,
    event_types     text NOT NULL,
    sensors         text NOT NULL,
    description     text,
    secret          text NOT NULL,
    previous_secret text,
    previous_until  timestamptz,
    created_at      timestamptz NOT NULL,
    updated_at      timestamptz NOT NULL,
    cursor          bigint NOT NULL CHECK (cursor >= 0),
    failed          bigint NOT NULL DEFAULT 0 CHECK (failed >= 0),
    next_attempt_at timestamptz NOT NULL,
    lease_holder    uuid,
    lease_until     timestamptz
);

CREATE TABLE webhook_deliveries (
    id          bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    webhook_id  text NOT NULL REFERENCES webhooks (id) ON DELETE CASCADE,
    event_seq   bigint NOT NULL,
    message_id  text NOT NULL,
    attempt     bigint NOT NULL,
    at          timestamptz NOT NULL,
    outcome     text NOT NULL CHECK (outcome IN ('delivered', 'failed', 'abandoned')),
    status      bigint,
    error       text,
    duration_ms bigint NOT NULL
);

CREATE INDEX webhook_deliveries_by_webhook ON webhook_deliveries (webhook_id, id);

-- The status each sensor was last announced in (a `sensor.status` audit
-- entry) for its due date: the clock's status changes are announced once,
-- whichever replica sees them first (the upsert's row lock decides).
CREATE TABLE status_announcements (
    sensor_id text PRIMARY KEY,
    status    text NOT NULL,
    due_at    timestamptz NOT NULL
);
