"""Large pose tables: the fast CSV path (pandas' C reader, numbers read as numbers) means the same as the row-by-row
reader, and U(RP) by the delta method agrees with the bootstrap above MODEL_MAX_CYCLES cycles."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, InsufficientData
from bench.metrology import uncertainty
from bench.metrology.tables import POSE_NUMERIC_COLUMNS, analyze_poses, pose_result_json, pose_table, read_table_csv
from bench.metrology.uncertainty import (
    MODEL_MAX_CYCLES,
    repeatability_uncertainty,
    repeatability_uncertainty_delta,
)

HEADER = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm"
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "data" / "iso9283_example.csv"


def both_readers(path: Path):
    """(row-by-row result or error, fast-path result or error) of ``pose_table(read_table_csv(path))``."""
    outcomes = []
    for numeric in ((), POSE_NUMERIC_COLUMNS):
        try:
            outcomes.append(pose_table(read_table_csv(path, numeric=numeric)))
        except ConfigError as exc:
            outcomes.append(str(exc))
    return outcomes


def test_the_example_table_gives_the_same_figures_through_both_readers():
    slow, fast = both_readers(EXAMPLE)
    assert fast["x_mm"].dtype == np.float64
    pd.testing.assert_frame_equal(slow, fast, check_dtype=False)
    assert [pose_result_json(r) for r in analyze_poses(slow)] == [pose_result_json(r) for r in analyze_poses(fast)]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,2,0,0,0,0,abc,0\nP1,3,0,0,0,0,0,0\n",
            "row 2, column y_mm: 'abc' is not a finite number",
        ),
        (f"{HEADER}\nP1,1,0,0,0,0,0,\n", "row 1, column z_mm: '' is not a finite number"),
        (f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,2,0,0,0,0,0\n", "row 2: 7 fields, expected 8 as in the header"),
        (f"{HEADER}\nP1,1,0,0,0,0,0,0,9\n", "row 1: 9 fields, expected 8 as in the header"),
        ("pose,cycle,x_mm,x_mm\nP1,1,0,0\n", "expected unique, non-empty column names"),
        (f"{HEADER}\nP1,1,0,0,0,0,0,inf\n", "row 1, column z_mm: 'inf' is not a finite number"),
    ],
)
def test_a_bad_table_gets_the_same_one_line_error_through_both_readers(tmp_path, text, message):
    path = tmp_path / "samples.csv"
    path.write_text(text)
    slow, fast = both_readers(path)
    assert isinstance(slow, str) and message in slow
    assert fast == slow


def test_comments_blank_lines_spaces_quotes_and_a_bom_read_alike(tmp_path):
    path = tmp_path / "samples.csv"
    path.write_bytes(
        (
            "\ufeff# exported by hand\n" + HEADER.replace(",", ", ") + "\n"
            "P#1, 1, 100, 0, 300, 100.1, 0.2, 299.9\n  # a comment after blanks\n"
            'P#1, 2, 100, 0, 300, 100.3, -0.1, 300.2\n\n"P2",1,90,5,310,90.1,5,310\n'
            "P2,2,90,5,310,89.8,5.1,310.1\nP#1,3,100,0,300,99.9,0.0,300.1\n"
        ).encode("utf-8")
    )
    slow, fast = both_readers(path)
    pd.testing.assert_frame_equal(slow, fast, check_dtype=False)
    assert list(slow["pose"]) == ["P#1", "P#1", "P2", "P2", "P#1"]
    no_quotes = tmp_path / "plain.csv"  # the same without quotes or blank lines: the fast path itself
    no_quotes.write_text("# exported\n" + HEADER + "\nP#1,1,100,0,300,100.1,0.2,299.9\nP2,1,90,5,310,90.1,5,310\n")
    fast = read_table_csv(no_quotes, numeric=POSE_NUMERIC_COLUMNS)
    assert fast["x_mm"].dtype == np.float64 and list(fast["pose"]) == ["P#1", "P2"]
    assert fast.attrs["source"] == str(no_quotes)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(["P1", "P2", "01", "1.50"]), st.floats(-500, 500, width=32)), min_size=3, max_size=12
    )
)
def test_random_tables_mean_the_same_through_both_readers(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("t") / "samples.csv"
    lines = [f"{pose},{i},1,2,3,{x!r},{x / 2!r},0.5" for i, (pose, x) in enumerate(rows, start=1)]
    path.write_text("\n".join([HEADER, *lines]) + "\n")
    slow, fast = both_readers(path)
    pd.testing.assert_frame_equal(slow, fast, check_dtype=False)  # labels such as "01" stay strings


def test_the_delta_method_agrees_with_the_bootstrap_for_many_cycles():
    rng = np.random.default_rng(5)
    anisotropic = rng.normal(size=(2000, 3)) * [0.3, 0.1, 0.05]
    skewed = np.c_[rng.exponential(0.2, 2000), rng.normal(0, 0.1, 2000), rng.gamma(2, 0.05, 2000)]
    for cloud in (anisotropic, skewed):
        bootstrap = repeatability_uncertainty(cloud, resamples=4000, method="bootstrap")
        # 4000 resamples: the bootstrap SD itself is uncertain by 1/sqrt(2 x 3999) = 1.1 %
        assert repeatability_uncertainty_delta(cloud) == pytest.approx(bootstrap, rel=0.04)


def test_the_delta_method_counts_the_barycentre_and_the_skew():
    # Without the barycentre and covariance terms the skewed cloud's U would be the plain l-bar + 3 S formula's.
    rng = np.random.default_rng(6)
    cloud = np.c_[rng.exponential(0.2, 3000), rng.normal(0, 0.1, 3000)]
    l = np.linalg.norm(cloud - cloud.mean(axis=0), axis=1)
    d = l - l.mean()
    s = l.std(ddof=1)
    naive = np.sqrt(np.sum((d + 1.5 / s * (d**2 - s**2)) ** 2)) / len(l)
    full = repeatability_uncertainty_delta(cloud)
    assert abs(full / naive - 1) > 0.02
    assert full == pytest.approx(repeatability_uncertainty(cloud, resamples=4000, method="bootstrap"), rel=0.04)


def test_auto_uses_the_measurement_model_up_to_the_limit_and_the_delta_method_above():
    rng = np.random.default_rng(7)
    small, large = rng.normal(size=(MODEL_MAX_CYCLES, 3)), rng.normal(size=(MODEL_MAX_CYCLES + 1, 3))
    assert repeatability_uncertainty(small) == repeatability_uncertainty(small, method="model")
    assert repeatability_uncertainty(large) == repeatability_uncertainty_delta(large)


def test_the_chunked_bootstrap_draws_what_one_batch_would(monkeypatch):
    cloud = np.random.default_rng(8).normal(size=(31, 3))
    whole = repeatability_uncertainty(cloud, resamples=500, seed=3, method="bootstrap")
    monkeypatch.setattr(uncertainty, "_BOOTSTRAP_CHUNK_CYCLES", 31 * 7)  # chunks of 7 resamples
    assert repeatability_uncertainty(cloud, resamples=500, seed=3, method="bootstrap") == whole


def test_bad_method_and_too_few_cycles_are_refused():
    with pytest.raises(ConfigError, match="method = 'jackknife', expected 'auto', 'bootstrap', 'delta' or 'model'"):
        repeatability_uncertainty(np.zeros((5, 3)), method="jackknife")
    with pytest.raises(InsufficientData, match="2 sample"):
        repeatability_uncertainty_delta(np.zeros((2, 3)))
