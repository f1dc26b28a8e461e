"""ISO 9283 clause 8 path protocols on the pkm5: the joint-space segmentation, the pre-flight, a streamed path run on
the simulator and its figures (AT/RT, CR/CO, AV/RV/FV) against the simulator's truth and an ideal robot."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reports_runs import simulated_run

from bench.cli import main
from bench.errors import ConfigError
from bench.metrology import path_characteristics
from bench.protocols import summarize
from bench.protocols.kinematics import robot_model
from bench.protocols.path import Cornering, PathAccuracy
from bench.reports.path_run import analyze_path_run, attained_cycles
from bench.store import Store

COUNT_MM = 25.4 / 800  # one count of the simulated 800 cpi mice


def _run(store, protocol, *, seed=4, ideal=False):
    return simulated_run(store, protocol, "pkm5", seed=seed, speed_factor=10000, ideal=ideal)


def test_the_paths_lie_in_the_cube_plane_through_the_iso_poses():
    p = PathAccuracy(cube_side_mm=40.0)
    line, circle = p.path("line"), p.path("circle")
    np.testing.assert_allclose(line.vertices_mm, [[94.0, -16.0, 304.0], [126.0, 16.0, 336.0]])  # P2 -> P4
    assert line.length_mm == pytest.approx(np.sqrt(32**2 * 3))
    assert circle.radius_mm == pytest.approx(16.0) and circle.length_mm == pytest.approx(32 * np.pi)
    points = circle.point(np.linspace(0, circle.length_mm, 7))
    np.testing.assert_allclose(np.linalg.norm(points - [110.0, 0.0, 320.0], axis=1), 16.0)
    np.testing.assert_allclose(points[:, 0] - 110.0, points[:, 2] - 320.0, atol=1e-12)  # the plane x = z
    rectangle = Cornering(cube_side_mm=40.0).path("rectangle")
    np.testing.assert_allclose(rectangle.corners_mm, [[94, 16, 304], [126, 16, 336], [126, -16, 336], [94, -16, 304]])


@pytest.mark.parametrize("shape", ["line", "circle", "rectangle"])
def test_every_segment_keeps_the_joint_space_chord_error_within_the_bound(shape):
    """Independent check: the forward kinematics at quarter points of every segment's joint-space chord."""
    p = (Cornering if shape == "rectangle" else PathAccuracy)(cube_side_mm=40.0, chord_error_mm=0.01)
    seg, path = p.segmentation(shape), p.path(shape)
    kinematics = robot_model("pkm5").kinematics
    for f in (0.25, 0.5, 0.75):
        fk = kinematics.fk((1 - f) * seg.joints[:-1] + f * seg.joints[1:])
        assert path.distance_mm(np.asarray(fk.pose)[:, :3]).max() <= 0.01
    assert seg.chord_error_mm <= 0.01
    # a looser bound gives fewer, longer segments
    loose = (Cornering if shape == "rectangle" else PathAccuracy)(
        cube_side_mm=40.0, chord_error_mm=0.1, max_segment_mm=20.0
    )
    assert len(loose.segmentation(shape).targets_mm) < len(seg.targets_mm)


def test_every_segment_target_passes_the_pre_flight_and_the_speeds_are_the_firmwares():
    p = PathAccuracy(shape="line", cycles=2, velocities_pct=[100.0, 10.0])
    summary = summarize(p)
    assert summary.ok and summary.counts["captures"] == 2 * 2 * (len(p.segmentation("line").targets_mm) - 1)
    for pct in (100.0, 10.0):
        plan = p.segment_plan("line", pct)
        assert all(0 < move_pct <= 100.0 and (move_pct * 2).is_integer() for _, move_pct, _ in plan)  # steps/s
        lengths = np.linalg.norm(np.diff(p.segmentation("line").targets_mm, axis=0), axis=1)
        speeds = lengths / np.array([d for _, _, d in plan])
        np.testing.assert_allclose(speeds, p.rated_mm_s * pct / 100, rtol=0.03)


def test_a_path_run_needs_a_streaming_instrument():
    from bench.protocols.plan import required_capabilities

    assert required_capabilities(Cornering(cycles=2, velocities_pct=[100.0])) == {"assembled", "arrival"}


def test_the_protocol_refuses_a_speed_the_legs_cannot_give_and_other_robots():
    with pytest.raises(ConfigError, match=r"path_speed_mm_s = 5, expected at most 0.89 mm/s"):
        PathAccuracy(path_speed_mm_s=5.0)
    with pytest.raises(ConfigError, match="robot = 'delta4'"):
        PathAccuracy(robot="delta4")


def _truth_at(samples, stations):
    """AT/RT of the simulator's true segment ends (each cycle a polyline from the path's start)."""
    paths = {}
    for s in sorted(samples, key=lambda x: x.step_index):
        paths.setdefault(s.cycle, []).append(s.raw["true_pose"][:3])
    return path_characteristics([np.array(p) for p in paths.values()], stations)


