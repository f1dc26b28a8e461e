"""The lab store's schema in PostgreSQL (schema ``bench``) and its migrations (docs/store.md, section Lab store)."""

from __future__ import annotations

import logging
from typing import Any

from bench.store.lab_connection import LabStoreError, redacted
from bench.store.lab_copy import TYPED_COLUMNS, typed_columns_ddl
from bench.store.lab_summary import POSE_TABLES_BACKFILL, POSE_TABLES_DDL

__all__ = ["LAB_SCHEMA_VERSION", "ensure_schema"]

_log = logging.getLogger(__name__)

#: The lab schema version this bench writes (kept in ``bench.schema_version``).
LAB_SCHEMA_VERSION = 5

_DDL = """
CREATE SCHEMA IF NOT EXISTS bench;
CREATE TABLE IF NOT EXISTS bench.schema_version (version integer NOT NULL);
CREATE TABLE IF NOT EXISTS bench.runs (
    uuid uuid PRIMARY KEY,
    bench text NOT NULL,
    local_id integer NOT NULL,
    campaign text,
    protocol_name text NOT NULL,
    protocol_version text NOT NULL,
    robot text NOT NULL,
    config_json text NOT NULL,
    settings_json text NOT NULL,
    calibration_ids_json text NOT NULL,
    calibration_uuids_json text NOT NULL,
    software_version text NOT NULL,
    git_sha text NOT NULL,
    status text NOT NULL,
    reason text,
    started_utc text NOT NULL,
    ended_utc text,
    synced_utc timestamptz NOT NULL DEFAULT now()
);
-- v5: the local store's checksum of the run as stored (status and reason as stored, checked by
-- bench.store.lab_records), and the status and reason the bench read it as when synced (what the lab shows)
ALTER TABLE bench.runs ADD COLUMN IF NOT EXISTS checksum text;  -- NULL: synced before v5
ALTER TABLE bench.runs ADD COLUMN IF NOT EXISTS read_status text;
ALTER TABLE bench.runs ADD COLUMN IF NOT EXISTS read_reason text;
CREATE INDEX IF NOT EXISTS runs_bench_robot_started ON bench.runs (bench, robot, started_utc);
CREATE TABLE IF NOT EXISTS bench.calibrations (
    uuid uuid PRIMARY KEY,
    bench text NOT NULL,
    local_id integer NOT NULL,
    name text NOT NULL,
    version integer NOT NULL,
    created_utc text NOT NULL,
    params_json text NOT NULL,
    source_run_uuid uuid,
    notes text NOT NULL
);
-- v5: the source run's id in its bench's file (the local checksum covers it) and the local store's checksum
ALTER TABLE bench.calibrations ADD COLUMN IF NOT EXISTS source_run_local_id integer;
ALTER TABLE bench.calibrations ADD COLUMN IF NOT EXISTS checksum text;  -- NULL: synced before v5
CREATE TABLE IF NOT EXISTS bench.samples (
    run_uuid uuid NOT NULL,  -- a bench.runs uuid: checked per statement (_RUN_REFERENCES_DDL), not per row
    step_index integer NOT NULL,
    kind text NOT NULL,
    pose text,
    cycle integer,
    t_s double precision NOT NULL,
    wall_utc text NOT NULL,
    values_json text NOT NULL,
    raw_json text,
    checksum text,  -- the local store's SHA-256 of the row (bench.store.sample_checksum); NULL: synced before v4
    PRIMARY KEY (run_uuid, step_index)
);
ALTER TABLE bench.samples ADD COLUMN IF NOT EXISTS checksum text;
"""

