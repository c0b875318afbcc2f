-- Version 6 (issue 28): a token may name the person who holds it, and the
-- role `reviewer` exists.
ALTER TABLE tokens DROP CONSTRAINT tokens_role_check;
ALTER TABLE tokens ADD CONSTRAINT tokens_role_check
    CHECK (role IN ('reader', 'station', 'reviewer', 'admin'));
ALTER TABLE tokens ADD COLUMN holder text;
