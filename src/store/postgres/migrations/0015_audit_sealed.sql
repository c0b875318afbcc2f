-- Version 15 (issue 48 item 2): an act no longer holds the trail's lock to
-- its commit. Each act's entries are written, in the act's own transaction,
-- to `audit_pending` — an insert that waits for no one — and sealed into
-- the chain (`audit`) shortly after its commit by one sealer at a time,
-- which alone takes `audit`'s EXCLUSIVE lock (src/store/postgres/audit.rs).
-- `id` keeps an act's entries in the act's order; an act that began after
-- another committed has greater ids than the other's, so is sealed after it.
-- A pending entry is never changed; the sealer deletes it in the transaction
-- that chains it.
CREATE TABLE audit_pending (
    id        bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    at        timestamptz NOT NULL,
    token_id  text NOT NULL,
    role      text NOT NULL,
    holder    text,
    action    text NOT NULL,
    object    text NOT NULL,
    change    text NOT NULL
);

CREATE FUNCTION accelcal_audit_pending_kept() RETURNS trigger
    LANGUAGE plpgsql
    AS $$
BEGIN
    RAISE EXCEPTION 'audit: a pending entry never changes'
        USING ERRCODE = 'integrity_constraint_violation';
END $$;

CREATE TRIGGER audit_pending_kept BEFORE UPDATE ON audit_pending
    FOR EACH ROW EXECUTE FUNCTION accelcal_audit_pending_kept();
