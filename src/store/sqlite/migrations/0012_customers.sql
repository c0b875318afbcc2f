-- Version 12 (issue 29): customers, and the items behind sensor ids, each
-- stored as its JSON definition (src/domain/customers.rs), as standards are.
CREATE TABLE customers (
    customer_id  TEXT PRIMARY KEY,
    definition   TEXT NOT NULL,
    updated_at   TEXT NOT NULL
) STRICT;

CREATE TABLE items (
    sensor_id    TEXT PRIMARY KEY,
    definition   TEXT NOT NULL,
    updated_at   TEXT NOT NULL
) STRICT;
