"""Reading tidy CSV sample tables: every cell a string, or the named columns as float64 at once, every fault named.

`read_table_csv` parses a plain table (no quotes, no comment lines) with pandas' C reader straight from the file and
anything else row by row with the csv module, which names the row and column at fault; `numeric_columns` turns
columns into finite floats, naming the first cell that is not one. Re-exported by :mod:`bench.metrology.tables`.
"""

from __future__ import annotations

import codecs
import csv
import io
import re
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import pandas as pd

from bench.errors import ConfigError

__all__ = ["NotPlainTable", "numeric_columns", "read_table_chunks", "read_table_csv"]

#: pandas >= 3 copies a shared column before any write, so a converted table need not copy the whole frame
#: (a 10^7-row table: 640 MB and a second of copying saved per call).
_COPY_ON_WRITE = int(pd.__version__.split(".")[0]) >= 3


def read_table_csv(path: str | Path, *, numeric: Sequence[str] = ()) -> pd.DataFrame:
    """Read a CSV as strings (no type guessing); lines starting with ``#`` and blank lines are skipped.

    Data rows are numbered from 1 after the header, the numbering every error message uses. A missing file, an
    empty table, a repeated column name or a row with the wrong number of fields is a one-line ``ConfigError``.

    ``numeric``: columns to read as float64 at once (those present; the others stay strings), which is what
    :func:`numeric_columns` makes of them anyway: a table of 10^6 rows then never holds millions of strings. A file
    without quotes whose every line has the header's number of fields is parsed by pandas' C reader; anything else
    (quotes, blank lines, a bad row, a cell that is not a number) by the row-by-row reader below, which names the
    row and column at fault.
    """
    path = Path(path)
    try:
        frame = _read_regular_csv(path, numeric) if numeric else None
        if frame is None:
            return _read_csv_rows(path, path.read_bytes())
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: not a readable CSV table ({exc})") from None
    frame.attrs["source"] = str(path)
    return frame


#: Bytes read at a time by the scan that decides between the readers (a bound on its memory).
_SCAN_BYTES = 1 << 24
#: A comment line of a CSV table: optional blanks, then ``#`` (a ``#`` inside a cell is data).
_COMMENT_LINE = re.compile(rb"(?m)^[ \t]*#[^\n]*(?:\n|$)")


def _scan(path: Path) -> tuple[bool, bool, bool]:
    """Whether the file holds a ``"`` (quoting), a ``#`` (maybe comment lines) and a blank (space or tab: cells to
    strip; a file without one parses without pandas' slower ``skipinitialspace``), scanned a block at a time."""
    quotes = hashes = blanks = False
    with path.open("rb") as handle:
        while block := handle.read(_SCAN_BYTES):
            quotes, hashes = quotes or b'"' in block, hashes or b"#" in block
            blanks = blanks or b" " in block or b"\t" in block
            if quotes:
                break
    return quotes, hashes, blanks


def _read_regular_csv(path: Path, numeric: Sequence[str]) -> pd.DataFrame | None:
    """The fast path of `read_table_csv`: pandas' C reader, straight from the file (no copy of it in memory;
    a file with comment lines is read, stripped of them, and parsed from memory), or ``None`` when the file needs
    the row-by-row reader (quotes, a blank or odd header, a row with too many or too few fields, a cell that is not
    a number, bad bytes), which names the row and column at fault."""
    quotes, hashes, blanks = _scan(path)
    if quotes:
        return None
    source: Path | io.BytesIO = path
    if hashes:
        source = io.BytesIO(_COMMENT_LINE.sub(b"", path.read_bytes().removeprefix(codecs.BOM_UTF8)))
    with open(source, "rb") if isinstance(source, Path) else source as handle:
        header = _plain_header(handle)
        if header is None:
            return None
        try:
            with warnings.catch_warnings():  # pandas drops a first row's extra fields with a warning: refused
                warnings.simplefilter("error", pd.errors.ParserWarning)
                frame = _c_reader(handle, header, numeric, blanks=blanks)
        except _C_READER_FAULTS:
            return None  # a cell that is not a number, bad bytes, a row with too many fields
    if frame.empty or _has_missing_cells(frame):
        return None  # a short row (pandas fills it) or a "nan" cell: the row-by-row reader names it
    return frame


#: What pandas' C reader raises on a row it cannot take (the row-by-row reader then names it).
_C_READER_FAULTS = (ValueError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.ParserWarning)


def _plain_header(handle: BinaryIO) -> list[str] | None:
    """The column names of the header line (the handle left at the file's start), or None when they are not unique,
    non-empty names."""
    first = handle.readline().removeprefix(codecs.BOM_UTF8)
    handle.seek(0)
    try:
        header = [name.strip() for name in next(csv.reader([first.decode("utf-8")], skipinitialspace=True))]
    except (UnicodeDecodeError, StopIteration):
        return None
    return None if len(set(header)) != len(header) or "" in header else header


