"""Figures readable at print size: every rendered text >= 7 pt on A4, one legend per small-multiples figure, one
scale across its panels."""

from __future__ import annotations

import numpy as np
import pytest
from figure_support import printed_font_sizes, same_scale, small_multiples
from hypothesis import given, settings
from hypothesis import strategies as st
from reports_runs import SETTINGS, pose_config, write_pose_run

from bench.reports import collect
from bench.reports.plots import MIN_FONT_PT, PRINT_WIDTH_IN
from bench.reports.pose_plots import (
    deviation_histograms,
    drift_series,
    error_map_3d,
    hull_loop,
    pose_scatter,
    report_plots,
)
from bench.store import Store


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    with Store(tmp_path_factory.mktemp("plots") / "bench.db") as store:
        run_id = write_pose_run(
            store, config=pose_config(velocities_pct=[100.0, 50.0, 10.0], cycles=5), settings=SETTINGS
        )
        yield collect(store, run_id, resamples=50)


def test_every_text_is_at_least_7_pt_on_a4(report):
    plots = report_plots(report)
    assert len(plots) >= 3
    for plot in plots:
        sizes = printed_font_sizes(plot)
        assert sizes and min(sizes) >= MIN_FONT_PT - 1e-9, plot.caption
        assert plot.figure.get_size_inches()[0] == pytest.approx(PRINT_WIDTH_IN, abs=0.01)


def test_small_multiples_share_one_scale_and_one_legend(report):
    for plot, count in ((pose_scatter(report), 15), (drift_series(report), 5)):
        grid, panels = small_multiples(plot)
        assert len(panels) == count and len({panel.title for panel in panels}) == count
        assert same_scale(grid)
        assert len(plot.figure.legends) == 1 and not any(axes.get_legend() for axes in plot.figure.axes)
    drift = drift_series(report)
    labels = [text.get_text() for text in drift.figure.legends[0].get_texts()]
    assert labels == ["100 % velocity", "50 % velocity", "10 % velocity"]
    grid, panels = small_multiples(drift)
    colours = {}  # what the one legend says holds in every panel: one colour per velocity
    for panel in panels:
        for line in panel.artists:
            colours.setdefault(line.get_label(), set()).add(line.get_color())
    assert sorted(colours) == sorted(labels) and all(len(c) == 1 for c in colours.values())


def test_pose_scatter_shows_every_cycle_inside_its_panel(report):
    grid, panels = small_multiples(pose_scatter(report))
    assert grid.xlim == grid.ylim  # one scale for x and y: the RP circle is round
    for panel, result in zip(panels, report.poses):
        points = panel.artists[0].get_offsets()
        assert len(points) == result.accuracy.n
        assert np.all((points >= grid.xlim[0]) & (points <= grid.xlim[1]))
        circle = panel.artists[3]
        assert circle.get_radius() == pytest.approx(result.repeatability.rp_mm)
        assert np.all(np.abs(np.asarray(circle.center)) + circle.get_radius() <= grid.xlim[1])


def test_deviation_histograms_count_every_cycle_on_shared_bins(report):
    plot = deviation_histograms(report)
    grid, panels = small_multiples(plot)
    assert len(panels) == len(report.poses) == 15
    assert same_scale(grid) and grid.ylim[0] == 0.0
    assert len(plot.figure.legends) == 1
    for panel, result in zip(panels, report.poses):
        outlines = [a for a in panel.artists if not a.get_label().startswith("_")]  # one step outline per axis
        assert len(outlines) == 3
        edges = [np.unique(line.get_xdata()) for line in outlines]
        assert all(np.array_equal(edges[0], e) for e in edges)  # the same bins
        # the step outline's heights over the bins add up to the cycles of the pose
        heights = outlines[0].get_ydata()[1:-1:2]
        assert heights.sum() == pytest.approx(result.accuracy.n)
        assert heights.max() <= grid.ylim[1]


def test_error_map_colours_each_pose_by_its_ap(report):
    plot = error_map_3d(report)
    (axes,) = [axes for axes in plot.figure.axes if axes.name == "3d"]
    tips = axes.collections[2]  # quiver, command poses, barycentre tips
    np.testing.assert_allclose(tips.get_array(), [r.accuracy.ap_mm for r in report.poses])
    assert len(report.poses) == 15 and "one vector per set of conditions (3)" in plot.caption


def test_figures_drawn_in_a_forked_process_are_the_same_pngs(report):
    from bench.reports.plots import draw_all, png_bytes

    here, forked = report_plots(report), report_plots(report)
    draw_all(forked, parallel=True)
    assert [png_bytes(plot) for plot in here] == [png_bytes(plot) for plot in forked]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(-50, 50), st.integers(-50, 50)), min_size=1, max_size=40))
def test_hull_loop_encloses_every_point_with_left_turns_only(coordinates):
    points = np.array(coordinates, dtype=float)
    loop = hull_loop(points)
    if loop is None:  # no area: every point on one line
        assert np.linalg.matrix_rank(points - points[0]) < 2
        return
    assert loop[0] == loop[-1] and len(set(loop[:-1].tolist())) == len(loop) - 1
    corners = points[loop]
    edges = np.diff(corners, axis=0)
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    assert np.all(turns > 0)  # strictly convex, counter-clockwise: no collinear vertex kept
    for start, edge in zip(corners[:-1], edges):  # every point on the inner side of every edge, or on it
        relative = points - start
        assert np.all(edge[0] * relative[:, 1] - edge[1] * relative[:, 0] >= 0)


def test_hull_loop_has_scipys_vertices():
    from scipy.spatial import ConvexHull

    points = np.random.default_rng(1).normal(size=(2500, 2))
    assert sorted(hull_loop(points)[:-1].tolist()) == sorted(ConvexHull(points).vertices.tolist())


def test_error_bars_of_a_length_stop_at_zero():
    """AP_P 0.1 ± 0.3 mm: the bar runs from 0 to 0.4 mm, never below 0 (a length cannot be negative)."""
    from bench.reports.plots import nonnegative_yerr

    lower, upper = nonnegative_yerr([0.1, 2.0, float("nan")], [0.3, 0.5, 0.0])
    assert lower == pytest.approx([0.1, 0.5, 0.0]) and upper == pytest.approx([0.3, 0.5, 0.0])
