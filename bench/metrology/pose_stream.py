"""Pose tables larger than memory: `analyze_pose_file` reads a plain CSV a chunk at a time and gives the figures of
:func:`bench.metrology.tables.analyze_poses`, bit for bit.

Each chunk is checked as :func:`~bench.metrology.tables.pose_table` checks a whole table (the same messages, rows
numbered in the file), its commands and frame tags compared with each pose's first row, and its samples appended to
one spill file per pose group (row number, cycle, attained columns; float64) in a temporary folder. Then each group
is read back, sorted by cycle (a repeated cycle refused, naming its row) and analysed by
:func:`~bench.metrology.tables.pose_result`. Memory: one chunk of the CSV and the largest pose group, never the run;
disk: 8 bytes per stored cell of the spill.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from bench.errors import ConfigError
from bench.metrology.table_reading import NotPlainTable, read_table_chunks, read_table_csv
from bench.metrology.tables import (
    _COMMAND,
    ANGLE_PAIRS,
    CONDITION_COLUMNS,
    POSE_NUMERIC_COLUMNS,
    PoseGroup,
    PoseResult,
    _check_constant_command,
    _check_single_frame,
    _check_unique_cycles,
    analyze_poses,
    measured_axes,
    pose_result,
    pose_table,
)

__all__ = ["CHUNK_ROWS", "STREAM_MIN_BYTES", "analyze_pose_file", "pose_file_results", "refuse_unanalysable"]

#: Rows of the CSV parsed at a time (about 70 MB of a pose table's columns as float64).
CHUNK_ROWS = 1 << 20
#: ``bench analyze iso9283`` reads a file at least this large a chunk at a time: above about two chunks the stream is
#: the faster too (10^7 rows, 0.58 GB: 19.4 s and 459 MB in chunks, 28.1 s and 1.43 GB whole; the same output).
STREAM_MIN_BYTES = 1 << 27


@dataclass
class _Group:
    """What the first pass keeps of one pose group: its key, first row, and spill file."""

    key: tuple[Any, ...]
    first_row: pd.DataFrame  #: the group's first row (its commands, frame tag and pose label)
    spill: Path
    rows: int = 0
    cycles_in_order: bool = True
    last_cycle: float = -np.inf


def analyze_pose_file(
    path: str | Path,
    *,
    instrument_u_mm: float = 0.0,
    k: float = 2.0,
    resamples: int = 1000,
    chunk_rows: int = CHUNK_ROWS,
) -> list[PoseResult] | None:
    """:func:`~bench.metrology.tables.analyze_poses` of the pose table in ``path`` read ``chunk_rows`` rows at a time,
    or None when the file is not a plain table (quotes, comment lines, a row pandas' C reader refuses): the caller
    then reads it whole, where the row-by-row reader names the fault. Position axes as with ``partial_axes``.

    Raises
    ------
    ConfigError
        A bad cell, a second command or frame in a pose, a repeated cycle (naming the file's row), or no rows.
    """
    chunks = read_table_chunks(path, numeric=POSE_NUMERIC_COLUMNS, chunk_rows=chunk_rows)
    if chunks is None:
        return None
    source = str(path)
    with tempfile.TemporaryDirectory(prefix="bench-poses-") as folder:
        try:
            groups, layout = _spill(chunks, Path(folder), source)
        except NotPlainTable:
            return None
        if not groups:
            refuse_unanalysable(pd.DataFrame(), source)
        axes, angles = layout
        varying = [
            i for i, _ in enumerate(CONDITION_COLUMNS) if len({g.key[1 + i] for g in groups.values()} - {None}) > 1
        ]
        results = []
        for group in groups.values():
            records = np.fromfile(group.spill, dtype=np.float64).reshape(group.rows, -1)
            group.spill.unlink()
            if not group.cycles_in_order:
                records = records[np.argsort(records[:, 1], kind="stable")]
            _refuse_repeated_cycle(records, group, source)
            pose = str(group.first_row["pose"].iat[0])
            conditions = tuple((CONDITION_COLUMNS[i], float(group.key[1 + i])) for i in varying)
            label = pose if not conditions else f"{pose} ({', '.join(f'{n}={v:g}' for n, v in conditions)})"
            commands = [*_COMMAND, *(cmd for cmd, _ in angles)]
            width = len(axes)
            results.append(
                pose_result(
                    PoseGroup(
                        label,
                        pose,
                        conditions,
                        axes,
                        np.array([records[:, 2 + i] for i in range(width)]).T,
                        angles,
                        np.array([records[:, 2 + width + i] for i in range(len(angles))]).T if angles else None,
                        {c: float(group.first_row[c].iat[0]) for c in commands},
                    ),
                    source=source,
                    instrument_u_mm=instrument_u_mm,
                    k=k,
                    resamples=resamples,
                )
            )
            del records
    return results


def refuse_unanalysable(frame: pd.DataFrame, source: str) -> None:
    """Refuse a table ``bench analyze iso9283`` cannot analyse: laser-grid readings (partial by design) or no rows."""
    if "horizontal_valid" in frame.columns:  # the laser grid: partial readings, as bench report lays them out
        raise ConfigError(
            f"{source}: laser-grid readings (column horizontal_valid; axes empty where a screen did not "
            f"decode), expected complete readings; analyse them with bench analyze grid-positioning {source}"
        )
    if frame.empty:  # a header and no rows: nothing measured, never an empty result printed as if it were one
        raise ConfigError(f"{source}: no rows, expected at least one measured pose")


def _spill(chunks: Iterable[pd.DataFrame], folder: Path, source: str) -> tuple[dict[tuple[Any, ...], _Group], Any]:
    """First pass: check every chunk, append each group's samples to its spill file; the groups in order of
    appearance and the table's (axes, angles)."""
    groups: dict[tuple[Any, ...], _Group] = {}
    layout = None
    for frame in chunks:
        refuse_unanalysable(frame, source)
        table = pose_table(frame, partial_axes=True)
        angles = [(cmd, att) for cmd, att in ANGLE_PAIRS if cmd in table.columns]
        layout = layout or (measured_axes(table), angles)
        axes = layout[0]
        commands = [*_COMMAND, *(cmd for cmd, _ in angles)]
        conditions = [c for c in CONDITION_COLUMNS if c in table.columns]
        keys = [table["pose"], *(table[c] for c in conditions)]
        codes = table.groupby(keys, sort=False).ngroup().to_numpy()
        order = np.argsort(codes, kind="stable")
        starts = np.flatnonzero(np.r_[True, codes[order][1:] != codes[order][:-1]])
        columns = ["cycle", *axes, *(att for _, att in angles)]
        values = np.column_stack([table.index.to_numpy(float), *(table[c].to_numpy(float) for c in columns)])
        poses, condition_values = table["pose"], {c: table[c].to_numpy(float) for c in conditions}
        for rows in np.split(order, starts[1:]):
            key = (
                str(poses.iat[rows[0]]),
                *(float(condition_values[c][rows[0]]) if c in conditions else None for c in CONDITION_COLUMNS),
            )
            group = groups.get(key)
            if group is None:
                group = groups[key] = _Group(key, table.iloc[rows[:1]], folder / f"{len(groups)}.f64")
            _check_against_first(table, rows, group, commands, source)
            records = values[rows]
            group.cycles_in_order &= bool(records[0, 1] > group.last_cycle and np.all(np.diff(records[:, 1]) > 0))
            group.last_cycle = float(records[-1, 1])
            with group.spill.open("ab") as handle:
                records.tofile(handle)
            group.rows += len(rows)
    return groups, layout


def _check_against_first(
    table: pd.DataFrame, rows: np.ndarray, group: _Group, commands: Sequence[str], source: str
) -> None:
    """A row of this chunk whose command or frame tag differs from the group's first row: the message of
    :func:`~bench.metrology.tables.analyze_poses` (the checks run on the first row and the first row at fault)."""
    first = group.first_row
    differs = np.zeros(len(rows), dtype=bool)
    for column in commands:
        differs |= table[column].to_numpy(float)[rows] != float(first[column].iat[0])
    if "frame" in table.columns:
        differs |= table["frame"].iloc[rows].astype(str).str.strip().to_numpy() != str(first["frame"].iat[0]).strip()
    if differs.any():
        pair = pd.concat([first, table.iloc[rows[[int(np.argmax(differs))]]]])
        _check_constant_command(pair, commands, source)
        _check_single_frame(pair, source)


def _refuse_repeated_cycle(records: np.ndarray, group: _Group, source: str) -> None:
    """Refuse the earliest row (in the file) whose cycle an earlier row of the group already had, as
    :func:`~bench.metrology.tables.analyze_poses` names it; ``records`` sorted by cycle, stably."""
    repeated = np.flatnonzero(records[1:, 1] == records[:-1, 1]) + 1
    if len(repeated):
        first_repeat = repeated[np.argmin(records[repeated, 0])]
        row, cycle = int(records[first_repeat, 0]), records[first_repeat, 1]
        _check_unique_cycles(pd.DataFrame({"pose": [group.key[0]] * 2, "cycle": [cycle] * 2}, index=[-1, row]), source)


def pose_file_results(
    path: str | Path, *, instrument_u_mm: float = 0.0, k: float = 2.0, chunk_rows: int | None = None
) -> list[PoseResult]:
    """The pose results of the table in ``path`` as ``bench analyze iso9283`` computes them: a chunk at a time when
    ``chunk_rows`` is given or the file has at least ``STREAM_MIN_BYTES`` (:func:`analyze_pose_file`), else (or
    when the file is not plain) read whole; position axes as measured (``partial_axes``)."""
    file = Path(path)
    if chunk_rows is None and file.is_file() and file.stat().st_size >= STREAM_MIN_BYTES:
        chunk_rows = CHUNK_ROWS
    if chunk_rows is not None:
        results = analyze_pose_file(file, instrument_u_mm=instrument_u_mm, k=k, chunk_rows=chunk_rows)
        if results is not None:
            return results
    frame = read_table_csv(path, numeric=POSE_NUMERIC_COLUMNS)
    refuse_unanalysable(frame, str(path))
    # an instrument that measures a subset of the axes (the camera: x, y): AP/RP over those, as bench report does
    return analyze_poses(pose_table(frame, partial_axes=True), instrument_u_mm=instrument_u_mm, k=k)
