"""ISO 230-2 bidirectional figures from a tidy table (``bench analyze iso230-2``) and their report figure:
hand-computed values, row order without meaning, one-line errors, fonts >= 7 pt on A4."""

import json

import numpy as np
import pytest
from figure_support import printed_font_sizes

from bench.cli import main
from bench.metrology.bidirectional_tables import analyze_bidirectional
from bench.metrology.tables import read_table_csv
from bench.reports.bidirectional import bidirectional_plot
from bench.reports.plots import MIN_FONT_PT, PRINT_WIDTH_IN

# up/down deviations at targets 0, 10, 25 mm: means ↑ 0.03, 0.04, 0.02 and ↓ -0.02, -0.01, -0.04; s = 0.01·√2
READINGS = {
    (0, "up"): (0.02, 0.04),
    (0, "down"): (-0.03, -0.01),
    (10, "up"): (10.05, 10.03),
    (10, "down"): (9.98, 10.00),
    (25, "up"): (25.01, 25.03),
    (25, "down"): (24.97, 24.95),
}


def _table(tmp_path, shuffle=False, axis=None, readings=READINGS, direction_names=("up", "down")):
    names = dict(zip(("up", "down"), direction_names))
    rows = [
        f"{target},{names[d]},{value}" + (f",{axis}" if axis else "")
        for (target, d), values in readings.items()
        for value in values
    ]
    if shuffle:
        rows = [rows[i] for i in np.random.default_rng(3).permutation(len(rows))]
    path = tmp_path / "bi.csv"
    path.write_text("\n".join(["target_mm,direction,reading_mm" + (",axis" if axis else ""), *rows]) + "\n")
    return path


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    "shuffle, names", [(False, ("up", "down")), (True, ("+", "-")), (True, ("forward", "backward"))]
)
def test_hand_computed_bidirectional_figures(capsys, tmp_path, shuffle, names):
    code, out, _ = _run(capsys, "analyze", "iso230-2", str(_table(tmp_path, shuffle, direction_names=names)), "--json")
    assert code == 0
    axis = json.loads(out)["axes"]["1"]
    s = 0.01 * np.sqrt(2)
    assert axis["reversal_mm"] == pytest.approx([0.05, 0.05, 0.06])
    assert axis["B_mm"] == pytest.approx(0.06)
    assert axis["R_up_mm"] == pytest.approx(4 * s) and axis["R_down_mm"] == pytest.approx(4 * s)
    assert axis["R_mm"] == pytest.approx(4 * s + 0.06)  # 2s↑ + 2s↓ + |B| at 25 mm
    assert axis["E_mm"] == pytest.approx(0.04 - -0.04)
    assert axis["M_mm"] == pytest.approx(0.015 - -0.01)  # bidirectional means 0.005, 0.015, -0.01
    assert axis["A_mm"] == pytest.approx((0.04 + 2 * s) - (-0.04 - 2 * s))
    assert (axis["n_up"], axis["n_down"]) == (2, 2)


def test_one_result_per_axis(capsys, tmp_path):
    first = _table(tmp_path, axis="X").read_text().splitlines()
    second = [line.replace(",X", ",Y") for line in first[1:]]
    path = tmp_path / "two.csv"
    path.write_text("\n".join([*first, *second]) + "\n")
    code, out, _ = _run(capsys, "analyze", "iso230-2", str(path), "--json")
    assert code == 0 and list(json.loads(out)["axes"]) == ["X", "Y"]


def test_errors_are_one_line(capsys, tmp_path):
    path = _table(tmp_path)
    bad = tmp_path / "bad.csv"
    bad.write_text(path.read_text().replace("25,down,24.95", "25,sideways,24.95"))
    code, _, err = _run(capsys, "analyze", "iso230-2", str(bad))
    assert code == 2 and "column direction: 'sideways'" in err and len(err.strip().splitlines()) == 1
    bad.write_text(path.read_text().replace("25,down,24.95\n", ""))
    code, _, err = _run(capsys, "analyze", "iso230-2", str(bad))
    assert code == 2 and "down approaches per target differ (0: 2, 10: 2, 25: 1)" in err
    code, _, err = _run(capsys, "analyze", "iso230-2", str(path), "--plot", str(tmp_path / "f.txt"))
    assert code == 2 and "expected a file name ending in .svg" in err


def test_plot_is_written_and_readable_on_a4(capsys, tmp_path):
    target = tmp_path / "figure.svg"
    code, out, _ = _run(capsys, "analyze", "iso230-2", str(_table(tmp_path)), "--plot", str(target))
    assert code == 0 and target.read_text().lstrip().startswith("<?xml") and "figure written" in out
    plot = bidirectional_plot(analyze_bidirectional(read_table_csv(_table(tmp_path))))
    sizes = printed_font_sizes(plot)
    assert sizes and min(sizes) >= MIN_FONT_PT - 1e-9
    assert plot.figure.get_size_inches()[0] == pytest.approx(PRINT_WIDTH_IN, abs=0.01)
    assert len(plot.figure.legends) == 1
