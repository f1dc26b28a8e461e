"""Export a stored run as the tidy table that bench's metrology reads: one row per attained sample.

Columns, in this order when present: ``pose, cycle, cmd_x_mm, cmd_y_mm, cmd_z_mm, x_mm, y_mm, z_mm, cmd_a_deg,
cmd_b_deg, cmd_c_deg, a_deg, b_deg, c_deg, velocity_pct, load_kg, t_s``, then any other stored value in name order.
Manual length readings (``length_mm`` against ``cmd_length_mm``, e.g. the payload ladder's legs) also get their
signed error ``error_mm`` (the input of ``bench analyze payload``). CSV always; Parquet when pyarrow (or
fastparquet) is installed.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.store.database import Store

__all__ = ["EXPORT_FORMATS", "TIDY_COLUMNS", "export_run", "tidy_table"]

#: The leading columns of the tidy table, in order.
TIDY_COLUMNS = ("pose", "cycle", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "x_mm", "y_mm", "z_mm",
                "cmd_a_deg", "cmd_b_deg", "cmd_c_deg", "a_deg", "b_deg", "c_deg", "velocity_pct", "load_kg", "t_s")

EXPORT_FORMATS = ("csv", "parquet")
_UNIT = re.compile(r"_(mm|deg|pct|kg|s|counts)$")


def tidy_table(store: Store, run_id: int, kind: str = "pose") -> pd.DataFrame:
    """The samples of one kind of run ``run_id`` as a tidy DataFrame (one row per sample, step order).

    Raises
    ------
    InsufficientData
        When the run has no sample of that kind.
    """
    store.run(run_id)  # names the run when it does not exist
    samples = store.samples(run_id, kind=kind)
    if not samples:
        raise InsufficientData(f"run {run_id}: no {kind!r} samples to export")
    rows = [{"pose": s.pose, "cycle": s.cycle, **s.values, "t_s": s.t_s, "step_index": s.step_index}
            for s in samples]
    table = pd.DataFrame(rows)
    if {"length_mm", "cmd_length_mm"} <= set(table.columns):  # manual leg readings: signed actuation error
        table["error_mm"] = table["length_mm"] - table["cmd_length_mm"]
    leading = [c for c in TIDY_COLUMNS if c in table.columns]
    table = table[leading + sorted(c for c in table.columns if c not in leading)]
    for column in table.columns:  # counts and indices (no unit in the name) read back as integers
        if column == "cycle" or not _UNIT.search(column) and column not in ("pose", "t_s"):
            values = table[column]
            if pd.api.types.is_numeric_dtype(values) and values.notna().all() and (values % 1 == 0).all():
                table[column] = values.astype(int)
    return table


def _parquet_available() -> bool:
    return any(importlib.util.find_spec(name) is not None for name in ("pyarrow", "fastparquet"))


def export_run(store: Store, run_id: int, path: str | Path, fmt: str = "csv", kind: str = "pose") -> Path:
    """Write the tidy table of a run to ``path`` as ``csv`` or ``parquet``; returns the path written."""
    if fmt not in EXPORT_FORMATS:
        raise ConfigError(f"--format {fmt}: expected one of {', '.join(EXPORT_FORMATS)}")
    if fmt == "parquet" and not _parquet_available():
        raise ConfigError("--format parquet: needs pyarrow (pip install pyarrow); use --format csv")
    table = tidy_table(store, run_id, kind=kind)
    path = Path(path)
    if fmt == "csv":
        table.to_csv(path, index=False, float_format="%.6f")
    else:
        table.to_parquet(path, index=False)
    return path
