"""The raw-data CSV of streamed series from the stored number text (bench.reports.rawdata_text): every token is the
repr pandas writes, a text that is not plainly ``json.dumps``' is refused, and a report's spool taken that way is
byte for byte the whole table's CSV, in a real store (with texts pandas quotes, and a sample that sends it back to
the store)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.reports.rawdata import StreamedSeries, write_table_csv
from bench.reports.rawdata_text import series_tokens
from bench.store import Store
from bench.store.export import series_table
from bench.store.records import to_json

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
series_keys = st.sampled_from(["t_s", "x_mm", "y_mm", "z_mm", 'odd "key"', "é_mm"])


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(series_keys, st.just(None), min_size=1), st.integers(0, 20), st.data())
def test_each_stored_float_is_the_text_pandas_writes(keys, length, data):
    series = {key: data.draw(st.lists(finite, min_size=length, max_size=length)) for key in keys}
    text = to_json({"reports": {"xy": [1, 2]}, "series": series, "t_request_s": 0.5}, "raw")
    decoded = json.loads(text)["series"]
    tokens = series_tokens(decoded, text)
    assert tokens is not None and list(tokens) == list(decoded)
    for key, values in decoded.items():
        expected = pd.DataFrame({"v": np.asarray(values, float), "w": 0}).to_csv(index=False, header=False)
        assert [line[:-2] for line in expected.splitlines()] == tokens[key]


@pytest.mark.parametrize(
    "raw, text",
    [
        ({"series": {"t_s": [0, 0.5]}}, None),  # an integer: pandas writes 0.0
        ({"series": {"t_s": [True, 0.5]}}, None),
        ({"series": {"t_s": [float("nan"), 0.5]}}, "allow_nan"),  # NaN: pandas writes nothing
        ({"notes": {"series": {"t_s": [1.0]}}, "series": {"t_s": [2.0]}}, None),  # a second "series" object
        ({'x"series': {"t_s": [1.0]}, "series": {"t_s": [2.0]}}, None),  # its text inside a key
        ({"series": {"t_s": [1.0, 2.0]}}, "compact"),  # not json.dumps' separators
        ({"series": {"t_s": [1.0, 2.0]}}, "1.00"),  # a number written another way
        ({"series": {"t_s": [[1.0, 2.0]], "x_mm": [2.0]}}, None),  # not a flat list of numbers
        ({"series": {"t_s": "1.0, 2.0"}}, None),
    ],
)
def test_a_text_not_plainly_json_dumps_is_not_taken(raw, text):
    if text == "allow_nan":
        stored = json.dumps(raw, sort_keys=True)
    elif text == "compact":
        stored = json.dumps(raw, sort_keys=True, separators=(",", ":"))
    elif text == "1.00":
        stored = to_json(raw, "raw").replace("1.0", "1.00")
    else:
        stored = json.dumps(raw, sort_keys=True)
    decoded = json.loads(stored)["series"]
    assert series_tokens(decoded, stored) is None


def _path_store(folder, samples) -> tuple[Store, int]:
    store = Store(folder / "s.db")
    run_id = store.start_run(protocol_name="iso9283_path", protocol_version="1", robot="pkm5", config={})
    for step, (pose, cycle, values, series) in enumerate(samples):
        store.add_sample(
            run_id,
            step,
            values=values,
            kind="path",
            pose=pose,
            cycle=cycle,
            t_s=float(step),
            raw={"reports": {"xy": {"dx_counts": [1, 0]}}, "series": series, "t_request_s": 0.25 * step},
        )
    return store, run_id


def _samples(rng, lengths, poses=("line", "circle")):
    return [
        (
            poses[i % len(poses)],
            1 + i // 2,
            {"cmd_x_mm": float(rng.normal()), "velocity_pct": 100.0, "load_kg": 0.0, "x_mm": 1.0},
            {
                "t_s": (np.arange(n) * 0.002 - 0.1).tolist(),
                "x_mm": np.round(rng.normal(100, 5, n), 4).tolist(),
                "y_mm": rng.normal(size=n).tolist(),
                "z_mm": [-0.0] * n,
            },
        )
        for i, n in enumerate(lengths)
    ]


def _spooled_bytes(store, run_id, folder, rows):
    raw = StreamedSeries(store, run_id, "path", rows=rows)
    passed = list(raw.passing_stored(store.iter_samples_text(run_id, kind="path")))
    digest, count = raw.write_csv(folder / "spooled.csv")
    return passed, raw._spooled is not None, digest, count, (folder / "spooled.csv").read_bytes()


@settings(max_examples=20, deadline=None)
@given(
    st.lists(st.integers(0, 40), min_size=1, max_size=10),
    st.integers(1, 60),
    st.sampled_from([("line", "circle"), ("a,b", 'say "x"'), ("P1",)]),
)
def test_the_spool_from_the_stored_text_is_the_whole_tables_csv(tmp_path_factory, lengths, rows, poses):
    folder = tmp_path_factory.mktemp("text")
    store, run_id = _path_store(folder, _samples(np.random.default_rng(len(lengths)), lengths, poses))
    with store:
        expected_digest = write_table_csv(series_table(store, run_id, kind="path"), folder / "whole.csv")
        passed, spooled, digest, count, written = _spooled_bytes(store, run_id, folder, rows)
    assert len(passed) == len(lengths) and spooled == (sum(lengths) > 0)
    assert (digest, count) == (expected_digest, sum(lengths))
    assert written == (folder / "whole.csv").read_bytes()


def test_a_sample_whose_text_cannot_be_taken_sends_the_csv_back_to_the_store(tmp_path):
    """An integer in a series (pandas writes 2.0): the spool is dropped, the CSV written from the store."""
    samples = _samples(np.random.default_rng(4), [5, 6, 7])
    samples[1][3]["t_s"][2] = 2  # stored as the integer 2
    store, run_id = _path_store(tmp_path, samples)
    with store:
        expected_digest = write_table_csv(series_table(store, run_id, kind="path"), tmp_path / "whole.csv")
        passed, spooled, digest, count, written = _spooled_bytes(store, run_id, tmp_path, rows=4)
    assert len(passed) == 3 and not spooled
    assert (digest, count) == (expected_digest, 18) and written == (tmp_path / "whole.csv").read_bytes()
    assert b",2.0\n" in written and b",2\n" not in written  # the integer as pandas writes it: 2.0
