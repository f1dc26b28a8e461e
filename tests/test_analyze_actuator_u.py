"""``bench analyze actuator`` prints the U of Groover's repeatability and accuracy in its table, as the pose table
prints U_AP and U_RP (issue 32, item 1: the text rounded the figures by a U it never showed)."""

from __future__ import annotations

import json
from pathlib import Path

from bench.cli import main

TABLES = Path(__file__).resolve().parents[1] / "examples" / "data" / "actuator_tables_a1_a6.csv"


def test_the_table_shows_the_u_of_repeatability_and_accuracy(capsys):
    assert main(["analyze", "actuator", str(TABLES), "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)["actuators"]
    assert main(["analyze", "actuator", str(TABLES)]) == 0
    header, *rows = capsys.readouterr().out.splitlines()
    columns = header.split()
    assert columns[2:6] == ["repeat_mm", "accuracy_mm", "U_repeat", "U_accuracy"]
    shown = {row.split()[0]: row.split() for row in rows[: len(figures)]}
    assert set(shown) == set(figures) == {"1", "2", "3", "4", "5", "6"}
    for actuator, cells in shown.items():
        for column, key in (("U_repeat", "U_repeatability_mm"), ("U_accuracy", "U_accuracy_mm")):
            printed = float(cells[columns.index(column)])
            assert 0 < figures[actuator][key] < 0.1  # Table 8-1's actuators: U of a few hundredths of a mm
            assert abs(printed - figures[actuator][key]) <= 0.0005 + 1e-12, (actuator, column, printed)
