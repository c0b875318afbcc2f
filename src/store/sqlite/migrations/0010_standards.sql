-- Version 10 (issue 29): reference standards, each stored as its JSON
-- definition (src/domain/standards.rs), as sensor types are.
CREATE TABLE standards (
    standard_id  TEXT PRIMARY KEY,
    definition   TEXT NOT NULL,
    updated_at   TEXT NOT NULL
) STRICT;
