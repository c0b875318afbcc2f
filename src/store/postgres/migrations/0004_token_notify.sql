-- Version 4: a token's change (its revocation) is announced when its
-- transaction commits, so that every accelcal replica sharing this
-- database drops what it cached of that token (src/store/cache/tokens.rs,
-- src/store/postgres/listen.rs). A new token needs no announcement: only
-- tokens that exist are cached.
CREATE FUNCTION accelcal_notify_token() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'DELETE' THEN
        PERFORM pg_notify('accelcal_tokens', OLD.id::text);
    ELSE
        PERFORM pg_notify('accelcal_tokens', NEW.id::text);
    END IF;
    RETURN NULL;
END
$$;

CREATE TRIGGER tokens_notify AFTER UPDATE OR DELETE ON tokens
    FOR EACH ROW EXECUTE FUNCTION accelcal_notify_token();
