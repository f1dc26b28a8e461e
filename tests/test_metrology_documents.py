"""The documents' prescribed test figures (bench.metrology.documents): the protocols' defaults, the laser grid's
defaults and the reference values they come from; and the reports read them from there, never from a protocol or a
sensor (imports flow cli -> protocols -> sensors/store -> motion; reports read the store)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from bench.metrology import documents
from bench.protocols import PROTOCOLS

REPORTS = Path(__file__).resolve().parents[1] / "bench" / "reports"
#: What a report may import from bench: itself, the store, pure metrology and the error family (motion is pure).
REPORT_IMPORTS = ("bench.reports", "bench.store", "bench.metrology", "bench.errors", "bench.robot_kinds")


def _bench_imports(path: Path) -> list[str]:
    modules = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules.append(node.module)
        elif isinstance(node, ast.Import):
            modules += [alias.name for alias in node.names]
    return [m for m in modules if m.startswith("bench.")]  # `from bench import __version__` is fine


@pytest.mark.parametrize("path", sorted(REPORTS.glob("*.py")), ids=lambda p: p.name)
def test_a_report_module_imports_only_the_store_metrology_and_errors(path):
    # function-level imports count too: that is where protocols and sensors had crept in
    stray = [m for m in _bench_imports(path) if not m.startswith(REPORT_IMPORTS)]
    assert stray == [], f"{path.name} imports {stray}"


def test_the_protocols_default_to_the_documents_figures():
    ladder = PROTOCOLS["payload_ladder"]().config()
    assert ladder["loads_kg"] == [float(v) for v in documents.LADDER_KG]
    assert ladder["lift_mm"] == documents.LADDER_LIFT_MM == 50.42
    positioning = PROTOCOLS["delta_positioning"]().config()
    assert positioning["poses"] == {label: list(pose) for label, pose in documents.POSITIONING_POSES.items()}
    assert positioning["cycles"] == documents.POSITIONING_READINGS == 15
    actuator = PROTOCOLS["actuator_accuracy"]().config()
    assert actuator["distances_mm"] == list(documents.ACTUATOR_TRAVELS_MM)
    assert actuator["repeats"] == documents.ACTUATOR_REPEATS == 10
    hits = PROTOCOLS["lasergrid_hits"]().config()
    assert [-z for z in hits["heights_mm"]] == list(documents.GRID_HEIGHTS_MM)
    assert hits["attempts"] == documents.GRID_HIT_ATTEMPTS and hits["offset_mm"] == list(documents.GRID_OFFSET_MM)
    assert hits["spread"] ** 2 == documents.GRID_SENSORS


def test_the_figures_are_the_documents_values():
    # 000 Table A.14: 20 loads from 0.45 to 25.23 kg, ascending; thesis §8.4.2 in cm: (0,0,-20), (-7,-7,-18), (5,-5,-16)
    assert len(documents.LADDER_KG) == 20 and list(documents.LADDER_KG) == sorted(documents.LADDER_KG)
    assert (documents.LADDER_KG[0], documents.LADDER_KG[-1]) == (0.45, 25.23)
    centimetres = [(0, 0, -20), (-7, -7, -18), (5, -5, -16)]
    assert list(documents.POSITIONING_POSES.values()) == [tuple(10.0 * v for v in pose) for pose in centimetres]


def test_the_laser_grid_defaults_are_the_documents():
    from bench.sensors.lasergrid import LASER_OFFSETS_MM, GridGeometry

    geometry = GridGeometry()
    assert geometry.calibration_id == documents.LASERGRID_GUI_PLACEMENT
    # the resolution: where the lasers fall between sensors, i.e. their offsets modulo the pitch, are 2.5 mm apart
    for screen in (geometry.horizontal, geometry.vertical):
        phases = np.unique(np.round(np.mod(LASER_OFFSETS_MM, screen.pitch_mm), 9))
        assert np.diff(np.append(phases, screen.pitch_mm)) == pytest.approx(documents.GRID_RESOLUTION_MM)
