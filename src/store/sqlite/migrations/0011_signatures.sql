-- Version 11 (issue 28): the signed acts on a calibration — approval,
-- rejection, withdrawal, supersession, confirmation — append-only beside
-- the calibration, which never changes. A calibration's state is the state
-- its last signature left it in (a confirmation keeps it), 'submitted'
-- before any (src/store/records.rs, state_sql!).
CREATE TABLE signatures (
    calibration_id  TEXT NOT NULL REFERENCES calibrations (id),
    seq             INTEGER NOT NULL CHECK (seq >= 1),
    action          TEXT NOT NULL CHECK (action IN ('approve', 'reject', 'withdraw', 'supersede', 'confirm')),
    state           TEXT NOT NULL CHECK (state IN ('submitted', 'approved', 'rejected', 'withdrawn', 'superseded')),
    meaning         TEXT NOT NULL,
    token_id        TEXT NOT NULL,
    role            TEXT NOT NULL,
    holder          TEXT,
    signed_at       TEXT NOT NULL,
    comment         TEXT,
    superseded_by   TEXT,
    PRIMARY KEY (calibration_id, seq)
) STRICT;

CREATE TRIGGER signatures_immutable BEFORE UPDATE ON signatures
BEGIN
    SELECT RAISE(ABORT, 'signatures: a signature never changes');
END;

CREATE TRIGGER signatures_kept BEFORE DELETE ON signatures
BEGIN
    SELECT RAISE(ABORT, 'signatures: a signature is never deleted');
END;
