"""Reading runs from the lab store as from a file: run names across benches, and :class:`LabRunView`, the read
interface of :class:`bench.store.Store` that the reports and the export use (``run``, ``runs``, ``samples``,
``sample_kinds``, ``calibration_by_id``, ``calibrations``, ``calibration``, ``path``, ``close``).

Run names (``bench report NAME``, ``bench export NAME``, ``--compare``, ``--trend``), on a file or on the server:

- ``BENCH/ID``: run ``ID`` of bench ``BENCH`` (the id ``bench runs`` lists, local to that bench's file);
- a run UUID, or its first 8 or more hex digits (``bench runs --json`` lists it);
- a bare ``ID``: the run of that id when exactly one bench has one (else the candidates are named).

A view numbers the runs and calibrations it shows by their id in their bench's file, so a report or an export of a
synced run equals the one made from the file. Where two benches' records with the same id meet in one view (a
comparison of ``bench-a/1`` with ``bench-b/1``), the one met later is shown as its id plus the first free multiple
of :data:`COLLIDING_ID_STEP` (``10001``); the reports' raw data and the export's ``.meta.json`` keep its bench and
UUID.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol, Self, TypeVar

from bench.errors import ConfigError
from bench.store.database import CalibrationRecord, RunRecord, SampleRecord, Store
from bench.store.lab_records import (
    CALIBRATION_CHECK_SQL,
    READ_REASON_SQL,
    READ_STATUS_SQL,
    RUN_CHECK_SQL,
    refuse_damaged_calibration,
    refuse_damaged_run,
)
from bench.store.records import from_json
from bench.store.sample_checksum import CHECKED_COLUMNS, sample_checksum
from bench.store.store_samples import checked_sample

__all__ = ["COLLIDING_ID_STEP", "LabRunView", "open_named_runs", "pick_run"]

#: The step that sets apart two benches' records of the same id in one view.
COLLIDING_ID_STEP = 10_000

_BENCH_ID = re.compile(r"(?P<bench>.+)/(?P<id>\d+)")
_UUID_PREFIX = re.compile(r"[0-9a-fA-F-]{8,36}")


class _RunName(NamedTuple):
    """What names a run (:func:`pick_run`): its id in its bench's file, its UUID, its bench."""

    id: int
    uuid: str
    bench: str


class _Named(Protocol):
    @property
    def id(self) -> int: ...
    @property
    def uuid(self) -> str: ...
    @property
    def bench(self) -> str: ...


_R = TypeVar("_R", bound=_Named)


def pick_run(records: Sequence[_R], name: str, where: str) -> _R:
    """The run of ``records`` that ``name`` names (see the module docstring); :class:`ConfigError` in one line when
    it names none or several (``where`` names the store)."""
    text = str(name).strip()
    found = _BENCH_ID.fullmatch(text)
    if found:
        matches = [r for r in records if r.bench == found["bench"] and r.id == int(found["id"])]
    elif text.isdigit():
        matches = [r for r in records if r.id == int(text)]
        if len(text) >= 8:  # a UUID prefix may be all decimal digits ((10/16)^8: 1 in 43 of them)
            matches += [r for r in records if r.uuid.lower().startswith(text) and r not in matches]
    elif _UUID_PREFIX.fullmatch(text) and len(text.replace("-", "")) >= 8:
        prefix = text.lower()
        matches = [r for r in records if r.uuid.lower().startswith(prefix)]
    else:
        raise ConfigError(f"run {text!r}: expected a run id, BENCH/ID or a run UUID (or its first 8+ hex digits)")
    if not matches:
        raise ConfigError(f"run {text}: no such run in {where}")
    if len(matches) > 1:
        listed = ", ".join(f"{r.bench}/{r.id} ({r.uuid[:8]})" for r in matches[:6])
        raise ConfigError(
            f"run {text}: names {len(matches)} runs in {where} ({listed}); name one as BENCH/ID or by its UUID"
        )
    return matches[0]


class _Numbering:
    """Ids shown for one kind of record: the record's id in its bench's file, unless another bench's record of
    that id came first (then id + k * COLLIDING_ID_STEP, the first free k)."""

    def __init__(self) -> None:
        self.shown: dict[str, int] = {}  # uuid -> id shown
        self.uuid_of: dict[int, str] = {}

    def number(self, uuid: str, local_id: int) -> int:
        if uuid not in self.shown:
            shown = local_id
            while shown in self.uuid_of:
                shown += COLLIDING_ID_STEP
            self.shown[uuid], self.uuid_of[shown] = shown, uuid
        return self.shown[uuid]

    def uuid(self, shown: int, what: str, where: str) -> str:
        try:
            return self.uuid_of[int(shown)]
        except KeyError:
            raise ConfigError(f"{what} {shown}: no such {what} in {where}") from None