def test_a_streamed_line_run_gives_at_rt_av_near_the_truth_and_an_ideal_robot_near_the_resolution(tmp_path, capsys):
    protocol = PathAccuracy(shape="line", cycles=3, velocities_pct=[100.0], final_hold_s=0.5)
    with Store(tmp_path / "p.db") as store:
        demo, ideal = _run(store, protocol), _run(store, protocol, ideal=True)
        result, perfect = analyze_path_run(store, demo), analyze_path_run(store, ideal)
        samples = store.samples(demo, kind="path")
    (line,), (best,) = result.figures, perfect.figures
    assert line.n_cycles == 3 and line.n_segments == len(protocol.segmentation("line").targets_mm) - 1
    # the demo robot's error model: AT of mm, as its true segment ends give (the stream adds the mice's counts and
    # the structure's lag between the ends)
    from bench.reports.path_run import path_stations

    truth = _truth_at(samples, path_stations(protocol.path("line"), 1.0, 2.0))
    assert 0.3 < line.at_mm < 5.0
    assert line.at_mm == pytest.approx(truth.at_mm, abs=0.2)
    # an ideal robot: AT and RT within about a count of the instrument, the commanded speed within 1 %
    assert best.at_mm < 1.5 * COUNT_MM and best.rt_mm < 3 * COUNT_MM
    assert abs(best.av_pct) < 1.0 and best.rv_pct < 0.5
    assert best.mean_speed_mm_s == pytest.approx(protocol.rated_mm_s, rel=0.01)
    # the stream is the whole motion: times increase, a cycle takes the path's length over the speed
    (cycle, t, p, starts), *_ = attained_cycles(samples)[("line", 100.0)]
    assert np.all(np.diff(t) > 0) and len(starts) == line.n_segments
    assert t[-1] - t[0] == pytest.approx(protocol.path("line").length_mm / protocol.rated_mm_s + 0.5, rel=0.03)
    # the CLI gives the same figures from the store
    assert main(["analyze", "path-run", str(demo), "--store", str(tmp_path / "p.db"), "--json"]) == 0
    printed_run = json.loads(capsys.readouterr().out)
    (printed,) = printed_run["paths"]
    assert "calliper at stops" in printed_run["not_measured"]["8.4"]
    assert printed["AT_mm"] == pytest.approx(line.at_mm) and printed["AV_pct"] == pytest.approx(line.av_pct)


def test_a_cornering_run_on_an_ideal_robot_rounds_the_corners_by_less_than_a_count(tmp_path):
    protocol = Cornering(cycles=2, velocities_pct=[100.0], final_hold_s=0.2)
    with Store(tmp_path / "c.db") as store:
        run_id = _run(store, protocol, ideal=True)
        (rectangle,) = analyze_path_run(store, run_id).figures
    assert [c for c, _, _ in rectangle.corners] == ["P3", "P4", "P5"]
    assert all(cr < COUNT_MM and co < 1.5 * COUNT_MM for _, cr, co in rectangle.corners)
    assert rectangle.at_mm < 1.5 * COUNT_MM


def test_analyze_path_run_refuses_a_pose_run(tmp_path, capsys):
    from reports_runs import write_pose_run

    with Store(tmp_path / "q.db") as store:
        run_id = write_pose_run(store)
    assert main(["analyze", "path-run", str(run_id), "--store", str(tmp_path / "q.db")]) == 2
    assert "a iso9283_pose run, expected one of iso9283_path, iso9283_cornering" in capsys.readouterr().err


@settings(max_examples=60, deadline=None)
@given(
    shape=st.sampled_from(["line", "rectangle", "circle"]),
    side=st.floats(5.0, 200.0),
    fraction=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20),
    spacing=st.floats(0.2, 10.0),
)
def test_commanded_points_lie_on_their_path_and_stations_are_at_most_the_spacing_apart(shape, side, fraction, spacing):
    from bench.metrology.path_geometry import commanded_path
    from bench.protocols.iso9283 import cube_poses

    path = commanded_path(shape, cube_poses((110.0, 0.0, 320.0), side))
    points = path.point(np.array(fraction) * path.length_mm)
    assert path.distance_mm(points).max() < 1e-9 * side
    stations = path.stations(spacing)
    gaps = np.linalg.norm(np.diff(np.vstack([stations, stations[:1]]) if path.closed else stations, axis=0), axis=1)
    assert gaps.max() <= spacing + 1e-9 and path.distance_mm(stations).max() < 1e-9 * side


@pytest.mark.parametrize("load_kg, prompts", [(0.0, []), (2.0, [2.0])])
def test_a_path_run_asks_for_its_load_before_its_first_move(load_kg, prompts):
    # its samples are labelled with the load: the operator confirms it is on (the runner asks for its removal)
    from bench.protocols.plan import iterate
    from bench.steps import Move, Prompt

    steps = list(iterate(Cornering(cycles=2, velocities_pct=[100.0], load_kg=load_kg), final=False))
    assert [s.conditions["load_kg"] for s in steps if isinstance(s, Prompt)] == prompts
    assert isinstance(steps[0], Prompt if prompts else Move)
