"""Tidy tables carry no meaning in row order: every ``bench analyze`` subcommand that reads a CSV gives the same
JSON for any permutation of the table's data rows (hypothesis over the permutations)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "data"


def _rows_of(path: Path) -> tuple[str, list[str]]:
    lines = [line for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    return lines[0], lines[1:]


def _table(header: str, rows) -> tuple[str, list[str]]:
    return header, [",".join(f"{v:.10g}" if not isinstance(v, str) else v for v in row) for row in rows]


def _stabilisation():
    rows = []
    for pose, target in (("P1", 0.0), ("P2", 5.0)):
        for cycle in (1, 2, 3):
            for _i, t in enumerate(np.arange(0.0, 1.0, 0.05)):
                x = target + 0.8 * math.exp(-4 * t) * math.cos(9 * t) * (1 + 0.1 * cycle)
                rows.append((pose, cycle, round(t, 3), x, 0.0, 0.0))
    return _table("pose,cycle,t_s,x_mm,y_mm,z_mm", rows)


def _vap():
    clouds = {"+x": ((0.1, 0, 0), 0.0), "-y": ((0, -0.2, 0), 0.3), "+z": ((0, 0, 0.05), 0.1)}
    return _table(
        "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm,cmd_a_deg,a_deg",
        [
            (f"P1/{d}", c, 0, 0, 0, x + n, y, z, 0, a + n)
            for d, ((x, y, z), a) in clouds.items()
            for c, n in enumerate((-0.01, 0.01, 0.004), start=1)
        ],
    )


def _exchangeability():
    header, rows = _rows_of(EXAMPLES / "iso9283_example.csv")
    cycle = header.split(",").index("cycle")
    return header + ",robot", [f"{r},SN{1 + int(r.split(',')[cycle]) % 2}" for r in rows]


def _tilts():
    return _table(
        "pose,cycle,cmd_b_deg,b_deg,velocity_pct",
        [
            (p, c, cmd, cmd + 0.3 * c - 0.1 * (c % 2) + off, v)
            for p, cmd, off in (("1-1", 10.11, 0.2), ("1-2", -5.5, -0.4))
            for c in (1, 2, 3)
            for v in (50, 100)
        ],
    )


def _depths():
    rows = [f"{p},{c},{cmd},{20 + 0.01 * c:.2f},,50" for p, cmd in (("1-1", 5.0), ("1-2", -3.0)) for c in (1, 2, 3)]
    rows += [
        f"{p},{c},{cmd},,{20 + 50 * math.tan(math.radians(cmd)) + 0.02 * c:.3f},50"
        for p, cmd in (("1-1", 5.0), ("1-2", -3.0))
        for c in (1, 2, 3)
    ]
    return "pose,cycle,cmd_a_deg,depth1_mm,depth2_mm,hole_spacing_mm", rows


def _grid():
    rows = []
    for pose, command in (("P1", (0.0, 0.0, 0.0)), ("P2", (10.0, 0.0, 5.0))):
        for cycle in (1, 2, 3, 4):
            h, v = int(cycle != 2), int(cycle != 3)
            x = f"{command[0] + 0.1 * cycle:g}" if h else ""
            y = f"{command[1] - 0.05 * cycle:g}" if (h or v) else ""
            z = f"{command[2] + 0.02 * cycle:g}" if v else ""
            rows.append(
                f"{pose},{cycle},{command[0]:g},{command[1]:g},{command[2]:g},{h},{v},{2 * h},{3 * v},{x},{y},{z}"
            )
    return (
        "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,horizontal_valid,vertical_valid,horizontal_hits,vertical_hits,"
        "x_mm,y_mm,z_mm"
    ), rows


def _line():
    x = np.linspace(0.0, 100.0, 21)
    return _table(
        "cycle,t_s,x_mm,y_mm,z_mm",
        [(c, 0.1 * i, xi, dy + 0.01 * i % 3, 0.0) for c, dy in enumerate((0.1, 0.3, 0.2), 1) for i, xi in enumerate(x)],
    )


def _corner():
    cut = [(-10, 0), (-1, 0), (0, 1), (0, 10)]
    past = [(-10, 0), (0.5, 0), (0.5, 0.5), (0, 1), (0, 10)]
    return _table(
        "cycle,t_s,x_mm,y_mm",
        [(c, 0.1 * i, x, y) for c, points in ((1, cut), (2, past)) for i, (x, y) in enumerate(points)],
    )


def _velocity():
    rows = []
    for cycle, speeds in ((1, [50] * 4), (2, [52] * 4), (3, [49, 51, 49, 51])):
        x = np.concatenate([[0.0], np.cumsum(np.array(speeds) * 0.1)])
        rows += [(cycle, 0.1 * i, xi, 0.0) for i, xi in enumerate(x)]
    return _table("cycle,t_s,x_mm,y_mm", rows)


def _positioning():
    rows = []
    for step, distance in ((1, -10.0), (2, 20.0)):
        for cycle in (1, 2):
            t = np.round(np.arange(0.0, 1.5, 0.05), 6)
            rows += [
                (step, cycle, ti, xi, 0.0, 0.0)
                for ti, xi in zip(t, np.interp(t, [0.0, 0.2, 1.0, 2.0], [0.0, 0.0, distance, distance]))
            ]
    return _table("step,cycle,t_s,x_mm,y_mm,z_mm", rows)


def _bidirectional():
    readings = {
        (0, "up"): (0.02, 0.04, 0.03),
        (0, "down"): (-0.03, -0.01, -0.02),
        (10, "up"): (10.05, 10.03, 10.04),
        (10, "down"): (9.98, 10.00, 9.99),
    }
    return _table("target_mm,direction,reading_mm", [(t, d, v) for (t, d), values in readings.items() for v in values])


#: (subcommand and options, the table) per ``bench analyze`` subcommand that reads a CSV.
CASES = {
    "iso9283": (["iso9283", "--instrument-u-mm", "0.01"], lambda: _rows_of(EXAMPLES / "iso9283_example.csv")),
    "orientation": (["orientation"], _tilts),
    "orientation (depths)": (["orientation"], _depths),
    "distance": (["distance"], lambda: _rows_of(EXAMPLES / "iso9283_example.csv")),
    "drift": (["drift", "--window-s", "100"], lambda: _rows_of(EXAMPLES / "iso9283_example.csv")),
    "stabilisation": (["stabilisation", "--band-mm", "0.1", "0.5"], _stabilisation),
    "actuator": (["actuator"], lambda: _rows_of(EXAMPLES / "actuator_tables_a1_a6.csv")),
    "payload": (["payload"], lambda: _rows_of(EXAMPLES / "payload_table_a14.csv")),
    "mouse (2x2 fit)": (["mouse"], lambda: _rows_of(EXAMPLES / "mouse_matrix_example.csv")),
    "mouse (increments)": (["mouse"], lambda: _rows_of(EXAMPLES / "mouse_table_a28.csv")),
    "grid-positioning": (["grid-positioning"], _grid),
    "vap": (["vap"], _vap),
    "exchangeability": (["exchangeability"], _exchangeability),
    "cornering": (["cornering", "--corner", "0,0", "--from=-10,0", "--to", "0,10"], _corner),
    "path-velocity": (["path-velocity", "--commanded-mm-s", "50"], _velocity),
    "positioning-time": (["positioning-time", "--band-mm", "0.5"], _positioning),
    "iso230-2": (["iso230-2"], _bidirectional),
}


def _same(a, b, where="") -> None:
    """JSON values equal up to float rounding; object keys compared as sets (their order means nothing)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for key in a:
            _same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{where}: {a} != {b}"
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, (int, float)):
        assert b == pytest.approx(a, rel=1e-9, abs=1e-12), f"{where}: {a} != {b}"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def _analyze(capsys, argv, path) -> dict:
    code = main(["analyze", argv[0], str(path), *argv[1:], "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_analysis_ignores_the_order_of_the_rows(name, tmp_path_factory, capsys):
    argv, table = CASES[name]
    header, rows = table()
    folder = tmp_path_factory.mktemp("order")
    original = folder / "original.csv"
    original.write_text("\n".join([header, *rows]) + "\n")
    reference = _analyze(capsys, argv, original)

    @settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(st.permutations(range(len(rows))))
    def check(order):
        shuffled = folder / "shuffled.csv"
        shuffled.write_text("\n".join([header, *(rows[i] for i in order)]) + "\n")
        _same(reference, _analyze(capsys, argv, shuffled), name)

    check()


def test_the_mouse_increments_need_the_reading_number(tmp_path, capsys):
    # the increments are differences of consecutive readings: without their numbers the row order would carry them
    path = tmp_path / "m.csv"
    path.write_text("distance_mm,position\n5,N/A\n5,951\n5,926\n")
    assert main(["analyze", "mouse", str(path)]) == 2
    err = capsys.readouterr().err
    assert "missing column reading" in err and len(err.strip().splitlines()) == 1
    path.write_text("reading,distance_mm,position\n1,5,N/A\n2,5,951\n2,5,926\n")
    assert main(["analyze", "mouse", str(path)]) == 2
    assert "column reading: 2 repeated" in capsys.readouterr().err
    path.write_text("reading,distance_mm,position\n3,5,902\n1,5,N/A\n2,5,951\n4,5,877\n")
    assert main(["analyze", "mouse", str(path), "--json"]) == 0
    five = json.loads(capsys.readouterr().out)["distances"]["5"]
    assert (five["n"], five["mean_delta_counts"]) == (2, pytest.approx((951 - 877) / 2))  # in reading order
