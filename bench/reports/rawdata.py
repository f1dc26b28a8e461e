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
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np
import pandas as pd

from bench.store import SampleRecord, Store
from bench.store.export import MixedSeries, SeriesPieces, series_chunks, series_table

__all__ = ["CsvPieces", "StreamedSeries", "write_table_csv", "write_tables_csv"]

#: Rows joined and written per chunk (bounds the memory of the row strings: about 100 bytes a row).
_CHUNK_ROWS = 200_000
#: Rows of a long run's raw data formatted at a time (:class:`StreamedSeries`): each distinct float's text is held
#: for its piece (about 70 bytes a value, 4 such columns of a path run), so 50,000 rows hold about 15 MB.
PIECE_ROWS = 50_000


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
    return write_tables_csv([table], path)[0]


def write_tables_csv(tables: Iterable[pd.DataFrame], path: str | Path) -> tuple[str, int]:
    """Write the rows of ``tables`` (pieces of one table: the same columns), in order, as that table's
    ``to_csv(path, index=False)`` would, a piece at a time; returns the file's SHA-256 and its rows."""
    with Path(path).open("wb") as file:
        writer = CsvPieces(file)
        for table in tables:
            writer.put(table)
    return writer.digest.hexdigest(), writer.rows


class CsvPieces:
    """One table's CSV written to ``file`` a piece at a time, as ``to_csv(index=False)`` of the whole table would
    write it, hashed as it is written (``digest``, ``rows``)."""

    def __init__(self, file: BinaryIO) -> None:
        self.file = file
        self.digest = hashlib.sha256()
        self.rows = 0

    def _put(self, text: str) -> None:
        data = text.encode("utf-8")
        self.file.write(data)
        self.digest.update(data)

    def put(self, table: pd.DataFrame) -> None:
        first, self.rows = self.rows == 0, self.rows + len(table)
        if not _plain(table):  # to_csv quotes and formats value by value: a piece at a time is the same text
            self._put(table.to_csv(index=False, header=first))
            return
        if first:
            self._put(table.head(0).to_csv(index=False, lineterminator="\n"))
        columns = [_column_text(table[name]) for name in table.columns]
        for start in range(0, len(table), _CHUNK_ROWS):
            self._put(
                "\n".join(map(",".join, zip(*(column[start : start + _CHUNK_ROWS] for column in columns)))) + "\n"
            )


class StreamedSeries:
    """A report's raw data too long to hold (a path run's millions of streamed points): the run's streamed series
    of ``kind`` (``bench export RUN --kind KIND --series``), never held whole. Written as the samples pass by for the
    analysis (:meth:`passing`: the run read once) to an anonymous temporary file, or else from the open store
    (:func:`bench.store.export.series_chunks`), a piece of ``rows`` rows at a time."""

    def __init__(self, store: Store, run_id: int, kind: str, rows: int = PIECE_ROWS) -> None:
        self.store, self.run_id, self.kind, self.rows = store, run_id, kind, rows
        self._spooled: tuple[BinaryIO, CsvPieces] | None = None

    def passing(self, samples: Iterable[SampleRecord]) -> Iterator[SampleRecord]:
        """``samples``, each as it comes, their CSV spooled on the way (kept when every one has passed)."""
        spool = tempfile.TemporaryFile()
        writer, pieces, good = CsvPieces(spool), SeriesPieces(self.rows), True
        for sample in samples:
            if good:
                try:
                    piece = pieces.add(sample)
                    if piece is not None:
                        writer.put(piece)
                except MixedSeries:  # aligned over the whole run when written (write_csv)
                    good = False
            yield sample
        try:
            last = pieces.rest() if good else None
        except MixedSeries:
            good = False
        if good and last is not None:
            writer.put(last)
        if good and writer.rows:
            self._spooled = (spool, writer)
        else:
            spool.close()

    def write_csv(self, path: str | Path) -> tuple[str, int]:
        """Write the table as :func:`write_table_csv` writes it whole; returns the SHA-256 and the rows."""
        if self._spooled is not None:
            spool, writer = self._spooled
            spool.seek(0)
            with Path(path).open("wb") as file:
                shutil.copyfileobj(spool, file)
            return writer.digest.hexdigest(), writer.rows
        try:
            return write_tables_csv(series_chunks(self.store, self.run_id, self.kind, self.rows), path)
        except MixedSeries:  # samples that differ in their columns: aligned over the whole run, as export does
            return write_tables_csv([series_table(self.store, self.run_id, self.kind)], path)
