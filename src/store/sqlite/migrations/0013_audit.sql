-- Version 13 (issue 28 item 6): the audit trail, one hash chain per
-- database (src/domain/audit.rs): every state-changing act appends an entry
-- in the transaction of the act. Entries are never changed or deleted;
-- `accelcal audit verify` finds any that were behind the service's back.
-- Acts before this version have no entries.
CREATE TABLE audit (
    seq       INTEGER PRIMARY KEY CHECK (seq >= 1),
    at        TEXT NOT NULL,
    token_id  TEXT NOT NULL,
    role      TEXT NOT NULL,
    holder    TEXT,
    action    TEXT NOT NULL,
    object    TEXT NOT NULL,
    change    TEXT NOT NULL,
    prev      TEXT NOT NULL,
    hash      TEXT NOT NULL
) STRICT;

CREATE INDEX audit_object ON audit (object, seq);

CREATE TRIGGER audit_immutable BEFORE UPDATE ON audit
BEGIN
    SELECT RAISE(ABORT, 'audit: an entry never changes');
END;

CREATE TRIGGER audit_kept BEFORE DELETE ON audit
BEGIN
    SELECT RAISE(ABORT, 'audit: an entry is never deleted');
END;
