"""The lab store's runs and calibrations checked against the checksum their bench stored
(:mod:`bench.store.record_checksum`), carried by the sync since lab schema 5: ``bench store check postgresql://...``
names each damaged record in one line, and the lab's readers refuse one (:func:`refuse_damaged_run`).

The lab's columns hold what the local store hashed, byte for byte: a run's ``status`` and ``reason`` as stored (a
``running`` run stays ``running``), its campaign by name, ``calibration_ids_json`` with the local ids; a
calibration's source run by its local id (``source_run_local_id``). The status and reason the bench read the run as
when it synced it (``read_status``, ``read_reason``: a ``running`` run without a live owner reads as interrupted) are
what the lab shows; they are checked to follow from the stored ones (equal, or ``running`` read as ``running`` or
``interrupted`` with any reason), and a run's ``calibration_uuids_json`` (the lab's link to its calibrations, not in
its checksum) to name calibrations of the ids its checked ``calibration_ids_json`` holds. A record synced before lab schema 5 carries no checksum: it is named as not
checked (not damage) and read as before; the next sync of its bench gives it its checksum.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from bench.store.record_checksum import (
    CALIBRATION_CHECKED_COLUMNS,
    RUN_CHECKED_COLUMNS,
    record_problem,
    refuse,
)
from bench.store.records import from_json

__all__ = [
    "CALIBRATION_CHECK_SQL",
    "READ_REASON_SQL",
    "READ_STATUS_SQL",
    "RUN_CHECK_SQL",
    "calibration_link_problem",
    "calibration_problem",
    "check_lab_records",
    "refuse_damaged_calibration",
    "refuse_damaged_run",
    "run_problem",
]

_LAB_COLUMN = {"uuid": "uuid::text", "source_run_id": "source_run_local_id"}
#: A bench.runs row (aliased ``r``)'s checked columns, in the local hash's order, then its checksum and the status
#: and reason it was read as.
RUN_CHECK_SQL = ", ".join(f"r.{_LAB_COLUMN.get(c, c)}" for c in RUN_CHECKED_COLUMNS) + (
    ", r.checksum, r.read_status, r.read_reason"
)
#: A bench.calibrations row (aliased ``c``)'s checked columns, in the local hash's order, then its checksum.
CALIBRATION_CHECK_SQL = ", ".join(f"c.{_LAB_COLUMN.get(col, col)}" for col in CALIBRATION_CHECKED_COLUMNS) + (
    ", c.checksum"
)
#: The status and reason the lab shows for a bench.runs row ``r``: as its bench read it (as stored before v5).
READ_STATUS_SQL = "(CASE WHEN r.read_status IS NULL THEN r.status ELSE r.read_status END)"
READ_REASON_SQL = "(CASE WHEN r.read_status IS NULL THEN r.reason ELSE r.read_reason END)"

_STATUS = RUN_CHECKED_COLUMNS.index("status")
_CALIBRATION_IDS = RUN_CHECKED_COLUMNS.index("calibration_ids_json")
_REASON = RUN_CHECKED_COLUMNS.index("reason")
_N_RUN = len(RUN_CHECKED_COLUMNS)
_N_CALIBRATION = len(CALIBRATION_CHECKED_COLUMNS)


def run_problem(checked: Sequence[Any]) -> str | None:
    """Why a run selected by :data:`RUN_CHECK_SQL` (``checked``) is damaged, or None (also for one synced before
    lab schema 5, which carries no checksum to check)."""
    fields, (checksum, read_status, read_reason) = checked[:_N_RUN], checked[_N_RUN:]
    if checksum is None:
        return None
    problem = record_problem(fields, checksum)
    if problem is not None:
        return problem
    status, reason = fields[_STATUS], fields[_REASON]
    if status == "running" and read_status in ("running", "interrupted"):
        return None
    if (read_status, read_reason) == (status, reason):
        return None
    return (
        f"its shown status {read_status!r} (reason {read_reason!r}) does not follow from its stored status "
        f"{status!r} (reason {reason!r})"
    )


def calibration_link_problem(checked: Sequence[Any], uuids_json: str, local_ids: Mapping[str, int]) -> str | None:
    """Why a run's ``calibration_uuids_json`` (the lab's link to its calibrations, which its checksum does not cover)
    names other calibrations than its checked ``calibration_ids_json`` (``local_ids``: the lab's calibrations' ids
    in their files, by UUID; a calibration never synced is not a mismatch), or None (also for a run synced before
    lab schema 5)."""
    if checked[_N_RUN] is None:
        return None
    ids = from_json(checked[_CALIBRATION_IDS])  # checked first: the bytes its bench stored
    try:
        uuids = from_json(uuids_json)
        linked = [None if u is None else local_ids.get(u, -1) for u in uuids]
    except (ValueError, TypeError, AttributeError) as exc:
        return f"its calibration_uuids_json does not parse as a list of UUIDs ({exc})"
    if len(linked) == len(ids) and all(got is None or got == want for got, want in zip(linked, ids)):
        return None
    return f"its calibration_uuids_json names calibrations {linked} where its checked calibration_ids_json holds {ids}"


def calibration_problem(checked: Sequence[Any]) -> str | None:
    """Why a calibration selected by :data:`CALIBRATION_CHECK_SQL` (``checked``) is damaged, or None (also for one
    synced before lab schema 5)."""
    fields, checksum = checked[:_N_CALIBRATION], checked[_N_CALIBRATION]
    return None if checksum is None else record_problem(fields, checksum)


def refuse_damaged_run(
    name: str, checked: Sequence[Any], path: str, links: tuple[str, Mapping[str, int]] | None = None
) -> None:
    """:class:`bench.store.record_checksum.DamagedRecord` in one line when the run ``name`` (``BENCH/ID``) is damaged,
    or its calibration ``links`` (its ``calibration_uuids_json`` and the calibrations' local ids by UUID, when it is
    to be read with its calibrations) name other calibrations than its checked ids."""
    refuse("runs", name, run_problem(checked), path)
    if links is not None:
        refuse("runs", name, calibration_link_problem(checked, *links), path)


def refuse_damaged_calibration(name: str, checked: Sequence[Any], path: str) -> None:
    """:class:`bench.store.record_checksum.DamagedRecord` in one line when the calibration ``name`` is damaged."""
    refuse("calibrations", name, calibration_problem(checked), path)


def check_lab_records(conn: Any, where: str) -> tuple[list[str], list[str]]:
    """The damaged runs and calibrations of the lab store behind ``conn`` (``where`` names it, its password hidden),
    one line each, and one line per record synced before lab schema 5 (no checksum: not checked, not damage)."""
    damaged: list[str] = []
    notes: list[str] = []
    with conn.transaction():
        runs = conn.execute(
            f"SELECT r.bench, r.local_id, {RUN_CHECK_SQL}, r.calibration_uuids_json FROM bench.runs r ORDER BY r.uuid"
        ).fetchall()
        calibrations = conn.execute(
            f"SELECT c.bench, c.local_id, {CALIBRATION_CHECK_SQL} FROM bench.calibrations c ORDER BY c.uuid"
        ).fetchall()
    local_ids = {row[2]: row[1] for row in calibrations}

    def linked_run_problem(checked: Sequence[Any]) -> str | None:
        return run_problem(checked[:-1]) or calibration_link_problem(checked[:-1], checked[-1], local_ids)

    for what, rows, problem_of, checksum_at in (
        ("run", runs, linked_run_problem, _N_RUN),
        ("calibration", calibrations, calibration_problem, _N_CALIBRATION),
    ):
        for bench, local_id, *checked in rows:
            name = f"{what} {bench}/{local_id} ({checked[0][:8]})"
            if checked[checksum_at] is None:
                notes.append(
                    f"{where}: {name}: synced before lab schema 5, its record carries no checksum "
                    "(not checked; sync its bench again)"
                )
                continue
            problem = problem_of(checked)
            if problem is not None:
                damaged.append(f"{where}: {name}: {problem}")
    return damaged, notes
