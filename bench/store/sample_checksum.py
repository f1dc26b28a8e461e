"""A checksum on every stored sample, so that a changed byte is found, never read as a different number.

SQLite's own checks (``PRAGMA integrity_check``) see a damaged page, not a changed digit: one flipped bit in a
stored ``values_json`` ("2.1" becoming "2.3") leaves a sound file that exports a different number. Each sample row
therefore carries ``checksum``: the SHA-256 (hex) of its stored columns as stored (the JSON text unparsed), computed
when the sample is encoded, before its commit (:func:`bench.store.sample_rows.encode_sample`). Reading a sample
(:meth:`bench.store.database.Store.samples`) recomputes it and refuses the run in one line naming the run and the
sample's step (:class:`DamagedSample`); ``bench store check`` lists every such row.

The run's id is left out of the hash on purpose: a copy of the rows under another id (the lab store) keeps its
checksums. A store written before schema version 3 gets its rows' checksums when it is migrated: they vouch for the
rows from then on, not for what happened to them before.
"""

from __future__ import annotations

import hashlib
import sqlite3
from collections.abc import Iterable
from typing import Any

from bench.errors import BenchError
from bench.store.records import from_json

__all__ = [
    "CHANGED",
    "CHECKED_COLUMNS",
    "NO_CHECKSUM",
    "DamagedSample",
    "checksum_problem",
    "damaged_sample_lines",
    "hash_fields",
    "parse_sample",
    "sample_checksum",
]

#: The ``samples`` columns the checksum covers, in the order hashed.
CHECKED_COLUMNS = ("step_index", "kind", "pose", "cycle", "t_s", "wall_utc", "values_json", "raw_json")


class DamagedSample(BenchError):
    """A stored sample whose bytes no longer match its checksum, or whose JSON does not parse: its run is refused."""


#: What is wrong with a stored record (a sample, a run, a calibration) whose checksum is missing or does not match.
NO_CHECKSUM = "it has no checksum (written outside bench)"
CHANGED = "its stored bytes no longer match their checksum (changed since it was stored)"
#: Separates the columns in the hashed text; ``NULL`` is hashed as :data:`_NULL` (neither occurs in bench's text).
_SEPARATOR, _NULL = "\x1f", "\x00"


def sample_checksum(
    step_index: int,
    kind: str,
    pose: str | None,
    cycle: int | None,
    t_s: float,
    wall_utc: str,
    values_json: str,
    raw_json: str | None,
) -> str:
    """SHA-256 (hex) of one sample's stored columns (:data:`CHECKED_COLUMNS`) as one text: the columns joined by
    U+001F, NULL as U+0000, integers in decimal, ``t_s`` as the shortest text that reads back as the same double
    (Python's ``repr``, which SQLite's REAL keeps exactly), all encoded as UTF-8 (bytes that are not UTF-8, read
    with ``surrogateescape``, hash as themselves).
    """
    return hash_fields(
        (
            str(int(step_index)),
            kind,
            pose,
            None if cycle is None else str(int(cycle)),
            repr(float(t_s)),
            wall_utc,
            values_json,
            raw_json,
        )
    )


def hash_fields(fields: Iterable[str | None]) -> str:
    """SHA-256 (hex) of text fields joined by U+001F, None as U+0000, encoded as UTF-8 (bytes that are not UTF-8,
    read with ``surrogateescape``, hash as themselves): the hash of every stored record's checksum."""
    text = _SEPARATOR.join(_NULL if field is None else field for field in fields)
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()


def checksum_problem(
    step_index: int,
    kind: str,
    pose: str | None,
    cycle: int | None,
    t_s: float,
    wall_utc: str,
    values_json: str,
    raw_json: str | None,
    checksum: str | None,
) -> str | None:
    """What is wrong with one stored row's checksum (None when it matches)."""
    if checksum is None:
        return NO_CHECKSUM
    try:
        expected = sample_checksum(step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json)
    except (TypeError, ValueError) as exc:
        return f"a column has the wrong type ({exc})"
    if expected != checksum:
        return CHANGED
    return None


def _refusal(run_id: int, step_index: int, path: str, problem: str) -> DamagedSample:
    return DamagedSample(
        f"store {path}: run {run_id} sample at step {step_index} is damaged: {problem}; its run is "
        f"refused, nothing computed from it: list the damage with `bench store check {path}` and "
        "read a backup copy"
    )


def parse_sample(run_id: int, row: tuple[Any, ...], path: str) -> tuple[Any, Any]:
    """The parsed ``(values, raw)`` of a stored row (:data:`CHECKED_COLUMNS` then ``checksum``) of run ``run_id``;
    :class:`DamagedSample` in one line when the row fails its checksum or its JSON does not parse."""
    problem = checksum_problem(*row)
    if problem is not None:
        raise _refusal(run_id, row[0], path, problem)
    parsed = []
    for name, text in (("values_json", row[6]), ("raw_json", row[7])):
        try:
            parsed.append(None if text is None and name == "raw_json" else from_json(text))
        except (TypeError, ValueError) as exc:
            raise _refusal(run_id, row[0], path, f"its {name} does not parse ({exc})") from None
    return parsed[0], parsed[1]


def damaged_sample_lines(db: sqlite3.Connection, path: str) -> Iterable[str]:
    """One line per damaged sample row of the store behind ``db`` (for ``bench store check``); nothing for a store
    older than schema version 3 (no ``checksum`` column: opening it with bench migrates it)."""
    columns = {row[1] for row in db.execute("PRAGMA table_info(samples)")}
    if "checksum" not in columns:
        return
    # JSON validity by SQLite (json_valid, in C): bench writes only strict JSON (no NaN), which it accepts
    query = (
        f"SELECT id, run_id, {', '.join(CHECKED_COLUMNS)}, checksum, json_valid(values_json),"
        " raw_json IS NULL OR json_valid(raw_json) FROM samples ORDER BY run_id, step_index"
    )
    for rowid, run_id, *row, values_ok, raw_ok in db.execute(query):
        problem = checksum_problem(*row)
        if problem is None and not (values_ok and raw_ok):
            problem = f"its {'values_json' if not values_ok else 'raw_json'} does not parse"
        if problem is not None:
            yield f"{path}: run {run_id} sample at step {row[0]} (samples row {rowid}): {problem}"
