"""Export a stored run as the tidy table that bench's metrology reads: one row per attained sample.

Columns, in this order when present: ``pose, cycle, cmd_x_mm, cmd_y_mm, cmd_z_mm, x_mm, y_mm, z_mm, cmd_a_deg,
cmd_b_deg, cmd_c_deg, a_deg, b_deg, c_deg, velocity_pct, load_kg, t_s``, then any other stored value in name order.
Manual length readings (``length_mm`` against ``cmd_length_mm``, e.g. the payload ladder's legs) also get their
signed error ``error_mm`` (the input of ``bench analyze payload``). CSV always; Parquet when pyarrow (or
fastparquet) is installed.

Samples that hold a streamed series (kind ``arrival``: the position from before the move was reported done until
the pose had settled) export with ``series=True`` as one row per point of each series: ``pose, cycle, cmd_*,
velocity_pct, load_kg`` of the sample, then ``t_s`` (relative to the move-done signal) and the measured columns
(the input of ``bench analyze stabilisation``).

A run measured by a relative instrument (the mice) adds ``registration``: the segment number of the registration
each row was measured in (:mod:`bench.store.registrations`); rows of different registrations share a frame only
within the registrations' uncertainty.
"""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench.errors import ConfigError, InsufficientData
from bench.extras import install_hint
from bench.store.database import SampleRecord, Store
from bench.store.descriptors import SAMPLE_KINDS, dtype_of, unit_of
from bench.store.registrations import registration_of, registrations

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "EXPORT_FORMATS",
    "TIDY_COLUMNS",
    "MixedSeries",
    "SeriesPieces",
    "default_kind",
    "export_run",
    "ordered_columns",
    "series_chunks",
    "series_context",
    "series_contexts",
    "series_table",
    "tidy_table",
]

#: The leading columns of the tidy table, in order.
TIDY_COLUMNS = (
    "pose",
    "cycle",
    "cmd_x_mm",
    "cmd_y_mm",
    "cmd_z_mm",
    "x_mm",
    "y_mm",
    "z_mm",
    "cmd_a_deg",
    "cmd_b_deg",
    "cmd_c_deg",
    "a_deg",
    "b_deg",
    "c_deg",
    "velocity_pct",
    "load_kg",
    "t_s",
)

EXPORT_FORMATS = ("csv", "parquet")


def tidy_table(store: Store, run_id: int, kind: str = "pose") -> pd.DataFrame:
    """The samples of one kind of run ``run_id`` as a tidy DataFrame (one row per sample, step order).

    Raises
    ------
    InsufficientData
        When the run has no sample of that kind.
    """
    import pandas as pd  # here, not at import: the store is opened by the desktop app and the CLI at start-up

    store.run(run_id)  # names the run when it does not exist
    samples = store.samples(run_id, kind=kind)
    if not samples:
        raise InsufficientData(f"run {run_id}: no {kind!r} samples to export")
    rows = [{"pose": s.pose, "cycle": s.cycle, **s.values, "t_s": s.t_s, "step_index": s.step_index} for s in samples]
    entries = registrations(store.run(run_id).settings)
    if entries:  # a relative instrument: which registration (segment) each row was measured in
        for row, sample in zip(rows, samples):
            row["registration"] = registration_of(sample.wall_utc, entries, sample.t_s)
    table = pd.DataFrame(rows)
    if {"length_mm", "cmd_length_mm"} <= set(table.columns):  # manual leg readings: signed actuation error
        table["error_mm"] = table["length_mm"] - table["cmd_length_mm"]
    leading = [c for c in TIDY_COLUMNS if c in table.columns]
    table = table[leading + sorted(c for c in table.columns if c not in leading)]
    for column in table.columns:  # declared integers, and indices (no unit) read back as integers
        if column in ("pose", "t_s"):
            continue
        if column == "cycle" or dtype_of(kind, column) == "int" or unit_of(kind, column) is None:
            values = table[column]
            if pd.api.types.is_numeric_dtype(values) and values.notna().all() and (values % 1 == 0).all():
                table[column] = values.astype(int)
    return table


#: Sample values repeated on every row of a streamed series besides the commanded ones: its conditions.
_SERIES_CONTEXT = ("velocity_pct", "load_kg", "step", "step_distance_mm")


def series_table(
    store: Store, run_id: int, kind: str = "arrival", samples: Iterable[SampleRecord] | None = None
) -> pd.DataFrame:
    """The streamed series of the samples of one kind, one row per series point (see the module docstring);
    ``samples``: those samples when the caller has read them already (they are read once per report).

    Raises
    ------
    InsufficientData
        When the run has no sample of that kind with a stored series.
    """
    import pandas as pd

    store.run(run_id)
    streamed = [
        item
        for sample in (store.samples(run_id, kind=kind) if samples is None else samples)
        if (item := _streamed(sample)) is not None
    ]
    if not streamed:
        raise InsufficientData(f"run {run_id}: no {kind!r} samples with a streamed series to export")
    table = _uniform_series(streamed)
    if table is None:  # samples that differ in their columns: pandas aligns them (missing values as NaN)
        table = pd.concat([pd.DataFrame({**context, **series}) for context, series in streamed], ignore_index=True)
    return _ordered(table)


