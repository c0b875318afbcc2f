-- Every change of a sensor's row is announced when its transaction commits,
-- so that every accelcal replica sharing this database drops what it cached
-- of that sensor (src/store/cache.rs, src/store/postgres/listen.rs).
CREATE FUNCTION accelcal_notify_sensor() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'DELETE' THEN
        PERFORM pg_notify('accelcal_sensors', OLD.sensor_id);
    ELSE
        PERFORM pg_notify('accelcal_sensors', NEW.sensor_id);
    END IF;
    RETURN NULL;
END
$$;

CREATE TRIGGER sensors_notify AFTER INSERT OR UPDATE OR DELETE ON sensors
    FOR EACH ROW EXECUTE FUNCTION accelcal_notify_sensor();
