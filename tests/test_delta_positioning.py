"""Delta robot positioning test (thesis §8.4.2) read by the laser grid: partial readings end to end on the simulated
delta4 controller with its laser-grid simulator, checked against the simulator's truth and an independent decoder
written from the reference tables (delta4-lasergrid.md §4.3-4.6), plus the analysis of partial readings."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.cli import main
from bench.errors import ConfigError
from bench.metrology.partial_pose import axis_errors, detection_rate, partial_pose_statistics
from bench.protocols import PROTOCOLS, Runner
from bench.rigs.lasergrid import LaserGridInstrument
from bench.robots.delta4 import Delta4Controller, SensorFrame
from bench.robots.testing import ScriptedPort
from bench.simulators import delta4 as sim_delta4
from bench.simulators.rig import simulated_rig
from bench.steps import Capture, commanded_values
from bench.store import Store, export_run, tidy_table

CYCLES = 4
SEED = 4  # P1 and P3 seen by the horizontal screen, P3 by the vertical one, P2 by neither (blind phases)

# Reference tables, typed in from delta4-lasergrid.md: laser offsets from BE (§4.4), GUI screen placement (§4.3:
# first sensor centre, 10 mm pitch, index = 16 row + column), the vertical laser set 40 mm below z0 (§4.2), the
# simulator's 1 mm detection window (§4.10) and the 3.75 mm decoding gate (§4.7).
OFFSETS_MM = np.array(
    [
        (0, 0),
        (15, 0),
        (0, -15),
        (15, -15),
        (-22.5, 0),
        (22.5, 0),
        (0, -22.5),
        (0, 22.5),
        (-22.5, -22.5),
        (-22.5, 22.5),
        (22.5, -22.5),
        (22.5, 22.5),
    ]
)
FIRST_CENTRE_MM = {"horizontal": np.array([-75.0, -75.0]), "vertical": np.array([-75.0, -225.0])}
R_MM, GATE_MM = 1.0, 3.75


def independent_decode(screen: str, lit: list[int], prior_mm: np.ndarray) -> tuple[float, float] | None:
    """BE (u, v) on one screen from its single lit sensor, or None when it does not decode unambiguously."""
    if len(lit) != 1:
        return None
    centre = FIRST_CENTRE_MM[screen] + 10.0 * np.array([lit[0] % 16, lit[0] // 16])
    distance = np.abs(centre - OFFSETS_MM - prior_mm).max(axis=1)
    best, second = np.sort(distance)[:2]
    if best >= GATE_MM or second - best < 2 * R_MM:
        return None
    return tuple(centre - OFFSETS_MM[np.argmin(distance)])


def independent_axes(raw: dict, command: np.ndarray) -> dict[str, float]:
    """Measured axes of one stored raw frame: each screen separately, nothing when the screens disagree on y."""
    horizontal = independent_decode("horizontal", raw["horizontal"], command[[0, 1]])
    vertical = independent_decode("vertical", raw["vertical"], command[[1, 2]] - (0.0, 40.0))
    if horizontal and vertical and abs(horizontal[1] - vertical[0]) > 2.5:
        return {}
    axes = {}
    if vertical:
        axes |= {"y_mm": vertical[0], "z_mm": vertical[1] + 40.0}
    if horizontal:
        axes |= {"x_mm": horizontal[0], "y_mm": horizontal[1]}
    return axes


@pytest.fixture(scope="module")
def positioning_run(tmp_path_factory):
    """One short delta_positioning run on the simulated delta4 with the grid attached: (store, run result, csv)."""
    folder = tmp_path_factory.mktemp("delta")
    store = Store(folder / "bench.db")
    rig = simulated_rig("delta4", seed=SEED, speed_factor=20000)
    try:
        result = Runner(rig, store).run(PROTOCOLS["delta_positioning"](settle_s=0.1, cycles=CYCLES))
    finally:
        rig.close()
    yield store, result, export_run(store, result.run_id, folder / "run.csv")
    store.close()


def test_positioning_run_completes_with_the_grid_and_stores_every_reading(positioning_run):
    store, result, _ = positioning_run
    assert (result.exit_status, result.samples) == ("completed", 3 * CYCLES)
    table = tidy_table(store, result.run_id)
    assert table["horizontal_valid"].sum() >= 1 and table["vertical_valid"].sum() >= 1
    assert table.loc[table["pose"] == "P2", ["horizontal_valid", "vertical_valid"]].to_numpy().sum() == 0
    raw = store.samples(result.run_id)[0].raw
    assert set(raw["status"]) == {"horizontal", "vertical"} and raw["report"].endswith(("v", "X"))


def test_stored_readings_are_within_the_detection_window_of_the_true_pose(positioning_run):
    store, result, _ = positioning_run
    compared = 0
    for sample in store.samples(result.run_id):
        true = np.array(sample.raw["true_pose"])
        command = np.array([sample.values[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
        assert 0.0 < np.abs(true - command).max() < 4.5  # the attained pose, off by the robot's error
        for axis, name in enumerate(("x_mm", "y_mm", "z_mm")):
            if name in sample.values:
                assert abs(sample.values[name] - true[axis]) <= R_MM + 1e-9  # one lattice point, window r
                compared += 1
    assert compared >= 6


def test_stored_values_are_what_an_independent_decoder_reads_from_the_raw_frames(positioning_run):
    store, result, _ = positioning_run
    for sample in store.samples(result.run_id):
        command = np.array([sample.values[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
        stored = {k: v for k, v in sample.values.items() if k in ("x_mm", "y_mm", "z_mm")}
        assert stored == pytest.approx(independent_axes(sample.raw, command))


def test_hit_rates_and_axis_counts_match_the_raw_frames(positioning_run, capsys):
    store, result, csv = positioning_run
    assert main(["analyze", "grid-positioning", str(csv), "--json"]) == 0
    poses = json.loads(capsys.readouterr().out)["poses"]
    samples = store.samples(result.run_id)
    for pose, figures in poses.items():
        frames = [s for s in samples if s.pose == pose]
        command = np.array([frames[0].values[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
        decoded = [independent_axes(s.raw, command) for s in frames]
        assert figures["n"] == len(frames) == CYCLES
        for screen, axis in (("horizontal", "x_mm"), ("vertical", "z_mm")):
            assert figures["screens"][screen]["lit"]["k"] == sum(bool(s.raw[screen]) for s in frames)
            assert figures["screens"][screen]["valid"]["k"] == sum(axis in d for d in decoded)
            assert figures["screens"][screen]["valid"]["rate"] == pytest.approx(
                sum(axis in d for d in decoded) / CYCLES
            )
        for axis in "xyz":
            values = [d[f"{axis}_mm"] for d in decoded if f"{axis}_mm" in d]
            assert figures["axes"][axis]["n"] == len(values)
            if values:
                assert figures["axes"][axis]["AP_mm"] == pytest.approx(np.mean(values) - command["xyz".index(axis)])


def test_a_pose_without_valid_readings_is_reported_as_such_not_as_zero(positioning_run, capsys):
    _, _, csv = positioning_run
    assert main(["analyze", "grid-positioning", str(csv), "--json"]) == 0
    p2 = json.loads(capsys.readouterr().out)["poses"]["P2"]
    assert p2["screens"]["horizontal"]["valid"]["rate"] == 0.0
    assert all(
        axis == {"n": 0, "AP_mm": None, "spread_3s_mm": None, "max_abs_error_mm": None, "mean_abs_error_mm": None}
        for axis in p2["axes"].values()
    )
    assert (p2["n_complete"], p2["AP_mm"], p2["RP_mm"]) == (0, None, None)
    assert main(["analyze", "grid-positioning", str(csv)]) == 0
    text = capsys.readouterr().out
    assert "P2" in text and text.count("no valid reading (n 0)") >= 3


def test_the_iso9283_analysis_refuses_partial_readings(positioning_run, capsys):
    _, _, csv = positioning_run
    assert main(["analyze", "iso9283", str(csv)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "laser-grid readings" in error[0]
    assert error[0].endswith(f"analyse them with bench analyze grid-positioning {csv}")


def test_an_axis_from_an_invalid_screen_is_refused(positioning_run, tmp_path, capsys):
    _, _, csv = positioning_run
    lines = csv.read_text().splitlines()
    header = lines[0].split(",")
    row = next(i for i, line in enumerate(lines[1:], 1) if line.split(",")[header.index("horizontal_valid")] == "0")
    cells = lines[row].split(",")
    cells[header.index("x_mm")] = "0.0"
    lines[row] = ",".join(cells)
    (tmp_path / "edited.csv").write_text("\n".join(lines) + "\n")
    assert main(["analyze", "grid-positioning", str(tmp_path / "edited.csv")]) == 2
    assert f"row {row}, column x_mm: '0.0', expected it only with horizontal_valid = 1" in capsys.readouterr().err


# -- frames that must not become positions ------------------------------------------------------------------------


class FrameSource:
    """Serves prepared sensor frames, as the driver's ``read_sensor_frame`` does (stamped when served)."""

    def __init__(self, *frames: tuple[tuple[int, ...], tuple[int, ...]]) -> None:
        self.frames = list(frames)

    def read_sensor_frame(self, timeout_s: float) -> SensorFrame:
        import time

        horizontal, vertical = self.frames.pop(0)
        return SensorFrame(horizontal, vertical, b"", time.monotonic(), time.monotonic())