#: Version 4: every sample's run exists, checked once per statement over the rows it stored (one anti-join), not
#: per row: PostgreSQL's foreign key runs one keyed lookup into bench.runs per sample, 4.3 us of the server's
#: 13.3 us a sample in schema 3 (measured: docs/lab-store.md). A run that samples reference cannot be deleted or
#: renumbered (the foreign key's other half, per run row: runs are few).
_RUN_REFERENCES_DDL = """
ALTER TABLE bench.samples DROP CONSTRAINT IF EXISTS samples_run_uuid_fkey;
CREATE OR REPLACE FUNCTION bench.check_sample_runs() RETURNS trigger LANGUAGE plpgsql AS $check$
DECLARE
    missing uuid;
BEGIN
    SELECT s.run_uuid INTO missing FROM (SELECT DISTINCT run_uuid FROM new_samples) AS s
        WHERE NOT EXISTS (SELECT FROM bench.runs r WHERE r.uuid = s.run_uuid) LIMIT 1;
    IF FOUND THEN
        RAISE EXCEPTION 'samples of run % stored before the run (bench.runs has no such uuid)', missing
            USING ERRCODE = 'foreign_key_violation';
    END IF;
    RETURN NULL;
END
$check$;
CREATE OR REPLACE FUNCTION bench.keep_referenced_runs() RETURNS trigger LANGUAGE plpgsql AS $keep$
BEGIN
    IF (TG_OP = 'DELETE' OR NEW.uuid IS DISTINCT FROM OLD.uuid)
            AND EXISTS (SELECT FROM bench.samples WHERE run_uuid = OLD.uuid) THEN
        RAISE EXCEPTION 'run % has samples in bench.samples: delete them first', OLD.uuid
            USING ERRCODE = 'foreign_key_violation';
    END IF;
    RETURN CASE WHEN TG_OP = 'DELETE' THEN OLD ELSE NEW END;
END
$keep$;
DROP TRIGGER IF EXISTS samples_check_runs_after_insert ON bench.samples;
CREATE TRIGGER samples_check_runs_after_insert AFTER INSERT ON bench.samples REFERENCING NEW TABLE AS new_samples
    FOR EACH STATEMENT EXECUTE FUNCTION bench.check_sample_runs();
DROP TRIGGER IF EXISTS samples_check_runs_after_update ON bench.samples;
CREATE TRIGGER samples_check_runs_after_update AFTER UPDATE ON bench.samples REFERENCING NEW TABLE AS new_samples
    FOR EACH STATEMENT EXECUTE FUNCTION bench.check_sample_runs();
DROP TRIGGER IF EXISTS runs_keep_referenced ON bench.runs;
CREATE TRIGGER runs_keep_referenced BEFORE DELETE OR UPDATE OF uuid ON bench.runs
    FOR EACH ROW EXECUTE FUNCTION bench.keep_referenced_runs();
"""

#: Version 1 -> 2: each typed column from the stored JSON, where it holds a number there.
_BACKFILL_TYPED = "UPDATE bench.samples SET " + ", ".join(
    f"\"{name}\" = CASE WHEN jsonb_typeof(values_json::jsonb -> '{name}') = 'number'"
    f" THEN (values_json::jsonb ->> '{name}')::double precision END"
    for name in TYPED_COLUMNS
)
_LOCK_KEY = 9283_21  # advisory lock serialising schema creation by benches that connect at once


def ensure_schema(conn: Any, url: str) -> None:
    """Create the lab schema when missing; refuse a server whose schema is newer than this bench's."""
    with conn.transaction():
        conn.execute("SELECT pg_advisory_xact_lock(%s)", (_LOCK_KEY,))
        row = conn.execute("SELECT to_regclass('bench.schema_version')").fetchone()
        if row[0] is not None:
            found = conn.execute("SELECT max(version) FROM bench.schema_version").fetchone()[0]
            if found is not None and found > LAB_SCHEMA_VERSION:
                raise LabStoreError(
                    f"lab store {redacted(url)}: server schema version {found} is newer than "
                    f"this bench's ({LAB_SCHEMA_VERSION}); upgrade bench to sync"
                )
            if found == LAB_SCHEMA_VERSION:
                return
        else:
            found = None
        conn.execute(_DDL)
        conn.execute(typed_columns_ddl("bench.samples"))
        if found == 1:  # version 1 had no typed columns: fill them from the JSON the server holds
            conn.execute(_BACKFILL_TYPED)  # (before the pose triggers, which would refold every run it updates)
        conn.execute(POSE_TABLES_DDL)
        conn.execute(_RUN_REFERENCES_DDL)
        if found in (1, 2, 3, 4):  # 1, 2: no pose tables; 3, 4: a row per point: fold the samples the server holds
            conn.execute(POSE_TABLES_BACKFILL)
        if found is not None:
            _log.warning("lab store %s: schema version %s migrated to %s", redacted(url), found, LAB_SCHEMA_VERSION)
        conn.execute("DELETE FROM bench.schema_version")
        conn.execute("INSERT INTO bench.schema_version VALUES (%s)", (LAB_SCHEMA_VERSION,))
