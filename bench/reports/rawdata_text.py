"""A long run's streamed series as CSV rows from the number text already stored: no number formatted again.

Formatting a float as text (its shortest repr, what ``to_csv`` writes) costs about 0.4 µs in CPython: 1.6 s for
the 4 series columns of a million streamed points, about as long as reading them. The store holds each sample's raw data
as ``json.dumps`` wrote it (``sort_keys``, ``", "`` between items, no NaN), and ``json.dumps`` writes a float as
that same repr, so each series column's CSV text is its JSON array's text split at ``", "``. A sample's series is
taken that way only when its text is plainly ``json.dumps``' (:func:`series_tokens`: one ``"series"`` object, keys
in order, as many tokens as values, every value a finite float, the first and last tokens the values' repr);
otherwise :meth:`SeriesText.add` says so and the caller writes the table as pandas does
(:mod:`bench.reports.rawdata`). The context columns (pose, cycle, commanded values) are formatted by pandas,
once per sample. The bytes equal :func:`bench.reports.rawdata.write_table_csv` of the whole table
(``tests/test_reports_rawdata_text.py``).
"""

from __future__ import annotations

import json
from functools import lru_cache
from itertools import chain, repeat
from typing import Any

import pandas as pd

from bench.reports.rawdata_format import column_text, plain_table
from bench.store import SampleRecord
from bench.store.export import MixedSeries, ordered_columns, series_context, series_contexts

__all__ = ["SeriesText", "TextNotTaken", "series_tokens"]

_SERIES_OBJECT = '"series": {'


@lru_cache(maxsize=256)
def _head(key: str, first: bool) -> str:
    """The text ``json.dumps`` writes before a series column's values."""
    return ("" if first else ", ") + json.dumps(key) + ": ["


def series_tokens(series: dict[str, Any], raw_json: str) -> dict[str, list[str]] | None:
    """Each series column's values as the text ``raw_json`` holds them (``repr`` of each float), None unless that
    text is plainly ``json.dumps``' of ``series``, the decoded ``raw["series"]`` (module docstring)."""
    if raw_json.count(_SERIES_OBJECT) != 1:
        return None
    position = raw_json.index(_SERIES_OBJECT) + len(_SERIES_OBJECT)
    tokens: dict[str, list[str]] = {}
    for number, (key, values) in enumerate(series.items()):
        head = _head(key, number == 0)
        if not isinstance(values, list) or not raw_json.startswith(head, position):
            return None
        start = position + len(head)
        end = raw_json.find("]", start)
        text = raw_json[start:end]
        if end < 0 or (values and set(map(type, values)) != {float}):
            return None  # true, false and null are not floats; NaN and Infinity are, and are refused just below
        if "N" in text or "I" in text:
            return None
        items = text.split(", ") if text else []
        if len(items) != len(values):
            return None
        if values and (items[0] != repr(values[0]) or items[-1] != repr(values[-1])):
            return None
        tokens[key] = items
        position = end + 1
    return tokens if raw_json.startswith("}", position) else None


def _context_texts(contexts: pd.DataFrame) -> list[dict[str, str]]:
    """Per sample, each context column's text as ``to_csv`` writes it (one ``to_csv`` of the piece's contexts, cut at
    its commas where no field is quoted; else column by column, :func:`column_text`)."""
    text = contexts.to_csv(index=False, header=False, lineterminator="\n")
    names = list(contexts.columns)
    if '"' not in text:
        return [dict(zip(names, line.split(","))) for line in text.split("\n")[:-1]]
    columns = [column_text(contexts[name]) for name in names]
    return [dict(zip(names, cells)) for cells in zip(*columns)]


class TextNotTaken(Exception):
    """A sample whose stored text cannot be taken as the CSV's (:func:`series_tokens`), or a piece that pandas
    writes otherwise (a text with a line break): the table is written as :mod:`bench.reports.rawdata` writes it."""


class SeriesText:
    """The CSV text of a run's streamed series, a piece of about ``rows`` rows at a time: samples given with their
    stored raw JSON (:meth:`add`), each piece's text returned when it is full (and by :meth:`rest`)."""

    def __init__(self, rows: int) -> None:
        self.rows = rows
        self._waiting: list[tuple[dict[str, Any], dict[str, list[str]]]] = []
        self._count = 0
        self._keys: tuple[list[str], list[str]] | None = None  # the context's keys, the series'
        self._dtypes: pd.Series | None = None  # the first piece's, as the whole table's pieces must all have

    def add(self, sample: SampleRecord, raw_json: str | None) -> tuple[str, int] | None:
        """Take ``sample`` (with its stored ``raw_json``): a full piece's (text, rows), else None. Raises
        TextNotTaken (its text cannot be taken), MixedSeries (the whole table would align the samples)."""
        context = series_context(sample)
        if context is None:
            return None
        series = sample.raw["series"]
        tokens = None if raw_json is None else series_tokens(series, raw_json)
        keys = (list(context), list(series))
        if tokens is None or (self._keys is not None and keys != self._keys) or set(keys[0]) & set(keys[1]):
            raise TextNotTaken(f"sample at step {sample.step_index}: its series text is not json.dumps' plainly")
        if len({len(values) for values in tokens.values()}) != 1:
            raise MixedSeries(f"sample at step {sample.step_index}: series of different lengths")
        self._keys = keys
        self._waiting.append((context, tokens))
        self._count += len(next(iter(tokens.values())))
        return self.rest() if self._count >= self.rows else None

    def header(self) -> str:
        """The CSV's first line (after a first piece)."""
        assert self._keys is not None
        return pd.DataFrame(columns=ordered_columns(chain(*self._keys))).to_csv(index=False, lineterminator="\n")

    def rest(self) -> tuple[str, int] | None:
        """The piece of the samples taken since the last one as (CSV text, rows), None without any."""
        if not self._waiting:
            return None
        assert self._keys is not None
        contexts = series_contexts([context for context, _ in self._waiting])
        if contexts is None:
            raise MixedSeries("samples with different context columns or types")
        order = ordered_columns(chain(*self._keys))
        floats = pd.Series([0.0]).dtype  # every series column's (series_tokens took only floats)
        dtypes = pd.concat([contexts.dtypes, pd.Series({key: floats for key in self._keys[1]})])[order]
        if self._dtypes is None:
            self._dtypes = dtypes
        elif not dtypes.equals(self._dtypes):
            raise MixedSeries("pieces with different columns or dtypes")
        if not plain_table(contexts):
            raise TextNotTaken("a text with a line break, or a column of another type: pandas writes it")
        texts = _context_texts(contexts)
        out = []
        for number, (_, tokens) in enumerate(self._waiting):
            count = len(next(iter(tokens.values())))
            streams: list[Any] = []
            pending = ""  # the constant text before the next series field
            for position, name in enumerate(order):
                separator = "," if position else ""
                if name in tokens:
                    streams += [repeat(pending + separator, count), tokens[name]]
                    pending = ""
                else:
                    pending += separator + texts[number][name]
            streams.append(repeat(pending + "\n", count))
            out.append("".join(chain.from_iterable(zip(*streams))))
        piece = "".join(out), self._count
        self._waiting, self._count = [], 0
        return piece
