-- Version 8: an `accelcal migrate` into this database that has not finished
-- (at most one row): the service refuses to start on the database until a
-- re-run of the same migrate finishes it (src/store/copy.rs).
CREATE TABLE import_in_progress (
    singleton INTEGER PRIMARY KEY CHECK (singleton = 1),
    description TEXT NOT NULL
) STRICT;