_RUN_SQL = (
    "SELECT r.local_id, r.uuid::text, r.bench, r.campaign, r.protocol_name, r.protocol_version, r.robot,"
    " r.config_json, r.settings_json, r.calibration_uuids_json, r.software_version, r.git_sha,"
    f" {READ_STATUS_SQL}, {READ_REASON_SQL}, r.started_utc, r.ended_utc,"
    f" (SELECT count(*) FROM bench.samples s WHERE s.run_uuid = r.uuid), {RUN_CHECK_SQL}"
    " FROM bench.runs r WHERE r.uuid = %s"
)
_CALIBRATION_SQL = (
    "SELECT c.local_id, c.uuid::text, c.name, c.version, c.created_utc, c.params_json,"
    f" c.source_run_uuid::text, r.local_id, c.notes, c.bench, {CALIBRATION_CHECK_SQL}"
    " FROM bench.calibrations c LEFT JOIN bench.runs r ON r.uuid = c.source_run_uuid"
)


class LabRunView:
    """The runs of a lab store (:class:`bench.store.lab.LabStore`) behind :class:`bench.store.Store`'s read
    interface, numbered as the module docstring says. Open one with :meth:`open` and name runs with :meth:`name`."""

    def __init__(self, lab: Any) -> None:
        self._lab = lab
        self.path = lab.path
        self.read_only = True
        self._runs = _Numbering()
        self._calibrations = _Numbering()
        self._records: dict[str, RunRecord] = {}
        self._calibration_local_ids: dict[str, int] | None = None

    @classmethod
    def open(cls, url: str) -> Self:
        from bench.store.lab import LabStore

        return cls(LabStore(url))

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        self._lab.close()

    def __repr__(self) -> str:
        return f"LabRunView({self.path!r})"

    # ---- runs ------------------------------------------------------------------------------------------------

    def name(self, name: str) -> int:
        """The id this view shows for the run ``name`` names (see the module docstring)."""
        # by name only (read, checked, by run()): a run damaged on the server does not stop reading the others
        names = [_RunName(*row) for row in self._lab.query("SELECT local_id, uuid::text, bench FROM bench.runs")]
        record = pick_run(names, name, f"lab store {self.path}")
        return self._runs.number(record.uuid, record.id)

    def _record(self, uuid: str) -> RunRecord:
        if uuid not in self._records:
            rows = self._lab.query(_RUN_SQL, (uuid,))
            if not rows:
                raise ConfigError(f"run {uuid}: no such run in lab store {self.path}")
            r = rows[0]
            if self._calibration_local_ids is None:  # (calibrations are few: their ids in their files, once)
                self._calibration_local_ids = dict(
                    self._lab.query("SELECT uuid::text, local_id FROM bench.calibrations")
                )
            links = (r[9], self._calibration_local_ids)
            refuse_damaged_run(f"{r[2]}/{r[0]}", r[17:], self.path, links)  # before its JSON is read
            calibrations = tuple(self._calibration_number(u) for u in from_json(r[9]))
            self._records[uuid] = RunRecord.from_row(
                r, run_id=self._runs.number(r[1], r[0]), calibration_ids=calibrations
            )
        return self._records[uuid]

    def run(self, run_id: int) -> RunRecord:
        """The run this view shows as ``run_id``; ``ConfigError`` when it shows none."""
        return self._record(self._runs.uuid(run_id, "run", f"lab store {self.path}"))

    def runs(self, *, bench: str | None = None, robot: str | None = None, since: str | None = None) -> list[RunRecord]:
        """The synced runs, filtered as :meth:`bench.store.Store.runs`, numbered by this view."""
        return [self._record(r.uuid) for r in self._lab.runs(bench=bench, robot=robot, since=since)]

    # ---- samples ---------------------------------------------------------------------------------------------

    def samples(self, run_id: int, kind: str | None = None) -> list[SampleRecord]:
        """The synced samples of a run in step order, optionally of one ``kind`` only (as
        :meth:`bench.store.Store.samples`: the JSON the file holds, parsed, each sample checked against the checksum
        its bench stored, so a sample changed on the server refuses its run: :class:`DamagedSample`). A sample synced
        before lab schema 4 has no checksum to check; its JSON is parsed as the file's is."""
        uuid = self._runs.uuid(run_id, "run", f"lab store {self.path}")
        rows = self._lab.query(
            f"SELECT {', '.join(CHECKED_COLUMNS)}, checksum"
            " FROM bench.samples WHERE run_uuid = %s" + (" AND kind = %s" if kind else "") + " ORDER BY step_index",
            (uuid, kind) if kind else (uuid,),
        )
        return [
            # a row synced before lab schema 4 has no checksum to check: its JSON is still parsed as the file's is
            checked_sample(run_id, row if row[8] is not None else (*row[:8], sample_checksum(*row[:8])), self.path)
            for row in rows
        ]

    def sample_kinds(self, run_id: int) -> dict[str, int]:
        """How many samples of each kind the run holds on the server, most frequent first."""
        uuid = self._runs.uuid(run_id, "run", f"lab store {self.path}")
        rows = self._lab.query(
            "SELECT kind, count(*) FROM bench.samples WHERE run_uuid = %s GROUP BY kind"
            ' ORDER BY count(*) DESC, kind COLLATE "C"',
            (uuid,),
        )
        return {kind: int(count) for kind, count in rows}

    # ---- calibrations ----------------------------------------------------------------------------------------

    def _calibration_number(self, uuid: str | None) -> int:
        if uuid is None:
            raise ConfigError(
                f"lab store {self.path}: a run names a calibration that was never synced; sync its bench again"
            )
        if uuid not in self._calibrations.shown:
            rows = self._lab.query(_CALIBRATION_SQL + " WHERE c.uuid = %s", (uuid,))
            if not rows:
                raise ConfigError(f"calibration {uuid}: not found in lab store {self.path}; sync its bench again")
            self._calibrations.number(uuid, rows[0][0])
        return self._calibrations.shown[uuid]

    def calibration_by_id(self, calibration_id: int) -> CalibrationRecord:
        uuid = self._calibrations.uuid(calibration_id, "calibration id", f"lab store {self.path}")
        r = self._lab.query(_CALIBRATION_SQL + " WHERE c.uuid = %s", (uuid,))[0]
        refuse_damaged_calibration(f"{r[9]}/{r[0]}", r[10:], self.path)  # before its parameters are read
        source = None if r[6] is None or r[7] is None else self._runs.number(r[6], r[7])
        return CalibrationRecord(
            id=calibration_id,
            uuid=r[1],
            name=r[2],
            version=r[3],
            created_utc=r[4],
            params=from_json(r[5]),
            source_run_id=source,
            notes=r[8],
        )

    def calibrations(self) -> list[CalibrationRecord]:
        """Every synced calibration version, by name then version (then bench)."""
        rows = self._lab.query(_CALIBRATION_SQL + " ORDER BY c.name, c.version, c.bench")
        return [self.calibration_by_id(self._calibration_number(r[1])) for r in rows]

    def calibration(self, name: str, version: int | None = None) -> CalibrationRecord:
        """Calibration ``name`` at ``version`` (the latest when None) among the synced ones."""
        found = [c for c in self.calibrations() if c.name == name and (version is None or c.version == version)]
        if not found:
            wanted = f"version {version}" if version else "any version"
            raise ConfigError(f"calibration {name!r}: {wanted} not found in lab store {self.path}")
        return found[-1]


def open_named_runs(spec: str, names: Sequence[str]) -> tuple[Store | LabRunView, list[int]]:
    """The store ``spec`` opened for reading (a :class:`LabRunView` for a ``postgresql://`` URL, else the file,
    read-only) and the ids it shows for the runs ``names`` name; the caller closes the store."""
    from bench.store.lab import is_lab_url

    if is_lab_url(spec):
        view = LabRunView.open(spec)
        try:
            return view, [view.name(name) for name in names]
        except BaseException:
            view.close()
            raise
    store = Store(spec, read_only=True)
    try:
        records = None
        ids = []
        for name in names:
            if str(name).strip().isdigit() and len(str(name).strip()) < 8:  # 8+ digits may be a UUID prefix
                ids.append(int(name))
                continue
            records = store.runs() if records is None else records
            ids.append(pick_run(records, name, store.path).id)
        return store, ids
    except BaseException:
        store.close()
        raise
