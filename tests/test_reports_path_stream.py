"""A path run is analysed and reported as it is read, cycle by cycle: the figures equal those computed by the metrology
from every cycle held at once, whatever the order of the samples, and the analysis's peak memory does not grow with
the run (tracemalloc, not the wall clock)."""

from __future__ import annotations

import random
import shutil
import tracemalloc

import numpy as np
import pytest
from reports_runs import copy_path_cycles, simulated_run

from bench.metrology import (
    cornering_deviations,
    path_characteristics,
    path_speed,
    path_velocity_characteristics,
)
from bench.metrology.iso9283_dynamics import station_crossings
from bench.metrology.uncertainty_figures import path_uncertainty
from bench.protocols.path import Cornering, PathAccuracy
from bench.reports import collect
from bench.reports.path import path_plot
from bench.reports.path_cycles import PLOTTED_CYCLES, PathCycles, attained_cycles, path_stations, speed_readings
from bench.reports.path_run import PathDesign, analyze_path_run
from bench.store import Store


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A line-and-circle run and a rectangle (cornering) run, 3 cycles each (the path model's fewest)."""
    folder = tmp_path_factory.mktemp("stream")
    with Store(folder / "p.db") as store:
        path = simulated_run(
            store,
            PathAccuracy(shape="both", cycles=3, velocities_pct=[100.0], final_hold_s=0.2),
            "pkm5",
            seed=6,
            speed_factor=10000,
        )
        corner = simulated_run(
            store, Cornering(cycles=3, velocities_pct=[100.0], final_hold_s=0.2), "pkm5", seed=7, speed_factor=10000
        )
    return folder, path, corner


def _held_figures(store: Store, run_id: int) -> dict:
    """Every figure from the metrology on the run's cycles held at once (the computation before streaming)."""
    design = PathDesign.from_config(store.run(run_id).config, "test")
    out = {}
    for (shape, velocity), cycles in attained_cycles(store.samples(run_id, kind="path")).items():
        path = design.path(shape)
        stations = path_stations(path, 1.0, 2.0)
        attained = [p for _, _, p, _ in cycles]
        r = path_characteristics(attained, stations)
        u = path_uncertainty(station_crossings(attained, stations)[0], stations, instrument_u_mm=_u_mm(store, run_id))
        figures = {"AT": r.at_mm, "RT": r.rt_mm, "U_AT": u.at.expanded_uncertainty, "U_RT": u.rt.expanded_uncertainty}
        if shape == "rectangle":
            for index, label in ((1, "P3"), (2, "P4"), (3, "P5")):
                corner = path.vertices_mm[index]
                near = [_near(p, corner) for p in attained]
                c = cornering_deviations(near, corner, path.vertices_mm[index - 1], path.vertices_mm[index + 1])
                figures[label] = (c.cr_mm, c.co_mm)
        if shape == "line":
            v_c = design.rated_mm_s * velocity / 100.0
            readings = speed_readings(cycles, 2.0, v_c, design.final_hold_s)
            v = path_velocity_characteristics([path_speed(t, p) for t, p in readings], v_c)
            figures.update(AV=v.av_pct, RV=v.rv_pct, FV=v.fv_mm_s)
        figures["duration"] = float(np.mean([t[-1] - t[0] for _, t, _, _ in cycles]))
        out[(shape, velocity)] = figures
    return out


def _u_mm(store: Store, run_id: int) -> float:
    from bench.reports.content import calibrations_in_force
    from bench.reports.instrument import counts_instrument

    run = store.run(run_id)
    return counts_instrument(run, calibrations_in_force(store, run), 0).sigma_mm or 0.0


def _near(p: np.ndarray, corner: np.ndarray) -> np.ndarray:
    """The samples within 5 mm of the corner in the pass closest to it."""
    distance = np.linalg.norm(p - corner, axis=1)
    closest = int(np.argmin(distance))
    inside = np.flatnonzero(distance >= 5.0)
    lo = inside[inside < closest].max(initial=-1) + 1
    hi = inside[inside > closest].min(initial=len(p))
    return p[lo:hi]


def _streamed_figures(analysis) -> dict:
    out = {}
    for f in analysis.figures:
        figures = {"AT": f.at_mm, "RT": f.rt_mm, "U_AT": f.at_u.expanded_uncertainty}
        figures["U_RT"] = f.rt_u.expanded_uncertainty
        figures.update({label: (cr, co) for label, cr, co in f.corners})
        if f.av_pct is not None:
            figures.update(AV=f.av_pct, RV=f.rv_pct, FV=f.fv_mm_s)
        figures["duration"] = f.duration_s
        out[(f.shape, f.velocity_pct)] = figures
    return out


@pytest.mark.parametrize("which", ["path", "corner"])
def test_the_streamed_figures_equal_those_of_the_cycles_held_at_once(runs, which):
    folder, path, corner = runs
    run_id = {"path": path, "corner": corner}[which]
    with Store(folder / "p.db", read_only=True) as store:
        held = _held_figures(store, run_id)
        streamed = _streamed_figures(analyze_path_run(store, run_id))
    assert set(streamed) == set(held) and len(held) == (2 if which == "path" else 1)
    assert streamed == held  # to the bit: the same numbers through the same formulas
    if which == "corner":
        assert {"P3", "P4", "P5"} <= set(streamed[("rectangle", 100.0)])


def test_samples_in_any_order_give_the_same_figures_and_a_repeated_segment_spoils_its_cycle(runs):
    folder, path, _ = runs
    with Store(folder / "p.db", read_only=True) as store:
        samples = store.samples(path, kind="path")
        in_order = _streamed_figures(analyze_path_run(store, path))
        shuffled = samples[:]
        random.Random(3).shuffle(shuffled)  # segments out of order, cycles interleaved
        assert _streamed_figures(analyze_path_run(store, path, samples=shuffled)) == in_order
        line = [s for s in samples if s.pose == "line"]
        repeated = analyze_path_run(store, path, samples=[*samples, line[-1]])  # cycle 3 of the line: one too many
    figure = next(f for f in repeated.figures if f.shape == "line")
    assert figure.n_cycles == 2 and figure.at_u is None  # 2 complete cycles: too few for the path model


def _peak_bytes(store_path, run_id: int, read) -> int:
    """tracemalloc's peak while ``read(store, run_id)`` runs (the modules it imports imported before)."""
    with Store(store_path, read_only=True) as store:
        tracemalloc.start()
        try:
            read(store, run_id)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()


def _streamed(store: Store, run_id: int) -> None:
    design = PathDesign.from_config(store.run(run_id).config, "test")
    cycles = PathCycles(design, station_mm=1.0, margin_mm=2.0, speed_station_mm=2.0)
    for sample in store.iter_samples(run_id, kind="path"):
        cycles.add(sample)


def _held(store: Store, run_id: int) -> None:
    attained_cycles(store.iter_samples(run_id, kind="path"))


@pytest.mark.slow
def test_peak_memory_does_not_grow_with_the_run_and_the_figure_draws_the_first_cycles(runs, tmp_path):
    folder, path, _ = runs
    peaks: dict = {}
    with Store(folder / "p.db", read_only=True) as store:
        analyze_path_run(store, path)  # every module it imports, imported
    for copies in (3, 7):  # 12 and 24 cycles of each path: both more than the figure keeps
        shutil.copy(folder / "p.db", tmp_path / f"x{copies}.db")
        copy_path_cycles(tmp_path / f"x{copies}.db", path, copies)
        for name, read in (("streamed", _streamed), ("held", _held), ("analysis", analyze_path_run)):
            peaks[name, copies] = _peak_bytes(tmp_path / f"x{copies}.db", path, read)
    assert peaks["held", 7] > 1.8 * peaks["held", 3], peaks  # the measure sees a run held: twice the cycles, ~2x
    # read cycle by cycle: a cycle's memory and the figure's PLOTTED_CYCLES cycles
    assert peaks["streamed", 7] < 1.3 * peaks["streamed", 3], peaks
    # the whole analysis, the path model's Monte Carlo included (its chunk of simulated campaigns is fixed)
    assert peaks["analysis", 7] < 1.3 * peaks["analysis", 3], peaks
    with Store(tmp_path / "x3.db", read_only=True) as store:
        report = collect(store, path)
    assert [f.n_cycles for f in report.analysis.figures] == [12, 12]
    plot = path_plot(report)
    labels = [t.get_text() for t in plot.figure.legends[0].get_texts()]
    assert labels == [f"attained, cycle {i}" for i in range(1, PLOTTED_CYCLES + 1)] + ["commanded"]
    assert f"the first {PLOTTED_CYCLES} of 12 cycles" in plot.caption