def capture_at(point):
    return Capture("P", 1, commanded=commanded_values(point))


def test_screens_disagreeing_on_y_store_no_position():
    # prior (0, 2.5, -150): horizontal sensor 105 = (9, 6), centre (15, -15), decodes as G5-c to (x, y) = (0, 0);
    # vertical sensor 40 = (8, 2), centre (5, -205), decodes as G5-b to (y, z - 40) = (5, -190). Both are 2.5 mm from
    # the prior, so both are "ok", but their y differ by 5 mm: one took the wrong laser and nothing says which.
    measured = LaserGridInstrument(FrameSource(((105,), (40,)))).measure(capture_at((0.0, 2.5, -150.0)))
    assert measured.raw["status"] == {"horizontal": "ok", "vertical": "ok"} and measured.raw["screens_disagree"]
    assert not {"x_mm", "y_mm", "z_mm"} & set(measured.values)
    assert measured.values["horizontal_valid"] == measured.values["vertical_valid"] == 0.0
    assert measured.values["y_disagreement_mm"] == 5.0


def test_an_ambiguous_screen_stores_nothing_and_the_other_screen_its_own_axes():
    # prior (0, 0, -150): horizontal sensor 104 = (8, 6), centre (5, -15); its nearest candidate (G5-b, BE at (5, 0))
    # is 5 mm from the prior, outside the 3.75 mm gate. Vertical sensor 41 = (9, 2) decodes as G5-c to (0, -190).
    measured = LaserGridInstrument(FrameSource(((104,), (41,)))).measure(capture_at((0.0, 0.0, -150.0)))
    assert measured.raw["status"] == {"horizontal": "ambiguous", "vertical": "ok"}
    assert "x_mm" not in measured.values and measured.values["horizontal_valid"] == 0.0
    assert (measured.values["y_mm"], measured.values["z_mm"], measured.values["vertical_valid"]) == (0.0, -150.0, 1.0)