class MixedSeries(Exception):
    """The samples' series differ in their columns or types: :func:`series_table` aligns them over the whole run."""


def series_chunks(store: Store, run_id: int, kind: str = "arrival", rows: int = 200_000) -> Iterator[pd.DataFrame]:
    """:func:`series_table` in pieces of about ``rows`` rows, the samples read one at a time (a long path run's
    millions of points are never held): the pieces' rows, in order, are that table's, with its columns and dtypes.

    Raises
    ------
    MixedSeries
        Before a piece that differs from the first in its columns or dtypes, or whose samples differ (the whole
        table aligns such samples, which needs them all): :func:`series_table` then.
    InsufficientData
        When the run has no sample of that kind with a stored series.
    """
    store.run(run_id)
    pieces = SeriesPieces(rows)
    for sample in getattr(store, "iter_samples", store.samples)(run_id, kind=kind):  # one at a time where it can
        piece = pieces.add(sample)
        if piece is not None:
            yield piece
    last = pieces.rest()
    if last is not None:
        yield last
    elif not pieces.points:
        raise InsufficientData(f"run {run_id}: no {kind!r} samples with a streamed series to export")


class SeriesPieces:
    """The pieces of :func:`series_chunks` from samples given one at a time (:meth:`add`, then :meth:`rest`)."""

    def __init__(self, rows: int = 200_000) -> None:
        self.rows = rows
        self.points = 0  #: the series points given so far
        self._streamed: list[tuple[dict[str, Any], dict[str, Any]]] = []
        self._waiting = 0
        self._first: Any = None  # the first piece's dtypes

    def add(self, sample: SampleRecord) -> pd.DataFrame | None:
        """Take ``sample``; the next piece once it holds ``rows`` points, else None. Raises MixedSeries."""
        item = _streamed(sample)
        if item is None:
            return None
        self._streamed.append(item)
        count = len(next(iter(item[1].values())))
        self.points += count
        self._waiting += count
        return self.rest() if self._waiting >= self.rows else None

    def rest(self) -> pd.DataFrame | None:
        """The piece of the samples taken since the last one, None without any. Raises MixedSeries."""
        if not self._streamed:
            return None
        table = _uniform_series(self._streamed)
        if table is None:
            raise MixedSeries("samples with different series columns or types")
        table = _ordered(table)
        if self._first is None:
            self._first = table.dtypes
        elif not table.dtypes.equals(self._first):
            raise MixedSeries("pieces with different columns or dtypes")
        self._streamed, self._waiting = [], 0
        return table


def _streamed(sample: SampleRecord) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """A sample's (context: pose, cycle, commanded values and conditions; its series), None without a series."""
    series = sample.raw.get("series") if isinstance(sample.raw, dict) else None
    if not series:
        return None
    context = {
        "pose": sample.pose,
        "cycle": sample.cycle,
        **{k: v for k, v in sample.values.items() if k.startswith("cmd_") or k in _SERIES_CONTEXT},
    }
    return context, series


def _ordered(table: pd.DataFrame) -> pd.DataFrame:
    """The streamed-series table's columns in the order of the module docstring (:func:`ordered_columns`)."""
    return table[ordered_columns(table.columns)]


def _context_columns(contexts: list[dict[str, Any]], lengths: Any) -> dict[str, Any] | None:
    """The context columns of samples with these contexts and series ``lengths``: each value repeated over its
    sample's rows, when every sample has the same keys, no missing value and one type (text, integer or float) per
    key; None otherwise."""
    import numpy as np

    keys = list(contexts[0])
    if any(list(context) != keys or any(v is None for v in context.values()) for context in contexts):
        return None
    columns: dict[str, Any] = {}
    for key in keys:
        values = [context[key] for context in contexts]
        if not all(type(v) is type(values[0]) for v in values) or not isinstance(values[0], (str, int, float)):
            return None
        columns[key] = np.repeat(np.array(values, dtype=object if isinstance(values[0], str) else None), lengths)
    return columns


def _typed_texts(table: pd.DataFrame, context: dict[str, Any]) -> pd.DataFrame:
    """``table`` with its text context columns typed as pandas infers them from per-sample frames."""
    import pandas as pd

    for key, value in context.items():
        if isinstance(value, str):
            table[key] = table[key].astype(pd.Series([value]).dtype)
    return table


