"""Actuator accuracy (dissertation Tables A.1-A.7, 8-1) and ISO 230-2 style positioning figures."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bench.errors import ConfigError, InsufficientData
from bench.metrology import control_resolution, groover_actuator, positioning_iso230_2

DATA = Path(__file__).resolve().parents[1] / "examples" / "data" / "actuator_tables_a1_a6.csv"
TARGETS = [10.0, 20.0, 30.0, 40.0, 50.0]

# Table 8-1 (printed, mm) and the recomputation from the raw tables (iso9283.md §7.4, [R]).
TABLE_8_1 = {1: (0.18, 0.19), 2: (0.12, 0.12), 3: (0.13, 0.13), 4: (0.14, 0.14), 5: (0.12, 0.12), 6: (0.20, 0.20)}
RECOMPUTED = {
    1: (0.183, 0.186),
    2: (0.119, 0.122),
    3: (0.127, 0.130),
    4: (0.140, 0.143),
    5: (0.121, 0.122),
    6: (0.194, 0.195),
}
# Table A.7: standard deviation (mm) at 10/20/30/40/50 mm per actuator.
TABLE_A_7 = {
    1: (0.06, 0.11, 0.04, 0.05, 0.04),
    2: (0.02, 0.05, 0.02, 0.05, 0.06),
    3: (0.04, 0.04, 0.04, 0.06, 0.03),
    4: (0.03, 0.06, 0.05, 0.07, 0.03),
    5: (0.03, 0.07, 0.03, 0.03, 0.03),
    6: (0.06, 0.08, 0.06, 0.07, 0.06),
}
BIAS_1 = (-0.009, -0.099, -0.132, -0.098, -0.113)
BIAS_5 = (-0.061, -0.129, -0.142, -0.158, -0.152)


def _readings(actuator: int) -> np.ndarray:
    table = pd.read_csv(DATA, comment="#")
    rows = table[table["actuator"] == actuator]
    return rows.pivot(index="repeat", columns="cmd_mm", values="travel_mm")[TARGETS].to_numpy()


@pytest.mark.parametrize("actuator", range(1, 7))
def test_tables_a1_a6_reproduce_table_8_1(actuator):
    cr = control_resolution(1.25, 200 if actuator <= 4 else 400)
    result = groover_actuator(TARGETS, _readings(actuator), control_resolution_mm=cr)
    assert result.repeatability_mm == pytest.approx(RECOMPUTED[actuator][0], abs=0.0005)
    assert result.accuracy_mm == pytest.approx(RECOMPUTED[actuator][1], abs=0.0005)
    assert result.repeatability_mm == pytest.approx(TABLE_8_1[actuator][0], abs=0.01)
    assert result.accuracy_mm == pytest.approx(TABLE_8_1[actuator][1], abs=0.01)
    assert result.sigma_mm == pytest.approx(TABLE_A_7[actuator], abs=0.005)
    assert result.n == 10


def test_bias_hidden_by_groover_is_reported():
    cr = control_resolution(1.25, 200)
    assert groover_actuator(TARGETS, _readings(1), control_resolution_mm=cr).mean_deviation_mm == pytest.approx(
        BIAS_1, abs=0.0005
    )
    five = groover_actuator(TARGETS, _readings(5), control_resolution_mm=cr / 2)
    assert five.mean_deviation_mm == pytest.approx(BIAS_5, abs=0.0005)
    assert five.max_abs_bias_mm == pytest.approx(0.158, abs=0.0005)


def test_control_resolution_of_the_dissertation_actuators():
    assert control_resolution(1.25, 200) == pytest.approx(0.00625)
    assert control_resolution(1.25, 400) == pytest.approx(0.003125)
    with pytest.raises(ConfigError, match="steps_per_rev = 0"):
        control_resolution(1.25, 0)


@settings(max_examples=40, deadline=None)
@given(arrays(float, (4, 3), elements=st.floats(-1, 1)), st.floats(-5, 5))
def test_constant_offset_moves_bias_not_groover_accuracy(noise, offset):
    # iso9283.md §10.2 #18.
    readings = np.array([10.0, 20.0, 30.0]) + noise
    base = groover_actuator([10, 20, 30], readings, control_resolution_mm=0.01)
    shifted = groover_actuator([10, 20, 30], readings + offset, control_resolution_mm=0.01)
    assert shifted.accuracy_mm == pytest.approx(base.accuracy_mm, abs=1e-9)
    assert np.array(shifted.mean_deviation_mm) == pytest.approx(np.array(base.mean_deviation_mm) + offset, abs=1e-9)


def test_one_repeat_is_insufficient():
    with pytest.raises(InsufficientData, match=r"readings_mm repeats per target: 1 sample\(s\), at least 2"):
        groover_actuator([10, 20], [[10, 20]], control_resolution_mm=0.01)


def test_iso230_2_hand_computed_seven_targets_five_approaches():
    # iso9283.md §10.2 #17: m = 7 targets, n = 5 approaches; means divide by cycles, not by targets.
    targets = np.arange(7) * 10.0
    up_dev = np.tile([[0.00], [0.02], [0.04], [0.02], [0.02]], (1, 7)) + np.arange(7) * 0.001
    down_dev = up_dev - 0.01
    result = positioning_iso230_2(targets, targets + up_dev, targets + down_dev)
    s = np.std([0.0, 0.02, 0.04, 0.02, 0.02], ddof=1)
    assert result.mean_deviation_forward_mm == pytest.approx(0.02 + np.arange(7) * 0.001)
    assert result.reversal_mm == pytest.approx([0.01] * 7)
    assert result.repeatability_forward_mm == pytest.approx(4 * s)
    assert result.repeatability_mm == pytest.approx(4 * s + 0.01)
    assert result.systematic_forward_mm == pytest.approx(0.006)
    assert result.systematic_mm == pytest.approx(0.016)
    assert result.mean_bidirectional_mm == pytest.approx(0.006)
    assert result.accuracy_forward_mm == pytest.approx(0.006 + 4 * s)
    assert result.accuracy_mm == pytest.approx(0.016 + 4 * s)
    assert result.n == 5


def test_iso230_2_reversal_sign_forward_above_backward_is_positive():
    targets = [0.0, 10.0]
    forward = [[0.05, 10.05], [0.06, 10.06]]
    backward = [[-0.05, 9.95], [-0.04, 9.96]]
    result = positioning_iso230_2(targets, forward, backward)
    assert all(b > 0 for b in result.reversal_mm)
    swapped = positioning_iso230_2(targets, backward, forward)
    assert all(b < 0 for b in swapped.reversal_mm)


def test_iso230_2_unidirectional_only():
    result = positioning_iso230_2([0, 10], [[0.0, 10.0], [0.1, 10.1]])
    assert result.reversal_mm is None and result.accuracy_mm is None
    assert result.repeatability_forward_mm == pytest.approx(4 * np.std([0, 0.1], ddof=1))


@settings(max_examples=50, deadline=None)
@given(st.integers(2, 6), st.integers(2, 6), st.integers(2, 6), st.data())
def test_iso230_2_ordering_invariants(m, n_up, n_down, data):
    # iso9283.md §10.2 #15: E >= max(E↑, E↓), A >= max(A↑, A↓), R >= max(R↑, R↓), M <= E.
    targets = np.arange(m) * 5.0
    up = targets + data.draw(arrays(float, (n_up, m), elements=st.floats(-1, 1)))
    down = targets + data.draw(arrays(float, (n_down, m), elements=st.floats(-1, 1)))
    r = positioning_iso230_2(targets, up, down)
    eps = 1e-12
    assert r.systematic_mm + eps >= max(r.systematic_forward_mm, r.systematic_backward_mm)
    assert r.accuracy_mm + eps >= max(r.accuracy_forward_mm, r.accuracy_backward_mm)
    assert r.repeatability_mm + eps >= max(r.repeatability_forward_mm, r.repeatability_backward_mm)
    assert r.mean_bidirectional_mm <= r.systematic_mm + eps