def test_hits_no_single_position_explains_are_a_fault_and_store_nothing():
    frames = ((119, 0), ())  # centres (-5, -5) and (-75, -75): no BE position lights both
    measured = LaserGridInstrument(FrameSource(frames)).measure(capture_at((0.0, 0.0, -150.0)))
    assert measured.raw["status"] == {"horizontal": "fault", "vertical": "no-hit"}
    assert not {"x_mm", "y_mm", "z_mm"} & set(measured.values)
    assert (measured.values["horizontal_hits"], measured.values["vertical_hits"]) == (2.0, 0.0)


def test_a_report_begun_before_the_servos_settled_is_never_stored():
    # The report "hV100X" (old pose) is on the wire before 'z'; its frame is only closed by the next report, which
    # arrives after the capture is asked for. The capture must skip it and store the next one (V101).
    port = ScriptedPort([("P080XQ073XR122XS127X", "hV100Xz"), ("z", "hV101Xv")])
    robot = Delta4Controller(port, settle_timeout_s=0.5)
    robot.move_servos((59.5102, 54.0404, 90.6811, 94.6176), require_settled=True)
    measured = LaserGridInstrument(robot).measure(capture_at((30.5, -39.9, -150.0)))
    assert measured.raw["vertical"] == [101] and measured.raw["report"] == "hV101Xv"


# -- the simulator program's options ---------------------------------------------------------------------------------


def _device(*options: str):
    import argparse

    parser = argparse.ArgumentParser()
    sim_delta4.add_arguments(parser)
    return sim_delta4.build_device(parser.parse_args(["--ideal", *options]))