def _c_reader(
    handle: BinaryIO, header: list[str], numeric: Sequence[str], *, blanks: bool, chunk_rows: int | None = None
) -> Any:
    """pandas' C reader on ``handle``: ``numeric`` columns as float64, the others as strings, nothing read as NaN,
    blanks before a cell skipped when the file has any; the whole table, or a reader of ``chunk_rows`` rows at a
    time."""
    types: dict[str, Any] = {column: np.float64 for column in numeric if column in header}
    types.update({column: str for column in header if column not in types})
    return pd.read_csv(
        handle,
        header=0,
        names=header,
        dtype=types,
        keep_default_na=False,
        na_values=[],
        skipinitialspace=blanks,
        index_col=False,
        engine="c",
        encoding="utf-8",
        chunksize=chunk_rows,
    )


def _has_missing_cells(frame: pd.DataFrame) -> bool:
    return any(frame[column].isna().any() for column in frame.columns)


class NotPlainTable(Exception):
    """A chunk of a table read by :func:`read_table_chunks` that pandas' C reader cannot take: the caller reads the
    file whole, where the row-by-row reader names the row and column at fault."""


def read_table_chunks(path: str | Path, *, numeric: Sequence[str], chunk_rows: int) -> Iterator[pd.DataFrame] | None:
    """A plain table (no quotes, no ``#``) ``chunk_rows`` rows at a time, each chunk as :func:`read_table_csv` reads
    the rows (``numeric`` columns as float64, the index the row number - 1, ``attrs["source"]`` the path); None when
    the file is not plain. A chunk the C reader cannot take raises :class:`NotPlainTable`. Memory: one chunk."""
    path = Path(path)
    try:
        quotes, hashes, blanks = _scan(path)
        handle = path.open("rb")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: not a readable CSV table ({exc})") from None
    header = None if quotes or hashes else _plain_header(handle)
    if header is None:
        handle.close()
        return None
    return _chunks(handle, header, numeric, chunk_rows, str(path), blanks)


def _chunks(
    handle: BinaryIO, header: list[str], numeric: Sequence[str], chunk_rows: int, source: str, blanks: bool
) -> Iterator[pd.DataFrame]:
    with handle, warnings.catch_warnings():
        warnings.simplefilter("error", pd.errors.ParserWarning)
        try:
            for chunk in _c_reader(handle, header, numeric, blanks=blanks, chunk_rows=chunk_rows):
                if _has_missing_cells(chunk):
                    raise NotPlainTable(source)
                chunk.attrs["source"] = source
                yield chunk
        except _C_READER_FAULTS:
            raise NotPlainTable(source) from None


def _read_csv_rows(path: Path, data: bytes) -> pd.DataFrame:
    """`read_table_csv` row by row with the csv module: every cell a string, every fault named."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a readable CSV table ({exc})") from None
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    rows = list(csv.reader(lines, skipinitialspace=True))
    if not rows:
        raise ConfigError(f"{path}: not a readable CSV table (no header line)")
    header = [name.strip() for name in rows[0]]
    if len(set(header)) != len(header) or "" in header:
        raise ConfigError(f"{path}: header {', '.join(header)}: expected unique, non-empty column names")
    for number, row in enumerate(rows[1:], start=1):
        if len(row) != len(header):
            raise ConfigError(f"{path}: row {number}: {len(row)} fields, expected {len(header)} as in the header")
    frame = pd.DataFrame(rows[1:], columns=header, dtype=str)
    frame.attrs["source"] = str(path)
    return frame


def numeric_columns(frame: pd.DataFrame, columns: Sequence[str], *, required: bool = True) -> pd.DataFrame:
    """Convert ``columns`` to float, naming the line, column and value of the first cell that is not a number.

    Missing columns raise ``ConfigError`` when ``required``; otherwise they are skipped.
    """
    source = frame.attrs.get("source", "table")
    missing = [c for c in columns if c not in frame.columns]
    if missing and required:
        raise ConfigError(f"{source}: missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}")
    out = frame.copy(deep=not _COPY_ON_WRITE)  # a shallow copy shares no writes with ``frame`` under copy-on-write
    for column in (c for c in columns if c in frame.columns):
        if pd.api.types.is_float_dtype(frame[column]):  # read as numbers already (read_table_csv's numeric=)
            finite = np.isfinite(frame[column].to_numpy())
            if not finite.all():
                index = frame.index[int(np.argmin(finite))]
                raise ConfigError(
                    f"{source}: row {int(index) + 1}, column {column}: "
                    f"{str(frame.at[index, column])!r} is not a finite number"
                )
            continue
        text = frame[column].astype(str).str.strip()
        values = pd.to_numeric(text, errors="coerce")
        bad = values.isna() | ~np.isfinite(values.fillna(0.0))
        if bad.any():
            index = bad.idxmax()
            raise ConfigError(
                f"{source}: row {int(index) + 1}, column {column}: {frame.at[index, column]!r} is not a finite number"
            )
        out[column] = values.astype(float)
    return out
