-- Version 13 (issue 42 item 3): issued certificates, frozen. A calibration's
-- certificate is issued when it is approved — the printable HTML and, when
-- the records allow one, the Digital Calibration Certificate, as they were
-- rendered then — and changes only by an amendment: a new revision of the
-- same certificate number, with its reason. Revisions never change and are
-- never deleted; the audit trail holds each one's SHA-256.
CREATE TABLE certificates (
    calibration_id  uuid NOT NULL REFERENCES calibrations (id),
    revision        integer NOT NULL CHECK (revision >= 1),
    issued_at       timestamptz NOT NULL,
    token_id        text NOT NULL,
    role            text NOT NULL,
    holder          text,
    reason          text,
    html            text NOT NULL,
    dcc             text,
    dcc_missing     text,
    html_sha256     text NOT NULL,
    dcc_sha256      text,
    PRIMARY KEY (calibration_id, revision),
    CHECK ((dcc IS NULL) = (dcc_sha256 IS NULL)),
    CHECK ((dcc IS NULL) = (dcc_missing IS NOT NULL)),
    CHECK ((revision = 1) = (reason IS NULL))
);

CREATE FUNCTION accelcal_certificates_kept() RETURNS trigger
    LANGUAGE plpgsql
    AS $$
BEGIN
    RAISE EXCEPTION 'certificates: an issued certificate never changes and is never deleted'
        USING ERRCODE = 'integrity_constraint_violation';
END $$;

CREATE TRIGGER certificates_kept BEFORE UPDATE OR DELETE ON certificates
    FOR EACH ROW EXECUTE FUNCTION accelcal_certificates_kept();
