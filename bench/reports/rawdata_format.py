"""A table's cells as ``DataFrame.to_csv`` writes them, formatted a column at a time (:mod:`bench.reports.rawdata`).

``to_csv`` formats every cell through ``ndarray.astype(str)``; here each column is factorised and only its distinct
values are formatted (by pandas itself, so quoting and the text of every value are pandas').
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["column_text", "plain_table"]


def column_text(column: pd.Series) -> list[str]:
    """Each cell of ``column`` as ``to_csv`` writes it (its distinct values formatted once by pandas)."""
    if isinstance(column.dtype, np.dtype) and column.dtype.kind == "f":  # by bit pattern: 0.0 and -0.0 differ
        values = column.to_numpy()
        codes, bits = pd.factorize(values.view(f"i{values.dtype.itemsize}"))
        uniques = bits.view(values.dtype)
    else:
        codes, uniques = pd.factorize(column, use_na_sentinel=True)
    frame = pd.DataFrame({"value": pd.Series(uniques, dtype=column.dtype), "end": 0})
    lines = frame.to_csv(index=False, header=False, lineterminator="\n").split("\n")[:-1]
    texts = [line[:-2] for line in lines]  # drop ",0": a second column keeps an empty value from being quoted
    texts.append("")  # code -1, a missing value: to_csv's na_rep
    return [texts[code] for code in codes.tolist()]


def plain_table(table: pd.DataFrame) -> bool:
    """Whether the fast path writes exactly what ``to_csv`` does: no text with a line break (a quoted line break
    would split a formatted value), a plain column index, more than one column (a row of one empty field is
    written quoted)."""
    if len(table.columns) < 2:
        return False
    if not isinstance(table.columns, pd.Index) or isinstance(table.columns, pd.MultiIndex):
        return False
    for name in table.columns:
        column = table[name]
        if not (
            pd.api.types.is_numeric_dtype(column.dtype)
            or pd.api.types.is_object_dtype(column.dtype)
            or pd.api.types.is_string_dtype(column.dtype)
        ):
            return False  # dates, categories, ...: left to pandas
        if column.dtype == object or pd.api.types.is_string_dtype(column.dtype):
            values = column.dropna().astype(str)
            if values.str.contains("[\r\n]", regex=True).any():
                return False
    return True
