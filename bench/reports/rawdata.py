"""The raw-data CSV beside a report, written in one vectorised pass and hashed as it is written.

``DataFrame.to_csv`` formats every cell through ``ndarray.astype(str)`` chunk by chunk: 33 s for the 2.3 million
streamed points of a long path run (12 columns), where 8 of the columns repeat one value per stored sample. Here each
column is factorised, only its distinct values are formatted (by pandas itself, so quoting and the text of every value
are pandas'), and the rows are joined from those strings: the same bytes as ``table.to_csv(path, index=False)`` (a test
compares them), in a few seconds. The decision to keep writing the file (and not only cite the store): the report's
"recompute" line reads it, and a customer gets the data the numbers came from without access to the bench's store;
``bench export`` writes the same table on demand.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["write_table_csv"]

#: Rows joined and written per chunk (bounds the memory of the row strings: about 100 bytes a row).
_CHUNK_ROWS = 200_000


def _column_text(column: pd.Series) -> list[str]:
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


def _plain(table: pd.DataFrame) -> bool:
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


def write_table_csv(table: pd.DataFrame, path: str | Path) -> str:
    """Write ``table`` to ``path`` as ``table.to_csv(path, index=False)`` would; returns the file's SHA-256."""
    path = Path(path)
    digest = hashlib.sha256()
    if not _plain(table):
        buffer = io.StringIO()
        table.to_csv(buffer, index=False)
        data = buffer.getvalue().encode("utf-8")
        path.write_bytes(data)
        return hashlib.sha256(data).hexdigest()
    header = table.head(0).to_csv(index=False, lineterminator="\n")
    columns = [_column_text(table[name]) for name in table.columns]
    with path.open("wb") as file:
        file.write(header.encode("utf-8"))
        digest.update(header.encode("utf-8"))
        for start in range(0, len(table), _CHUNK_ROWS):
            rows = zip(*(column[start : start + _CHUNK_ROWS] for column in columns))
            chunk = ("\n".join(map(",".join, rows)) + "\n").encode("utf-8")
            file.write(chunk)
            digest.update(chunk)
    return digest.hexdigest()
