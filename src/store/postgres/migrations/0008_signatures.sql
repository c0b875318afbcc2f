-- Version 8 (issue 28): the signed acts on a calibration — approval,
-- rejection, withdrawal, supersession, confirmation — append-only beside
-- the calibration, which never changes. A calibration's state is the state
-- its last signature left it in (a confirmation keeps it), 'submitted'
-- before any (src/store/records.rs, state_sql!).
CREATE TABLE signatures (
    calibration_id  uuid NOT NULL REFERENCES calibrations (id),
    seq             integer NOT NULL CHECK (seq >= 1),
    action          text NOT NULL CHECK (action IN ('approve', 'reject', 'withdraw', 'supersede', 'confirm')),
    state           text NOT NULL CHECK (state IN ('submitted', 'approved', 'rejected', 'withdrawn', 'superseded')),
    meaning         text NOT NULL,
    token_id        text NOT NULL,
    role            text NOT NULL,
    holder          text,
    signed_at       timestamptz NOT NULL,
    comment         text,
    superseded_by   uuid,
    PRIMARY KEY (calibration_id, seq)
);

CREATE FUNCTION accelcal_signatures_kept() RETURNS trigger
    LANGUAGE plpgsql
    AS $$
BEGIN
    RAISE EXCEPTION 'signatures: a signature never changes and is never deleted'
        USING ERRCODE = 'integrity_constraint_violation';
END $$;

CREATE TRIGGER signatures_kept BEFORE UPDATE OR DELETE ON signatures
    FOR EACH ROW EXECUTE FUNCTION accelcal_signatures_kept();
