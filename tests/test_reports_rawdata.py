"""The report's raw-data CSV is byte for byte what pandas writes (its fast writer formats each distinct value once),
and the streamed-series table built column by column equals the one built sample by sample."""

from __future__ import annotations

import hashlib
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.reports.rawdata import StreamedSeries, write_table_csv
from bench.store import export


def _pandas_bytes(table: pd.DataFrame, path) -> bytes:
    table.to_csv(path, index=False)
    return path.read_bytes()


def test_edge_values_are_written_as_pandas_writes_them(tmp_path):
    table = pd.DataFrame(
        {
            "pose": ["P1", "a,b", None, 'q"x', ""],
            "cycle": [1, 2, 3, 4, 5],
            "x_mm": [0.1, np.nan, -0.0, 1e-5, 1e17],
            "ok": [True, False, True, True, False],
            "v": [np.inf, -np.inf, 3.0, 2.5, 100.0],
            "z_mm": [0.0, -0.0, 0.0, -0.0, 1.0],
        }
    )
    expected = _pandas_bytes(table, tmp_path / "pandas.csv")
    digest = write_table_csv(table, tmp_path / "fast.csv")
    assert (tmp_path / "fast.csv").read_bytes() == expected
    assert digest == hashlib.sha256(expected).hexdigest()


def test_a_line_break_in_a_text_and_a_single_column_go_through_pandas(tmp_path):
    for table in (
        pd.DataFrame({"note": ["two\nlines", "x"], "x_mm": [1.0, 2.0]}),
        pd.DataFrame({"x_mm": [np.nan, 1.0]}),
    ):
        expected = _pandas_bytes(table, tmp_path / "pandas.csv")
        write_table_csv(table, tmp_path / "fast.csv")
        assert (tmp_path / "fast.csv").read_bytes() == expected


floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(["P1", "P2", "a,b", "", 'say "x"']), st.integers(-3, 10**12), floats, floats),
        min_size=0,
        max_size=40,
    )
)
def test_any_table_of_texts_integers_and_floats_is_written_as_pandas_writes_it(tmp_path_factory, rows):
    folder = tmp_path_factory.mktemp("csv")
    table = pd.DataFrame(rows, columns=["pose", "cycle", "x_mm", "t_s"]).astype(
        {"cycle": "int64", "x_mm": "float64", "t_s": "float64"}
    )
    expected = _pandas_bytes(table, folder / "pandas.csv")
    assert write_table_csv(table, folder / "fast.csv") == hashlib.sha256(expected).hexdigest()
    assert (folder / "fast.csv").read_bytes() == expected


def _sample(step: int, pose, cycle, values: dict, series: dict):
    return SimpleNamespace(
        step_index=step, pose=pose, cycle=cycle, values=values, raw={"series": series, "t_request_s": 0.0}
    )


class _Store:
    def __init__(self, samples):
        self._samples = samples

    def run(self, run_id):
        return None

    def samples(self, run_id, kind=None):
        return self._samples


def test_the_series_table_column_by_column_equals_the_one_sample_by_sample():
    rng = np.random.default_rng(1)
    samples = [
        _sample(
            i,
            f"P{1 + i % 3}",
            1 + i // 3,
            {"cmd_x_mm": 10.0 * i, "velocity_pct": 50.0, "load_kg": 0.0, "x_mm": 1.0},
            {"t_s": list(np.arange(n) * 0.01), "x_mm": list(rng.normal(size=n)), "y_mm": [0.5] * n},
        )
        for i, n in enumerate((3, 7, 1, 5, 4, 6))
    ]
    fast = export.series_table(_Store(samples), 1, kind="path")
    by_sample = pd.concat(
        [
            pd.DataFrame(
                {
                    "pose": s.pose,
                    "cycle": s.cycle,
                    "cmd_x_mm": s.values["cmd_x_mm"],
                    "velocity_pct": 50.0,
                    "load_kg": 0.0,
                    **s.raw["series"],
                }
            )
            for s in samples
        ],
        ignore_index=True,
    )[["pose", "cycle", "cmd_x_mm", "x_mm", "y_mm", "velocity_pct", "load_kg", "t_s"]]
    pd.testing.assert_frame_equal(fast, by_sample, check_exact=True)
    assert len(fast) == 26


def test_samples_with_different_series_columns_are_aligned_with_missing_values():
    samples = [
        _sample(0, "P1", 1, {}, {"t_s": [0.0, 0.1], "x_mm": [1.0, 2.0]}),
        _sample(1, "P1", 2, {}, {"t_s": [0.0], "x_mm": [3.0], "y_mm": [4.0]}),
    ]
    table = export.series_table(_Store(samples), 1, kind="path")
    assert table["y_mm"].isna().tolist() == [True, True, False]
    assert table["x_mm"].tolist() == pytest.approx([1.0, 2.0, 3.0])


def _path_samples(rng, lengths, extra_every: int = 0):
    """Streamed samples of varying lengths; every ``extra_every``-th one (0: none) has a y_mm series column more."""
    return [
        _sample(
            i,
            f"P{1 + i % 2}",
            1 + i // 2,
            {"cmd_x_mm": float(i), "velocity_pct": 100.0},
            {
                "t_s": list(np.arange(n) * 0.01),
                "x_mm": list(rng.normal(size=n)),
                **({"y_mm": [0.5] * n} if extra_every and i % extra_every == extra_every - 1 else {}),
            },
        )
        for i, n in enumerate(lengths)
    ]


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.integers(1, 9), min_size=1, max_size=12),
    st.integers(1, 30),
    st.sampled_from([0, 1, 2, 5]),
    st.booleans(),
)
def test_the_raw_data_written_a_piece_at_a_time_is_the_whole_tables_bytes(
    tmp_path_factory, lengths, rows, extra_every, spooled
):
    folder = tmp_path_factory.mktemp("pieces")
    store = _Store(_path_samples(np.random.default_rng(len(lengths)), lengths, extra_every))
    expected = write_table_csv(export.series_table(store, 1, kind="path"), folder / "whole.csv")
    raw = StreamedSeries(store, 1, "path", rows=rows)
    if spooled:  # as a report: the CSV spooled while the analysis reads the samples
        assert len(list(raw.passing(store.samples(1)))) == len(lengths)
    assert raw.write_csv(folder / "pieces.csv") == (expected, sum(lengths))
    assert (folder / "pieces.csv").read_bytes() == (folder / "whole.csv").read_bytes()
    if extra_every not in (0, 1) and len(lengths) >= extra_every:  # mixed columns: aligned over the whole run
        with pytest.raises(export.MixedSeries):
            list(export.series_chunks(store, 1, "path", rows=rows))