def test_the_simulator_attaches_the_grid_and_no_grid_reports_no_hit():
    with_grid, without = _device(), _device("--no-grid")
    for device in (with_grid, without):
        device.feed(b"E", 0.0)
    # home (0, 0, -150) lies at phase (5, 5) of both screens: G5-c lights (9, 6) and (9, 2), sensors 105 and 41
    assert with_grid.tick(0.0) == b"H105XV041X" and without.tick(0.0) == b"hv"


def test_bad_grid_options_are_refused_naming_the_option():
    with pytest.raises(ConfigError, match=r"--grid-p-miss = 1.5, expected a number in \[0, 1\]"):
        _device("--grid-p-miss", "1.5")
    with pytest.raises(ConfigError, match=r"--grid-spot-half-width-mm = 5.0, expected a number in \(0, 5\) mm"):
        _device("--grid-spot-half-width-mm", "5")


def test_miss_probability_by_height_reproduces_appendix_d2_at_each_height():
    from bench.simulators.lasergrid import LaserGridSimulator

    simulator = LaserGridSimulator(p_miss_by_distance=True, seed=5)
    for height_mm, thesis in ((140.0, 0.9925), (200.0, 0.98)):  # hits / 400 attempts in Appendix D2
        frames = simulator.frames(np.tile([-5.0, -5.0, -height_mm], (4000, 1)))  # BE on sensor (7, 7)
        assert np.mean([len(f.horizontal) == 1 for f in frames]) == pytest.approx(thesis, abs=0.006)
    with pytest.raises(ConfigError, match="p_miss = 0.1 with p_miss_by_distance"):
        LaserGridSimulator(p_miss=0.1, p_miss_by_distance=True)


# -- statistics of partial readings ----------------------------------------------------------------------------------


def test_detection_rate_wilson_interval_against_the_closed_form_at_zero():
    rate = detection_rate([0] * 15)
    assert (rate.k, rate.n, rate.rate, rate.low) == (0, 15, 0.0, 0.0)
    assert rate.high == pytest.approx(4 / (15 + 4))  # 0 of n: Wilson upper bound z^2 / (n + z^2), z = 2


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(*[st.one_of(st.none(), st.floats(-5, 5)) for _ in range(3)]), min_size=1, max_size=12))
def test_each_axis_counts_only_its_own_readings(rows):
    readings = np.array([[np.nan if v is None else v for v in row] for row in rows], dtype=float)
    command = np.array([1.0, -2.0, 3.0])
    stats = partial_pose_statistics(readings, command)
    for k, axis in enumerate(stats.axes):
        present = readings[~np.isnan(readings[:, k]), k]
        assert axis.n == len(present)
        if len(present) == 0:
            assert axis == axis_errors([np.nan], 0.0)
        else:
            assert axis.ap_mm == pytest.approx(present.mean() - command[k], abs=1e-9)
            assert axis.max_abs_error_mm == pytest.approx(np.abs(present - command[k]).max())
            assert (axis.spread_3s_mm is None) == (len(present) < 2)
    complete = ~np.isnan(readings).any(axis=1)
    assert stats.n_complete == complete.sum() and (stats.rp_mm is None) == (complete.sum() < 2)


@pytest.mark.parametrize(
    "module",
    ["bench.metrology.partial_pose", "bench.rigs.lasergrid", "bench.sensors.lasergrid", "bench.simulators.lasergrid"],
)
def test_docstring_examples(module):
    import importlib

    from doctests import run_doctests

    result = run_doctests(importlib.import_module(module))
    assert result.failed == 0 and result.attempted > 0


def test_a_numeric_table_with_nan_axes_reads_like_the_csv(positioning_run):
    """The exported table read back by pandas (NaN floats, not strings) gives the same checked table as the CLI's
    string reader: an unmeasured axis stays NaN, never the text 'nan' or 0."""
    import pandas as pd

    from bench.metrology.partial_pose import grid_positioning_table
    from bench.metrology.tables import read_table_csv

    _, _, csv = positioning_run
    from_numbers = grid_positioning_table(pd.read_csv(csv))
    from_strings = grid_positioning_table(read_table_csv(csv))
    for axis in ("x_mm", "y_mm", "z_mm"):
        np.testing.assert_array_equal(from_numbers[axis].isna(), from_strings[axis].isna())
        np.testing.assert_allclose(from_numbers[axis].dropna(), from_strings[axis].dropna())
    assert from_numbers["z_mm"].isna().any()  # the thesis poses leave some axes unmeasured
