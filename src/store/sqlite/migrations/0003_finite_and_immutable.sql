-- Nothing non-finite is ever stored, and a stored calibration never changes.
-- The service refuses both before they reach the database; these triggers
-- make the schema itself refuse them, whatever writes to it.

CREATE TRIGGER calibrations_finite_numbers
BEFORE INSERT ON calibrations
WHEN EXISTS (SELECT 1 FROM json_each(NEW.coefficients) WHERE type NOT IN ('real', 'integer'))
  OR EXISTS (SELECT 1 FROM json_each(NEW.std_errors) WHERE type NOT IN ('real', 'integer'))
BEGIN
    SELECT RAISE(ABORT, 'calibrations: fused coefficients and standard errors must be finite numbers');
END;

CREATE TRIGGER calibrations_immutable
BEFORE UPDATE ON calibrations
BEGIN
    SELECT RAISE(ABORT, 'calibrations: a stored calibration never changes');
END;
