"""The report of a path run: its results table from the stored streamed samples, the deviations rows of clause 8,
and the figure of the commanded and attained paths at print size."""

from __future__ import annotations

import pytest
from figure_support import printed_font_sizes, same_scale, small_multiples
from reports_runs import html_tables, pdf_text, simulated_path_run

from bench.metrology.formatting import format_measured
from bench.reports import collect, write_report
from bench.reports.path import path_plot
from bench.reports.path_run import analyze_path_run
from bench.reports.plots import MIN_FONT_PT
from bench.store import Store


@pytest.fixture(scope="module")
def path_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("path")
    run_id = simulated_path_run(folder, shape="both", cycles=2, seed=6)
    with Store(folder / "p.db", read_only=True) as store:
        figures = analyze_path_run(store, run_id).figures
    return folder, run_id, figures


def test_the_report_prints_the_figures_the_analysis_computes(path_run):
    folder, run_id, figures = path_run
    paths = write_report(folder / "p.db", run_id, folder / "out")
    tables = html_tables(paths.html)
    header, *rows = tables["path"]
    assert header[:6] == ["Path", "v (%)", "v_c (mm/s)", "Cycles", "AT ± U (mm)", "RT ± U (mm)"]
    by_shape = {f.shape: f for f in figures}
    assert [r[0] for r in rows] == ["circle", "line"]
    for row in rows:  # 2 cycles: too few for the path model, so AT and RT are printed without a U, to 1 µm
        f = by_shape[row[0]]
        assert row[4] == f"{f.at_mm:.3f}" and row[5] == f"{f.rt_mm:.3f}" and row[3] == "2"
        assert f.at_u is None and f.rt_u is None
    line, f = next(r for r in rows if r[0] == "line"), by_shape["line"]
    # AV and RV carry their U from 2 cycles already (Student's k, the chi pivot), the value rounded by it
    assert line[8] == format_measured(f.av_pct, f.av_u.expanded_uncertainty, signed=True) and " ± " in line[8]
    assert line[9] == format_measured(f.rv_pct, f.rv_u.expanded_uncertainty) and line[10] == f"{f.fv_mm_s:.3f}"
    assert next(r for r in rows if r[0] == "circle")[8] == "—"  # no path velocity on the circle
    deviations = {r[1]: r for r in tables["deviations"][1:]}
    assert tables["deviations"][0][:5] == ["Clause", "Topic", "ISO 9283 requirement", "What was done", "Status"]
    assert deviations["cycles"][4] == "deviates" and deviations["stations"][4] == "conforms"  # 2 of 10 cycles
    assert "chord error <= 0.01 mm" in deviations["interpolation"][3]
    # 8.4 is refused with its reason: the orientation is not streamed along a path (calliper at stops only)
    assert deviations["reorientation"][4] == "deviates" and "not measured" in deviations["reorientation"][5]
    text = pdf_text(paths.pdf)
    assert "SIMULATED DATA" in text and f"bench analyze path-run {run_id}" in text


def test_the_path_figure_is_readable_at_print_size_with_one_legend_and_one_scale(path_run):
    folder, run_id, _ = path_run
    with Store(folder / "p.db", read_only=True) as store:
        report = collect(store, run_id)
    plot = path_plot(report)
    assert min(printed_font_sizes(plot)) >= MIN_FONT_PT - 1e-9
    grid, panels = small_multiples(plot)
    assert [panel.title for panel in panels] == ["line at 100 %", "circle at 100 %"]
    assert same_scale(grid) and grid.xlim == grid.ylim  # one scale, u and v alike: the paths keep their shape
    assert len(plot.figure.legends) == 1 and not any(a.get_legend() for a in plot.figure.axes)
    labels = [t.get_text() for t in plot.figure.legends[0].get_texts()]
    assert labels == ["attained, cycle 1", "attained, cycle 2", "commanded"]
