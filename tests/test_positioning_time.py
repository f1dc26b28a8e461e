"""ISO 9283 clause 9 minimum positioning time on the pkm5: the Table 19 step plan and its pre-flight, a streamed run
on the simulator, and its figures against an independent computation from the raw samples and the simulator's motion
(the commanded constant-speed moves through the simulator's structural mode)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from figure_support import printed_font_sizes
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from reports_runs import simulated_run

from bench.cli import main
from bench.errors import ConfigError
from bench.protocols import summarize
from bench.protocols.positioning_time import MinimumPositioningTime
from bench.reports import collect
from bench.reports.plots import MIN_FONT_PT
from bench.reports.positioning_time import analyze_positioning_run, collect_positioning_time, positioning_time_plot
from bench.robots.pkm5_kinematics import steps_for_pose
from bench.simulators.dynamics import StructuralMode
from bench.store import Store

COUNT_MM = 25.4 / 800  # one count of the simulated 800 cpi mice
RATED_STEPS_S = 200  # the pkm5 firmware's rated (100 %) step rate
P1 = (110.0, 0.0, 320.0)
#: A fast run: two short steps (per-axis -2 then +4 mm), two cycles, on an ideal robot (true pose = commanded).
QUICK = dict(steps_mm=[-2.0, 4.0], cycles=2, hold_s=2.0, rest_s=0.3, settle_s=0.5)


def _move_s(start, end) -> float:
    """The firmware's constant-speed move time: the leg with the most steps at the rated step rate."""
    return max(abs(a - b) for a, b in zip(steps_for_pose((*start, 0, 0)), steps_for_pose((*end, 0, 0)))) / RATED_STEPS_S


def test_the_table_19_steps_from_the_cube_centre_keep_those_in_the_workspace():
    p = MinimumPositioningTime()
    assert [(s.number, s.distance_mm, s.target) for s in p.kept_steps] == [
        (1, -10.0, (100.0, -10.0, 310.0)),
        (2, 20.0, (120.0, 10.0, 330.0)),
    ]
    assert [s["step"] for s in p.skipped_steps] == [3, 4, 5, 6, 7]  # offsets -40, +60, -140, +360, -640 mm
    assert p.skipped_steps[0]["target_mm"] == [70.0, -40.0, 280.0] and "outside" in p.skipped_steps[0]["reason"]
    summary = summarize(p)
    assert summary.ok and summary.counts["captures"] == 3 * 2  # ISO Table 5: 3 cycles
    captures = [s for s in p.steps() if type(s).__name__ == "Capture"]
    # each window reaches back over the whole commanded move plus the rest before it (the model plans in
    # fractional steps, the firmware counts whole ones: one step is 5 ms)
    assert captures[0].conditions["lead_s"] == pytest.approx(_move_s(P1, (100, -10, 310)) + 0.5, abs=6e-3)
    assert captures[1].conditions["lead_s"] == pytest.approx(_move_s((100, -10, 310), (120, 10, 330)) + 0.5, abs=6e-3)
    assert {c.kind for c in captures} == {"positioning"} and captures[1].conditions["step"] == 2
    stored = p.config()
    assert stored["steps"][1] == {"step": 2, "distance_mm": 20.0, "target_mm": [120.0, 10.0, 330.0]}


def test_a_skipped_step_makes_the_next_one_start_from_the_last_pose_kept():
    p = MinimumPositioningTime(steps_mm=[-2.0, 300.0, -296.0])  # offsets -2, +298 (outside), +2 mm
    assert [(s.number, s.distance_mm) for s in p.kept_steps] == [(1, -2.0), (3, 4.0)]


