"""The calibrations of the run store: :class:`StoreCalibrations`, a part of :class:`bench.store.Store`."""

from __future__ import annotations

import uuid
from collections.abc import Mapping
from typing import Any

from bench.errors import ConfigError
from bench.store.connection import GuardedConnection
from bench.store.record_checksum import (
    CALIBRATION_CHECKED_COLUMNS,
    checked_columns_sql,
    record_checksum,
    refuse_damaged,
)
from bench.store.records import CalibrationRecord, from_json, to_json, utc_now

__all__ = ["StoreCalibrations"]


class StoreCalibrations:
    """:class:`bench.store.Store`'s calibrations: named, versioned parameter sets, each with its UUID."""

    path: str
    _db: GuardedConnection
    resuming: int | None

    def add_calibration(
        self, name: str, params: Mapping[str, Any], *, source_run_id: int | None = None, notes: str = ""
    ) -> CalibrationRecord:
        """Store a new version of calibration ``name`` (versions count from 1) and return it."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            (latest,) = self._db.execute(
                "SELECT COALESCE(MAX(version), 0) FROM calibrations WHERE name = ?", (name,)
            ).fetchone()
            fields = (
                str(uuid.uuid4()),
                name,
                latest + 1,
                utc_now(),
                to_json(dict(params), "params"),
                source_run_id,
                notes,
            )
            cursor = self._db.execute(
                f"INSERT INTO calibrations ({', '.join(CALIBRATION_CHECKED_COLUMNS)}, checksum)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (*fields, record_checksum(*fields)),
            )
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        return self.calibration_by_id(cursor.inserted_id())

    def ensure_calibration(self, name: str, params: Mapping[str, Any], *, notes: str = "") -> CalibrationRecord:
        """The latest version of ``name`` if its parameters equal ``params``, else a new version with them; while
        :attr:`resuming` a run, a new version is refused instead (a refused resume writes nothing)."""
        try:
            latest = self.calibration(name)
        except ConfigError:
            latest = None
        if latest is not None and latest.params == from_json(to_json(dict(params), "params")):
            return latest
        if self.resuming is not None:
            now = f"version {latest.version} is the latest" if latest else "none is stored"
            raise ConfigError(
                f"run {self.resuming}: calibration {name!r} in force would be a new version ({now}, "
                f"with other parameters); a run resumes only with the calibrations it started with: "
                "start a new run (bench run)"
            )
        return self.add_calibration(name, params, notes=notes)

    def calibration(self, name: str, version: int | None = None) -> CalibrationRecord:
        """Calibration ``name`` at ``version`` (the latest when None); ``ConfigError`` when missing."""
        query = "SELECT id FROM calibrations WHERE name = ?" + (" AND version = ?" if version else "")
        query += " ORDER BY version DESC LIMIT 1"
        row = self._db.execute(query, (name, version) if version else (name,)).fetchone()
        if row is None:
            wanted = f"version {version}" if version else "any version"
            raise ConfigError(f"calibration {name!r}: {wanted} not found in {self.path}")
        return self.calibration_by_id(row[0])

    def calibration_by_id(self, calibration_id: int) -> CalibrationRecord:
        row = self._db.execute(
            f"SELECT t.id, {checked_columns_sql('calibrations', 't')}, t.checksum FROM calibrations t WHERE t.id = ?",
            (calibration_id,),
        ).fetchone()
        if row is None:
            raise ConfigError(f"calibration id {calibration_id}: not found in {self.path}")
        refuse_damaged("calibrations", row[0], row[1:-1], row[-1], self.path)  # before its parameters are read
        return CalibrationRecord(
            id=row[0],
            uuid=row[1],
            name=row[2],
            version=row[3],
            created_utc=row[4],
            params=from_json(row[5]),
            source_run_id=row[6],
            notes=row[7],
        )

    def calibrations(self) -> list[CalibrationRecord]:
        """Every calibration version, by name then version."""
        ids = [r[0] for r in self._db.execute("SELECT id FROM calibrations ORDER BY name, version")]
        return [self.calibration_by_id(i) for i in ids]