def series_contexts(contexts: list[dict[str, Any]]) -> pd.DataFrame | None:
    """One row per sample of the context columns (pose, cycle, commanded values, conditions) of samples with these
    contexts, with the dtypes :func:`series_table` gives those columns; None where it would align the samples."""
    import pandas as pd

    columns = _context_columns(contexts, 1)
    return None if columns is None else _typed_texts(pd.DataFrame(columns), contexts[0])


def series_context(sample: SampleRecord) -> dict[str, Any] | None:
    """A sample's context (pose, cycle, commanded values, conditions: repeated on each row of its series), None
    for a sample without a streamed series."""
    item = _streamed(sample)
    return None if item is None else item[0]


def ordered_columns(names: Iterable[str]) -> list[str]:
    """The streamed-series table's column names in the order of the module docstring."""
    names = list(names)
    leading = [c for c in TIDY_COLUMNS if c in names and c != "t_s"] + ["t_s"]
    return leading + sorted(c for c in names if c not in leading)


def _uniform_series(streamed: list[tuple[dict[str, Any], dict[str, Any]]]) -> pd.DataFrame | None:
    """The rows of ``streamed`` (context, series) in one pass, column by column (a DataFrame per sample took 10 s
    for a long path run's 7,000 samples), when every sample has the same context and series columns, no missing
    context and floating-point series; None otherwise (the caller concatenates per sample, which gives the same
    table column for column)."""
    import numpy as np
    import pandas as pd

    context_keys, series_keys = list(streamed[0][0]), list(streamed[0][1])
    if any(list(series) != series_keys for _, series in streamed):
        return None
    lengths = np.array([len(series[series_keys[0]]) for _, series in streamed])
    columns = _context_columns([context for context, _ in streamed], lengths)
    if columns is None:
        return None
    for key in series_keys:
        parts = [series[key] for _, series in streamed]
        if any(len(part) != n for part, n in zip(parts, lengths)):
            return None
        arrays = [np.asarray(part) for part in parts]
        if any(array.dtype.kind != "f" for array in arrays):  # ints, bools, text: per-sample frames keep their types
            return None
        columns[key] = np.concatenate(arrays)
    table = pd.DataFrame({key: columns[key] for key in (*context_keys, *series_keys)})
    return _typed_texts(table, streamed[0][0])


def _parquet_available() -> bool:
    return any(importlib.util.find_spec(name) is not None for name in ("pyarrow", "fastparquet"))


def default_kind(store: Store, run_id: int) -> str:
    """The sample kind ``bench export`` (and the window's Export) writes unless told: ``pose`` when the run has pose
    samples, else its most frequent kind."""
    store.run(run_id)  # names a run that does not exist
    kinds = store.sample_kinds(run_id)
    return "pose" if "pose" in kinds or not kinds else next(iter(kinds))


def export_run(
    store: Store, run_id: int, path: str | Path, fmt: str = "csv", kind: str = "pose", series: bool = False
) -> Path:
    """Write the tidy table of a run (``series=True``: its streamed series) to ``path`` as ``csv`` or ``parquet``;
    returns the path written.

    Beside it goes ``<path>.meta.json``: the run's identity (UUID, bench, local id), protocol, robot, and the unit,
    dtype and meaning of every exported column (from the sample descriptor; the unit from the name otherwise)."""
    if not Path(path).parent.is_dir():
        raise ConfigError(f"export: folder {Path(path).parent} does not exist, expected an existing folder")
    if fmt not in EXPORT_FORMATS:
        raise ConfigError(f"--format {fmt}: expected one of {', '.join(EXPORT_FORMATS)}")
    if fmt == "parquet" and not _parquet_available():
        raise ConfigError(f"--format parquet: {install_hint('pyarrow')} (or use --format csv)")
    table = series_table(store, run_id, kind=kind) if series else tidy_table(store, run_id, kind=kind)
    path = Path(path)
    if fmt == "csv":
        table.to_csv(path, index=False, float_format="%.6f")
    else:
        table.to_parquet(path, index=False)
    _write_meta(store, run_id, kind, table, Path(f"{path}.meta.json"))
    return path


def _write_meta(store: Store, run_id: int, kind: str, table: pd.DataFrame, meta_path: Path) -> None:
    run = store.run(run_id)
    descriptor = SAMPLE_KINDS.get(kind)
    columns = {}
    for name in table.columns:
        declared = descriptor.column(name) if descriptor else None
        columns[name] = declared.as_dict() if declared else {"name": name, "unit": unit_of(kind, name)}
    meta = {
        "run_uuid": run.uuid,
        "bench": run.bench,
        "run_id": run.id,
        "protocol": run.protocol_name,
        "protocol_version": run.protocol_version,
        "robot": run.robot,
        "campaign": run.campaign,
        "kind": kind,
        "columns": columns,
    }
    meta_path.write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n", encoding="utf-8")