def test_the_protocol_refuses_what_it_cannot_drive():
    with pytest.raises(ConfigError, match=r"no step target lies in the pkm5 workspace"):
        MinimumPositioningTime(steps_mm=[500.0])
    with pytest.raises(ConfigError, match=r"p1_mm = \[0.0, 0.0, 0.0\]: outside the pkm5 workspace"):
        MinimumPositioningTime(p1_mm=[0.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="robot = 'delta4'"):
        MinimumPositioningTime(robot="delta4")
    with pytest.raises(ConfigError, match="exceeds the 60 s streamed window"):
        MinimumPositioningTime(velocities_pct=[10.0])


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("positioning") / "b.db"
    with Store(path) as store:
        run_id = simulated_run(store, MinimumPositioningTime(**QUICK), "pkm5", seed=3, speed_factor=1000, ideal=True)
    return path, run_id


def _direct_time(t, p, band, hysteresis):
    """t_pos = t_2 - t_leave written out: leave |p - p(t_0)| > B, then inside B + h of the last point for good."""
    t_leave = t[np.argmax(np.linalg.norm(p - p[0], axis=1) > band)]
    d = np.linalg.norm(p - p[-1], axis=1)
    t_1 = np.argmax(d <= band)
    beyond = np.flatnonzero(d[t_1:] > band + hysteresis)
    t_2 = t[t_1 + (beyond[-1] + 1 if len(beyond) else 0)]
    return t_2 - t_leave


def test_the_stored_run_gives_the_positioning_time_of_its_raw_series(quick_run):
    path, run_id = quick_run
    with Store(path, read_only=True) as store:
        samples = store.samples(run_id, kind="positioning")
        result = analyze_positioning_run(store, run_id, bands_mm=[0.1, 0.5], hysteresis_mm=COUNT_MM)
    assert len(samples) == 4 and {s.values["step"] for s in samples} == {1.0, 2.0}
    by_band = {f.band_mm: f for f in result.figures}
    for band in (0.1, 0.5):
        figures = by_band[band]
        assert figures.steps == (1, 2) and figures.cycles == (1, 2)
        for i, step in enumerate((1, 2)):
            direct = [
                _direct_time(
                    np.array(s.raw["series"]["t_s"]),
                    np.column_stack([s.raw["series"][k] for k in ("x_mm", "y_mm", "z_mm")]),
                    band,
                    COUNT_MM,
                )
                for s in sorted(samples, key=lambda s: s.cycle)
                if s.values["step"] == step
            ]
            np.testing.assert_allclose(figures.result.time_s_per_cycle[i], direct, atol=1e-9)
            assert figures.result.mean_time_s[i] == pytest.approx(np.mean(direct), abs=1e-9)
    # the series runs from rest before the move (rest_s) to hold_s after the move-done signal
    first = samples[0].raw["series"]
    assert first["t_s"][0] == pytest.approx(-samples[0].values["lead_s"]) and first["t_s"][-1] == 2.0


def test_the_positioning_time_is_the_simulators_commanded_motion_and_ringing(quick_run):
    """Truth: the commanded constant-speed move (its duration from the firmware's step counts) through the
    simulator's structural mode (defaults: 2.5 Hz, damping 0.05), sampled finely, t_pos by the same definition."""
    path, run_id = quick_run
    with Store(path, read_only=True) as store:
        result = analyze_positioning_run(store, run_id, bands_mm=[0.1, 1.0], hysteresis_mm=0.0)
    poses = [P1, (108.0, -2.0, 318.0), (112.0, 2.0, 322.0)]
    mode, t = StructuralMode(), np.arange(-8.0, 2.0, 0.0005)
    for figures in result.figures:
        for i in range(2):
            duration = _move_s(poses[i], poses[i + 1])
            true = mode.arrival(t, poses[i], poses[i + 1], duration)
            keep = t >= -duration - 0.3  # the recorded window: rest_s before the move starts
            truth = _direct_time(t[keep], true[keep], figures.band_mm, 0.0)
            # the mice see the truth within a count and their 2 ms report interval
            assert figures.result.mean_time_s[i] == pytest.approx(truth, abs=0.05), (figures.band_mm, i)
            # a slow stepper move: the time is the commanded move, less the travel inside the two bands
            speed = np.linalg.norm(np.subtract(poses[i + 1], poses[i])) / duration
            assert truth == pytest.approx(duration - 2 * figures.band_mm / speed, abs=0.1)


def test_bench_analyze_and_the_report_give_the_same_times(quick_run, tmp_path, capsys):
    path, run_id = quick_run
    db = str(path)
    assert main(["analyze", "positioning-run", str(run_id), "--store", db, "--band-mm", "0.5", "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    steps = stored["results"][0]["steps"]
    assert [s["step"] for s in steps] == [1, 2] and [s["step"] for s in stored["skipped_steps"]] == []
    out = tmp_path / "series.csv"
    assert main(["export", str(run_id), "--kind", "positioning", "--series", "--store", db, "--out", str(out)]) == 0
    capsys.readouterr()
    assert (
        main(
            [
                "analyze",
                "positioning-time",
                str(out),
                "--band-mm",
                "0.5",
                "--hysteresis-mm",
                repr(stored["hysteresis_mm"]),
                "--json",
            ]
        )
        == 0
    )
    from_csv = json.loads(capsys.readouterr().out)["bands"]["0.5"]
    assert [s["mean_time_s"] for s in from_csv] == pytest.approx([s["mean_time_s"] for s in steps], abs=1e-9)
    with Store(path, read_only=True) as store:
        report = collect_positioning_time(store, run_id, bands_mm=[0.5])

    assert report.clauses == ("9 minimum positioning time",)
    plot = positioning_time_plot(report)
    sizes = printed_font_sizes(plot)
    assert sizes and min(sizes) >= MIN_FONT_PT - 1e-9 and len(plot.figure.legends) == 1  # readable at print size
    deviations = {d.topic: d for d in report.deviations}
    assert deviations["cycles"].status == "deviates" and deviations["steps"].status == "deviates"
    assert (
        main(
            ["report", str(run_id), "--store", db, "--out", str(tmp_path / "r"), "--format", "html", "--band-mm", "0.5"]
        )
        == 0
    )
    html = (tmp_path / "r" / f"report_run{run_id}.html").read_text()
    assert "Minimum positioning time (ISO 9283 9)" in html
    assert f"{steps[1]['mean_time_s']:.3f}" in html
    # --criterion t_pos_s: each step's mean time against the limit, simple acceptance (no U stated)
    limit = (steps[0]["mean_time_s"] + steps[1]["mean_time_s"]) / 2
    with Store(path, read_only=True) as store:
        judged = collect(store, run_id, bands_mm=[0.5], criteria={"t_pos_s": limit})
    assert [v[-1] for v in judged.decision.verdicts] == ["pass" if s["mean_time_s"] <= limit else "fail" for s in steps]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-0.3, 0.3), min_size=8, max_size=30),
    st.floats(2.0, 20.0),  # longer than twice the widest band (0.9 mm): a shorter step has no positioning time
    st.floats(-50, 50),
    st.floats(0.05, 0.4),
    st.floats(0.0, 0.5),
)
def test_a_wider_band_never_lengthens_the_positioning_time_and_the_frame_does_not_matter(
    ripple, step_mm, shift, band, wider
):
    """Invariants of t_pos = t_2 - t_leave: non-increasing in B (t_leave comes later, t_1 and t_2 earlier), and
    independent of where the time origin and the position frame lie."""
    from bench.metrology import minimum_positioning_time

    t = np.arange(len(ripple) + 4) * 0.1
    x = np.concatenate([[0.0, 0.0], step_mm + np.asarray(ripple) * np.linspace(1, 0, len(ripple)), [step_mm] * 2])
    distances = np.abs(np.r_[x - x[0], x - x[-1]])
    assume(
        min(np.min(np.abs(distances - b)) for b in (band, band + wider)) > 1e-6
    )  # a sample on the band edge: rounding decides either way
    series = [[(t, x[:, None])]]
    narrow = minimum_positioning_time(series, band_mm=band).mean_time_s[0]
    assert minimum_positioning_time(series, band_mm=band + wider).mean_time_s[0] <= narrow + 1e-12
    moved = [[(t + shift, x[:, None] + shift)]]
    assert minimum_positioning_time(moved, band_mm=band).mean_time_s[0] == pytest.approx(narrow, abs=1e-9)
