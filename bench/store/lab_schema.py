"""The lab store's schema in PostgreSQL (schema ``bench``) and its migrations (docs/store.md, section Lab store)."""

from __future__ import annotations

import logging

from bench.store.lab_connection import LabStoreError, redacted
from bench.store.lab_copy import TYPED_COLUMNS, typed_columns_ddl
from bench.store.lab_summary import POSE_TABLES_BACKFILL, POSE_TABLES_DDL

__all__ = ["LAB_SCHEMA_VERSION", "ensure_schema"]

_log = logging.getLogger(__name__)

#: The lab schema version this bench writes (kept in ``bench.schema_version``).
LAB_SCHEMA_VERSION = 3

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
CREATE TABLE IF NOT EXISTS bench.samples (
    run_uuid uuid NOT NULL REFERENCES bench.runs (uuid),
    step_index integer NOT NULL,
    kind text NOT NULL,
    pose text,
    cycle integer,
    t_s double precision NOT NULL,
    wall_utc text NOT NULL,
    values_json text NOT NULL,
    raw_json text,
    PRIMARY KEY (run_uuid, step_index)
);
"""

#: Version 1 -> 2: each typed column from the stored JSON, where it holds a number there.
_BACKFILL_TYPED = "UPDATE bench.samples SET " + ", ".join(
    f"\"{name}\" = CASE WHEN jsonb_typeof(values_json::jsonb -> '{name}') = 'number'"
    f" THEN (values_json::jsonb ->> '{name}')::double precision END"
    for name in TYPED_COLUMNS
)
_LOCK_KEY = 9283_21  # advisory lock serialising schema creation by benches that connect at once


def ensure_schema(conn, url: str) -> None:
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
        if found in (1, 2):  # versions 1 and 2 had no pose tables: fold the samples the server holds
            conn.execute(POSE_TABLES_BACKFILL)
            _log.warning("lab store %s: schema version %s migrated to %s", redacted(url), found, LAB_SCHEMA_VERSION)
        conn.execute("DELETE FROM bench.schema_version")
        conn.execute("INSERT INTO bench.schema_version VALUES (%s)", (LAB_SCHEMA_VERSION,))
