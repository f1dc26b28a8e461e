"""A toy sensor for tests/test_sensor_kinds.py: a laser tracker that reports the target's position, written as a new
sensor's author would, with nothing registered anywhere but its one record.

The tracker's device is a file of JSON lines, one reading each (``{"seq": 7, "pose": [x, y, z, ...]}``, mm), the
newest last. Each capture stores the position, the reading's number (``tracker_seq``) and the distance from the
tracker's base (``tracker_range_mm``), columns the record declares with their units. In a rehearsal its stand-in is
the robot simulator's truth log, which holds lines of that shape.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from typing import Any

from bench.errors import LinkError
from bench.rigs.interfaces import Measurement
from bench.steps import Capture

_BASE_EXPECTED = "the tracker's base [x, y, z] in mm"
#: The toy tracker's standard uncertainty per axis (mm).
U_MM = 0.005


@dataclass(frozen=True)
class TrackerSpec:
    log: str  #: the tracker's device: its readings as JSON lines
    base_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)


def parse(table: Any) -> TrackerSpec:
    base = table.get("base_mm", list, [0.0, 0.0, 0.0], expected=_BASE_EXPECTED)
    if len(base) != 3 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in base):
        raise table.fail("base_mm", base, _BASE_EXPECTED)
    log = table.get("log", str, required=True, expected="the tracker's device")
    return TrackerSpec(log=log, base_mm=(float(base[0]), float(base[1]), float(base[2])))


class Tracker:
    def __init__(self, path: str, base_mm: tuple[float, float, float]) -> None:
        self.path, self.base_mm = path, base_mm

    def measure(self, capture: Capture) -> Measurement:
        with open(self.path, encoding="utf-8") as handle:
            lines = handle.read().splitlines()
        if not lines:
            raise LinkError(f"toy tracker {self.path}: no reading yet")
        entry = json.loads(lines[-1])
        x, y, z = (float(v) for v in entry["pose"][:3])
        return Measurement(
            {
                "x_mm": x,
                "y_mm": y,
                "z_mm": z,
                "tracker_seq": float(entry["seq"]),
                "tracker_range_mm": math.dist((x, y, z), self.base_mm),
            },
            raw={"line": lines[-1]},
        )

    def settings(self) -> dict[str, Any]:
        # u_mm: its standard uncertainty per axis, which the report's budget reads (a tracker's few micrometres)
        return {"instrument": "toy laser tracker", "log": self.path, "base_mm": list(self.base_mm), "u_mm": U_MM}


def open_tracker(opening: Any) -> Tracker:
    spec: TrackerSpec = opening.spec
    if not os.path.exists(spec.log):
        raise LinkError(f"{opening.station.source}: toy_tracker.log = {spec.log!r}: no such device")
    return Tracker(spec.log, spec.base_mm)


def check(station: Any, spec: TrackerSpec) -> list[Any]:
    from bench.rigs.check import guarded

    def readings() -> str:
        with open(spec.log, encoding="utf-8") as handle:
            return f"{sum(1 for _ in handle)} readings"

    return [guarded("toy_tracker.log", spec.log, "serial", readings)]


def stand_in(station: Any, spec: TrackerSpec, *, folder: str, truth_path: str) -> tuple[TrackerSpec, list[str]]:
    return dataclasses.replace(spec, log=truth_path), []
