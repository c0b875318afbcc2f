-- Version 7 (issue 29): reference standards, each stored as its JSON
-- definition (src/domain/standards.rs), as sensor types are.
CREATE TABLE standards (
    standard_id  text COLLATE "C" PRIMARY KEY,
    definition   json NOT NULL,
    updated_at   timestamptz NOT NULL
);
