"""The raw-data CSV beside a report, written in one vectorised pass and hashed as it is written.

``DataFrame.to_csv`` formats every cell through ``ndarray.astype(str)`` chunk by chunk: 33 s for the 2.3 million
streamed points of a long path run (12 columns), where 8 of the columns repeat one value per stored sample. Here each
column is factorised, only its distinct values are formatted (by pandas itself, so quoting and the text of every value
are pandas'), and the rows are joined from those strings: the same bytes as ``table.to_csv(path, index=False)`` (a test
compares them), in a few seconds. A long run's streamed series, read from the store with their JSON text, are
written from that text instead (:mod:`bench.reports.rawdata_text`: no float formatted again; the same bytes). The
decision to keep writing the file (and not only cite the store): the report's "recompute" line reads it, and a
customer gets the data the numbers came from without access to the bench's store; ``bench export`` writes the same
table on demand.
"""

from __future__ import annotations

import hashlib
import shutil
import tempfile
from collections.abc import Callable, Generator, Iterable, Iterator
from pathlib import Path
from typing import BinaryIO

import pandas as pd

from bench.reports.rawdata_child import CsvInChild, worth_a_process
from bench.reports.rawdata_format import column_text, plain_table
from bench.reports.rawdata_text import SeriesText, TextNotTaken
from bench.store import SampleRecord, Store
from bench.store.export import MixedSeries, SeriesPieces, series_chunks, series_table

__all__ = ["CsvPieces", "StreamedSeries", "write_table_csv", "write_tables_csv"]

#: Rows joined and written per chunk (bounds the memory of the row strings: about 100 bytes a row).
_CHUNK_ROWS = 200_000
#: Rows of a long run's raw data formatted at a time (:class:`StreamedSeries`): each distinct float's text is held
#: for its piece (about 70 bytes a value, 4 such columns of a path run), so 50,000 rows hold about 15 MB.
PIECE_ROWS = 50_000


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

    def put_text(self, text: str, rows: int, *, header: Callable[[], str]) -> None:
        """Write ``rows`` rows' CSV ``text`` (after the ``header()`` line when they are the first)."""
        if self.rows == 0:
            self._put(header())
        self.rows += rows
        self._put(text)

    def put(self, table: pd.DataFrame) -> None:
        first, self.rows = self.rows == 0, self.rows + len(table)
        if not plain_table(table):  # to_csv quotes and formats value by value: a piece at a time is the same text
            self._put(table.to_csv(index=False, header=first))
            return
        if first:
            self._put(table.head(0).to_csv(index=False, lineterminator="\n"))
        columns = [column_text(table[name]) for name in table.columns]
        for start in range(0, len(table), _CHUNK_ROWS):
            self._put(
                "\n".join(map(",".join, zip(*(column[start : start + _CHUNK_ROWS] for column in columns)))) + "\n"
            )


def _spooling(
    stored: Iterable[tuple[SampleRecord, str | None]], file: BinaryIO, rows: int
) -> Generator[SampleRecord, None, CsvPieces | None]:
    """Yield each of ``stored`` (samples with their raw JSON as stored, or None) as it comes while writing their
    series' CSV to ``file`` a piece of ``rows`` rows at a time; returns the writer (digest, rows), None when the
    series cannot be written so (:class:`MixedSeries`, :class:`TextNotTaken`: the caller writes it from the store)."""
    writer, frames, texts, good = CsvPieces(file), SeriesPieces(rows), SeriesText(rows), True
    by_text: bool | None = None  # chosen by the first sample with a series: whether its text came with it

    def put(piece: pd.DataFrame | tuple[str, int] | None) -> None:
        if isinstance(piece, tuple):
            writer.put_text(*piece, header=texts.header)
        elif piece is not None:
            writer.put(piece)

    for sample, raw_json in stored:
        if good:
            try:
                if by_text is None and isinstance(sample.raw, dict) and sample.raw.get("series"):
                    by_text = raw_json is not None
                if by_text is not None:
                    put(texts.add(sample, raw_json) if by_text else frames.add(sample))
            except (MixedSeries, TextNotTaken):  # written from the store when asked (write_csv)
                good = False
        yield sample
    try:
        if good and by_text is not None:
            put(texts.rest() if by_text else frames.rest())
    except (MixedSeries, TextNotTaken):
        good = False
    return writer if good else None


