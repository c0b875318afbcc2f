-- Who holds an idempotency key's lease: a request releases a key only while
-- it still holds it, never after another request took the expired lease over.

ALTER TABLE idempotency_keys ADD COLUMN holder TEXT;
