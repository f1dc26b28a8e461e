"""``bench store check postgresql://...``: every sample the lab store holds checked against the checksum its bench
computed when the sample was taken (carried by the sync since lab schema 4, :mod:`bench.store.sample_checksum`),
and every typed column (``x_mm``, ...) against the number its ``values_json`` holds, so that a changed byte or a
changed number on the server is found, one line per damaged sample.

A sample synced before lab schema 4 carries no checksum: it cannot be checked, and each run holding such samples
is named once (they are not damage). The runs and calibrations are checked against their own checksums by
:mod:`bench.store.lab_records` (``bench store check`` runs both). The pose tables (``bench.pose_keys``, ``bench.pose_point_sets``) are folded from
the typed columns and not checked here.
"""

from __future__ import annotations

from typing import Any

from bench.store.lab_copy import SAMPLE_COLUMNS, TYPED_COLUMNS
from bench.store.records import from_json
from bench.store.sample_checksum import checksum_problem

__all__ = ["check_lab_samples"]

_TYPED = ", ".join(f's."{name}"' for name in TYPED_COLUMNS)
_QUERY = (
    f"SELECT r.bench, r.local_id, s.run_uuid::text, {', '.join(f's.{c}' for c in SAMPLE_COLUMNS)}, s.checksum,"
    f" {_TYPED} FROM bench.samples s JOIN bench.runs r ON r.uuid = s.run_uuid ORDER BY s.run_uuid, s.step_index"
)
_ROWS_PER_FETCH = 10_000


def _typed_problem(values_json: str, typed: tuple[float | None, ...]) -> str | None:
    """Where a typed column differs from the number its row's ``values_json`` holds (NULL where it holds none)."""
    try:
        values = from_json(values_json)
    except ValueError as exc:
        return f"its values_json does not parse ({exc})"
    if not isinstance(values, dict):
        values = {}
    for name, held in zip(TYPED_COLUMNS, typed):
        value = values.get(name)
        expected = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
        if held != expected:
            return f"its typed column {name} holds {held} where its values_json holds {value}"
    return None


def check_lab_samples(conn: Any, where: str) -> tuple[list[str], list[str]]:
    """The damaged samples of the lab store behind ``conn`` (an open psycopg connection; ``where`` names the store,
    its password hidden), one line each, and one line per run whose samples carry no checksum (not damage)."""
    damaged: list[str] = []
    unchecked: dict[str, int] = {}
    with conn.transaction(), conn.cursor(name="bench_lab_check") as rows:
        rows.itersize = _ROWS_PER_FETCH
        rows.execute(_QUERY)
        for bench, local_id, run_uuid, step, kind, pose, cycle, t_s, wall, values, raw, checksum, *typed in rows:
            name = f"run {bench}/{local_id} ({run_uuid[:8]})"
            problem = None
            if checksum is None:
                unchecked[name] = unchecked.get(name, 0) + 1
            else:
                problem = checksum_problem(step, kind, pose, cycle, t_s, wall, values, raw, checksum)
            problem = problem or _typed_problem(values, tuple(typed))
            if problem is not None:
                damaged.append(f"{where}: {name} sample at step {step}: {problem}")
    notes = [
        f"{where}: {name}: {count} samples synced before lab schema 4 carry no checksum (not checked)"
        for name, count in unchecked.items()
    ]
    return damaged, notes
