-- Version 16 (issue 42 item 3): issued certificates, frozen. A calibration's
-- certificate is issued when it is approved — the printable HTML and, when
-- the records allow one, the Digital Calibration Certificate, as they were
-- rendered then — and changes only by an amendment: a new revision of the
-- same certificate number, with its reason. Revisions never change and are
-- never deleted; the audit trail holds each one's SHA-256.
CREATE TABLE certificates (
    calibration_id  TEXT NOT NULL REFERENCES calibrations (id),
    revision        INTEGER NOT NULL CHECK (revision >= 1),
    issued_at       TEXT NOT NULL,
    token_id        TEXT NOT NULL,
    role            TEXT NOT NULL,
    holder          TEXT,
    reason          TEXT,
    html            TEXT NOT NULL,
    dcc             TEXT,
    dcc_missing     TEXT,
    html_sha256     TEXT NOT NULL,
    dcc_sha256      TEXT,
    PRIMARY KEY (calibration_id, revision),
    CHECK ((dcc IS NULL) = (dcc_sha256 IS NULL)),
    CHECK ((dcc IS NULL) = (dcc_missing IS NOT NULL)),
    CHECK ((revision = 1) = (reason IS NULL))
) STRICT;

CREATE TRIGGER certificates_immutable BEFORE UPDATE ON certificates
BEGIN
    SELECT RAISE(ABORT, 'certificates: an issued certificate never changes');
END;

CREATE TRIGGER certificates_kept BEFORE DELETE ON certificates
BEGIN
    SELECT RAISE(ABORT, 'certificates: an issued certificate is never deleted');
END;
