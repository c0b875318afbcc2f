-- Version 10 (issue 28 item 6): the audit trail, one hash chain per
-- database (src/domain/audit.rs): every state-changing act appends an entry
-- in the transaction of the act, holding this table's EXCLUSIVE lock from
-- the append to the commit, so that replicas writing at once append one
-- after the other. Entries are never changed or deleted; `accelcal audit
-- verify` finds any that were behind the service's back. Acts before this
-- version have no entries.
CREATE TABLE audit (
    seq       bigint PRIMARY KEY CHECK (seq >= 1),
    at        timestamptz NOT NULL,
    token_id  text NOT NULL,
    role      text NOT NULL,
    holder    text,
    action    text NOT NULL,
    object    text NOT NULL,
    change    text NOT NULL,
    prev      text NOT NULL,
    hash      text NOT NULL
);

CREATE INDEX audit_object ON audit (object, seq);

CREATE FUNCTION accelcal_audit_kept() RETURNS trigger
    LANGUAGE plpgsql
    AS $$
BEGIN
    RAISE EXCEPTION 'audit: an entry never changes and is never deleted'
        USING ERRCODE = 'integrity_constraint_violation';
END $$;

CREATE TRIGGER audit_kept BEFORE UPDATE OR DELETE ON audit
    FOR EACH ROW EXECUTE FUNCTION accelcal_audit_kept();
