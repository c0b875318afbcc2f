-- Version 9 (issue 29): customers, and the items behind sensor ids, each
-- stored as its JSON definition (src/domain/customers.rs), as standards are.
CREATE TABLE customers (
    customer_id  text COLLATE "C" PRIMARY KEY,
    definition   json NOT NULL,
    updated_at   timestamptz NOT NULL
);

CREATE TABLE items (
    sensor_id    text COLLATE "C" PRIMARY KEY,
    definition   json NOT NULL,
    updated_at   timestamptz NOT NULL
);
