-- Version 14 (issue 48 item 3): the signatures that name a replacement,
-- indexed. Judging who may review a calibration follows its supersessions
-- back (`records::earlier_submitters_sql`), from the calibration that
-- replaced to the one replaced: without this index each step read every
-- signature of the database, a cost that grew with all of history.
CREATE INDEX signatures_by_replacement ON signatures (superseded_by)
    WHERE superseded_by IS NOT NULL;