class StreamedSeries:
    """A report's raw data too long to hold (a path run's millions of streamed points): the run's streamed series
    of ``kind`` (``bench export RUN --kind KIND --series``), never held whole. Written as the samples pass by for the
    analysis (:meth:`passing`: the run read once) to an anonymous temporary file, or else from the open store
    (:func:`bench.store.export.series_chunks`), a piece of ``rows`` rows at a time; a long run's, while the machine
    is not busy, by a second process reading the store beside the analysis (:mod:`bench.reports.rawdata_child`)."""

    def __init__(
        self, store: Store, run_id: int, kind: str, rows: int = PIECE_ROWS, *, in_child: bool | None = None
    ) -> None:
        self.store, self.run_id, self.kind, self.rows = store, run_id, kind, rows
        self._spooled: tuple[BinaryIO, CsvPieces] | None = None
        #: the samples that passed by for the analysis (None: none passed): the writer process must read as many
        self.passed: int | None = None
        #: the writer process of a long run's CSV, running beside the analysis (None: written here, spooled);
        #: ``in_child`` None chooses by the run's length (:func:`bench.reports.rawdata_child.worth_a_process`)
        self.child: CsvInChild | None = None
        if in_child or (in_child is None and worth_a_process(store, run_id, kind)):
            self.child = CsvInChild(store.path, run_id, kind, rows)

    def passing(self, samples: Iterable[SampleRecord]) -> Iterator[SampleRecord]:
        """``samples``, each as it comes, their CSV spooled on the way (kept when every one has passed)."""
        return self.passing_stored((sample, None) for sample in samples)

    def passing_stored(self, stored: Iterable[tuple[SampleRecord, str | None]]) -> Iterator[SampleRecord]:
        """:meth:`passing` of samples given with their raw JSON as stored (``Store.iter_samples_text``; None where
        the store has no text to give): the series' CSV text taken from it (:mod:`bench.reports.rawdata_text`),
        not formatted again. With a writer process (:attr:`child`) the samples only pass: it writes the CSV."""
        if self.child is not None:
            self.passed = 0
            for self.passed, (sample, _) in enumerate(stored, start=1):
                yield sample
            return
        spool = tempfile.TemporaryFile()
        writer = yield from _spooling(stored, spool, self.rows)
        if writer is not None and writer.rows:
            self._spooled = (spool, writer)
        else:
            spool.close()

    def write_from_store(self, path: str | Path) -> tuple[str, int, int]:
        """Read the run from the store once and write its CSV at ``path`` (what the writer process does,
        :mod:`bench.reports.rawdata_child`); returns the SHA-256, the rows and the samples read."""
        with Path(path).open("wb") as file:
            spooling = _spooling(self.store.iter_samples_text(self.run_id, kind=self.kind), file, self.rows)
            samples = 0
            try:
                while True:
                    next(spooling)
                    samples += 1
            except StopIteration as done:
                writer = done.value
        if writer is not None and writer.rows:
            return writer.digest.hexdigest(), writer.rows, samples
        return (*self._write_chunks(path), samples)

    def write_csv(self, path: str | Path) -> tuple[str, int]:
        """Write the table as :func:`write_table_csv` writes it whole; returns the SHA-256 and the rows."""
        if self._spooled is not None:
            spool, writer = self._spooled
            spool.seek(0)
            with Path(path).open("wb") as file:
                shutil.copyfileobj(spool, file)
            return writer.digest.hexdigest(), writer.rows
        if self.child is not None:
            return self.child.join(path, self.passed)
        return self._write_chunks(path)

    def _write_chunks(self, path: str | Path) -> tuple[str, int]:
        """The table from the open store, a piece at a time (samples whose text was not taken)."""
        try:
            return write_tables_csv(series_chunks(self.store, self.run_id, self.kind, self.rows), path)
        except MixedSeries:  # samples that differ in their columns: aligned over the whole run, as export does
            return write_tables_csv([series_table(self.store, self.run_id, self.kind)], path)
