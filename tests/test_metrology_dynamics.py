"""Drift, stabilisation time, overshoot and path AT/RT: hand-built series with known answers."""

import numpy as np
import pytest

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    path_characteristics,
    pose_accuracy,
    pose_drift,
    pose_repeatability,
    position_stabilisation,
)


def test_drift_matches_per_window_reference():
    rng = np.random.default_rng(7)
    t = np.arange(600.0)
    warm_up = 0.001 * t[:, None] * [1.0, 0.0, 0.0]  # x drifts 0.6 mm over the test
    attained = 100.0 + warm_up + rng.normal(0, 0.02, (600, 3))
    result = pose_drift(t, attained, [100, 100, 100], window_s=200)
    windows = [slice(0, 200), slice(200, 400), slice(400, 600)]
    ap = [pose_accuracy(attained[w], [100, 100, 100]).ap_mm for w in windows]
    rp = [pose_repeatability(attained[w]).rp_mm for w in windows]
    assert result.ap_mm == pytest.approx(ap)
    assert result.rp_mm == pytest.approx(rp)
    assert result.dap_mm == pytest.approx(abs(ap[0] - ap[2]))
    assert result.drp_mm == pytest.approx(abs(rp[0] - rp[2]))
    assert result.n_per_window.tolist() == [200, 200, 200]
    assert result.window_start_s.tolist() == [0.0, 200.0, 400.0]


def test_drift_is_independent_of_row_order():
    rng = np.random.default_rng(3)
    t = rng.uniform(0, 100, 50)
    attained = rng.normal(0, 1, (50, 3))
    order = rng.permutation(50)
    a = pose_drift(t, attained, [0, 0, 0], window_s=30)
    b = pose_drift(t[order], attained[order], [0, 0, 0], window_s=30)
    assert a.dap_mm == pytest.approx(b.dap_mm) and a.drp_mm == pytest.approx(b.drp_mm)


def test_drift_refuses_a_window_with_one_sample():
    with pytest.raises(InsufficientData, match=r"drift window starting at t = 10 s: 1 sample\(s\), at least 2"):
        pose_drift([0, 1, 10], [[0, 0, 0], [0, 0, 1], [0, 0, 2]], [0, 0, 0], window_s=5)


def test_drift_needs_two_windows():
    with pytest.raises(InsufficientData, match="drift windows: 1 sample"):
        pose_drift([0, 1], [[0, 0, 0], [0, 0, 1]], [0, 0, 0], window_s=5)


def test_stabilisation_and_overshoot_hand_built():
    # Approach 1 mm away, cross into the 0.1 mm band at t = 2, overshoot to 0.3 mm at t = 3, settle from t = 5.
    t = np.arange(8.0)
    x = np.array([1.0, 0.5, 0.05, -0.3, 0.15, 0.05, 0.01, 0.0])
    result = position_stabilisation(t, x[:, None], band_mm=0.1)
    assert result.first_entry_s == 2.0
    assert result.settled_s == 5.0
    assert result.stabilisation_time_s == 3.0
    assert result.overshoot_mm == pytest.approx(0.3)


def test_no_overshoot_when_staying_inside_band():
    result = position_stabilisation([0, 1, 2, 3], [[1.0], [0.08], [0.02], [0.0]], band_mm=0.1)
    assert result.stabilisation_time_s == 0.0
    assert result.overshoot_mm == 0.0


def test_stabilisation_never_in_band_raises():
    with pytest.raises(InsufficientData, match="never enters the 0.1 mm band"):
        position_stabilisation([0, 1], [[1.0], [0.5]], band_mm=0.1, final_mm=[0.0])


def test_stabilisation_refuses_unordered_times():
    with pytest.raises(ConfigError, match="strictly increasing"):
        position_stabilisation([0, 2, 1], [[1.0], [0.5], [0.0]], band_mm=0.1)


def test_path_accuracy_and_repeatability_on_offset_lines():
    # Commanded straight line along x; cycles offset in y by +0.1, +0.3, +0.2 mm, sampled coarsely.
    stations = np.column_stack([np.linspace(0, 100, 11), np.zeros(11), np.zeros(11)])
    samples = np.linspace(-5, 105, 23)
    paths = [np.column_stack([samples, np.full(23, dy), np.zeros(23)]) for dy in (0.1, 0.3, 0.2)]
    result = path_characteristics(paths, stations)
    assert result.at_mm == pytest.approx(0.2)
    distances = np.array([0.1, 0.1, 0.0])
    assert result.rt_mm == pytest.approx(distances.mean() + 3 * distances.std(ddof=1))
    assert result.n_cycles == 3


def test_path_interpolates_between_samples():
    # One cycle rises linearly in y: at the plane x = 50 the interpolated y is 0.5 even though no sample is there.
    stations = [[0, 0], [50, 0], [100, 0]]
    paths = [[[0, 0], [33, 0.33], [66, 0.66], [100, 1.0]], [[0, 0], [33, 0.33], [66, 0.66], [100, 1.0]]]
    result = path_characteristics(paths, stations)
    assert result.at_per_station_mm == pytest.approx([0.0, 0.5, 1.0])
    assert result.rt_mm == pytest.approx(0.0)


def test_path_that_misses_a_plane_raises():
    with pytest.raises(InsufficientData, match="path cycle 1 never crosses the plane of station 1"):
        path_characteristics([[[0, 0], [10, 0]], [[0, 0], [4, 0]]], [[0, 0], [5, 0], [10, 0]])
