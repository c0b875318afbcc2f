-- Version 14 (issue 29 item 3, reverse trace): a reference standard found
-- nonconforming, and the calibrations made with it in the affected window
-- (src/domain/nonconformity.rs). The signatures gain the act `hold` and the
-- state `under_review` it leaves: the table is rebuilt with the wider
-- checks (SQLite cannot alter a CHECK), rows and triggers as they were.
CREATE TABLE signatures_wider (
    calibration_id  TEXT NOT NULL REFERENCES calibrations (id),
    seq             INTEGER NOT NULL CHECK (seq >= 1),
    action          TEXT NOT NULL CHECK (action IN ('approve', 'reject', 'withdraw', 'supersede', 'confirm', 'hold')),
    state           TEXT NOT NULL CHECK (state IN ('submitted', 'approved', 'rejected', 'withdrawn', 'superseded', 'under_review')),
    meaning         TEXT NOT NULL,
    token_id        TEXT NOT NULL,
    role            TEXT NOT NULL,
    holder          TEXT,
    signed_at       TEXT NOT NULL,
    comment         TEXT,
    superseded_by   TEXT,
    PRIMARY KEY (calibration_id, seq)
) STRICT;

INSERT INTO signatures_wider SELECT calibration_id, seq, action, state, meaning, token_id,
    role, holder, signed_at, comment, superseded_by FROM signatures;
DROP TABLE signatures;
ALTER TABLE signatures_wider RENAME TO signatures;

CREATE TRIGGER signatures_immutable BEFORE UPDATE ON signatures
BEGIN
    SELECT RAISE(ABORT, 'signatures: a signature never changes');
END;

CREATE TRIGGER signatures_kept BEFORE DELETE ON signatures
BEGIN
    SELECT RAISE(ABORT, 'signatures: a signature is never deleted');
END;

CREATE TABLE nonconformities (
    id                  TEXT PRIMARY KEY,
    standard_id         TEXT NOT NULL REFERENCES standards (standard_id),
    found_at            TEXT NOT NULL,
    last_known_good_at  TEXT,
    window_from         TEXT NOT NULL,
    reason              TEXT NOT NULL,
    recorded_at         TEXT NOT NULL,
    token_id            TEXT NOT NULL,
    role                TEXT NOT NULL,
    holder              TEXT
) STRICT;

CREATE INDEX nonconformities_standard ON nonconformities (standard_id, found_at);

-- Each calibration of a nonconformity's window, with its state then.
CREATE TABLE nonconformity_calibrations (
    nonconformity_id  TEXT NOT NULL REFERENCES nonconformities (id),
    calibration_id    TEXT NOT NULL REFERENCES calibrations (id),
    state_found       TEXT NOT NULL,
    PRIMARY KEY (nonconformity_id, calibration_id)
) STRICT;
