-- Version 11 (issue 29 item 3, reverse trace): a reference standard found
-- nonconforming, and the calibrations made with it in the affected window
-- (src/domain/nonconformity.rs). The signatures gain the act `hold` and the
-- state `under_review` it leaves.
ALTER TABLE signatures
    DROP CONSTRAINT signatures_action_check,
    ADD CONSTRAINT signatures_action_check
        CHECK (action IN ('approve', 'reject', 'withdraw', 'supersede', 'confirm', 'hold')),
    DROP CONSTRAINT signatures_state_check,
    ADD CONSTRAINT signatures_state_check
        CHECK (state IN ('submitted', 'approved', 'rejected', 'withdrawn', 'superseded', 'under_review'));

CREATE TABLE nonconformities (
    id                  uuid PRIMARY KEY,
    standard_id         text NOT NULL REFERENCES standards (standard_id),
    found_at            timestamptz NOT NULL,
    last_known_good_at  timestamptz,
    window_from         timestamptz NOT NULL,
    reason              text NOT NULL,
    recorded_at         timestamptz NOT NULL,
    token_id            text NOT NULL,
    role                text NOT NULL,
    holder              text
);

CREATE INDEX nonconformities_standard ON nonconformities (standard_id, found_at);

-- Each calibration of a nonconformity's window, with its state then.
CREATE TABLE nonconformity_calibrations (
    nonconformity_id  uuid NOT NULL REFERENCES nonconformities (id),
    calibration_id    uuid NOT NULL REFERENCES calibrations (id),
    state_found       text NOT NULL,
    PRIMARY KEY (nonconformity_id, calibration_id)
);
