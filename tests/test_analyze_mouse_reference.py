"""``bench analyze mouse`` of a mouse_calibration run's export says what it fitted against: the commanded travel
(the robot under test, right only for a calibrated-axis run) unless ``--reference`` gives the calliper readings, and
then it fits against those (issue 32, item 5: a fit against the robot under test is never silent)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from bench.cli import main

ROOT = Path(__file__).resolve().parents[1]
CALIBRATION = ROOT / "examples" / "mouse_calibration.toml"
#: A calliper that reads 1 % long: a fit against it reads a 1 % larger scale (mm/count) than against the command.
CALLIPER_GAIN = 1.01


@pytest.fixture(scope="module")
def export(tmp_path_factory) -> Path:
    """The ``mouse`` export of a simulated calibrated-axis mouse_calibration run."""
    where = tmp_path_factory.mktemp("mouse")
    protocol = where / "mouse_calibration_axis.toml"
    text = CALIBRATION.read_text()
    assert text.count('reference = "calliper"') == 1
    protocol.write_text(text.replace('reference = "calliper"', 'reference = "calibrated-axis"'))
    store = where / "bench.db"
    assert main(["run", str(protocol), "--sim", "--store", str(store), "--no-progress"]) == 0
    out = where / "mouse.csv"
    assert main(["export", "1", "--store", str(store), "--kind", "mouse", "--out", str(out)]) == 0
    return out


def _calliper_readings(export: Path, path: Path) -> Path:
    """A mouse_reference table (pose, cycle, reference_mm) of a calliper reading CALLIPER_GAIN x the command along
    each move's axis (the x moves' x, the y moves' y)."""
    with export.open() as source, path.open("w", newline="") as target:
        writer = csv.writer(target)
        writer.writerow(["pose", "cycle", "reference_mm"])
        for row in csv.DictReader(source):
            axis = "cmd_x_mm" if row["pose"].startswith("x") else "cmd_y_mm"
            writer.writerow([row["pose"], row["cycle"], CALLIPER_GAIN * float(row[axis])])
    return path


def _fit(capsys, *args: str) -> dict:
    capsys.readouterr()
    assert main(["analyze", "mouse", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_fit_names_its_reference_and_uses_the_calliper_when_given(export, tmp_path, capsys):
    commanded = _fit(capsys, str(export))
    assert commanded["reference"].startswith("the commanded travel (cmd_x_mm, cmd_y_mm)")
    assert "--reference REF.csv (bench export RUN --kind mouse_reference)" in commanded["reference"]
    readings = _calliper_readings(export, tmp_path / "reference.csv")
    calliper = _fit(capsys, str(export), "--reference", str(readings))
    assert calliper["reference"] == f"the calliper readings of {readings}"
    ratio = [c / m for c, m in zip(calliper["scale_mm_per_count"], commanded["scale_mm_per_count"])]
    assert ratio == pytest.approx([CALLIPER_GAIN, CALLIPER_GAIN], rel=2e-3)
    capsys.readouterr()
    assert main(["analyze", "mouse", str(export)]) == 0
    assert capsys.readouterr().out.splitlines()[0] == f"reference: {commanded['reference']}"
