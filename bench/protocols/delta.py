"""The delta thesis's tests on the 4-RSS delta robot with the laser grid (reference delta4-lasergrid.md §7.2-7.3).

- ``delta_positioning``: 15 readings at each of 3 poses, (0, 0, -200), (-70, -70, -180) and (50, -50, -160) mm
  (thesis §8.4.2, Appendix D1), unidirectional order, a Checkpoint after each cycle.
- ``lasergrid_hits``: hit repeatability of the laser grid: 16 sensors of the horizontal screen in a 4 x 4 spread,
  at heights 140, 170 and 200 mm below the base, 25 attempts each (§8.4.3, Appendix D2). Each attempt re-approaches
  from a seeded random offset of 10-20 mm [choice of the reference, §7.3] and captures one sensor report (kind
  ``grid_hit``: the expected sensor, whether it was reported, whether any sensor was).
"""

from __future__ import annotations

import numpy as np

from bench.metrology.documents import GRID_HIT_ATTEMPTS, GRID_OFFSET_MM, POSITIONING_POSES, POSITIONING_READINGS
from bench.protocols.base import Protocol, register
from bench.protocols.parameters import (
    FloatListParameter,
    FloatParameter,
    IntegerParameter,
    PoseTableParameter,
)
from bench.steps import (
    Capture,
    Checkpoint,
    Move,
    Plan,
    Settle,
    commanded_values,
    visit,
)

__all__ = ["DeltaPositioning", "LaserGridHits", "grid_targets"]


class _DeltaProtocol(Protocol):
    robots = ("delta4",)
    settle_s = FloatParameter(0.5, unit="s", minimum=0.0, maximum=600.0, description="dwell before a reading")

    def __init__(self, source: str = "parameters", **values) -> None:
        values.setdefault("robot", "delta4")
        super().__init__(source, **values)

    def final_steps(self) -> Plan:
        yield from self.return_home()


@register
class DeltaPositioning(_DeltaProtocol):
    """Thesis §8.4.2: positioning accuracy, 15 readings at 3 poses."""

    name = "delta_positioning"
    version = "1"
    title = "Delta robot positioning test (thesis §8.4.2), 3 poses x 15"

    cycles = IntegerParameter(POSITIONING_READINGS, minimum=2, description="readings per pose (thesis: 15)")
    poses = PoseTableParameter(
        POSITIONING_POSES,
        min_width=3,
        max_width=3,
        description="labelled poses, mm (thesis: (0,0,-20), (-7,-7,-18), (5,-5,-16) cm)",
    )

    def steps(self) -> Plan:
        for cycle in range(1, self.cycles + 1):
            for label, target in self.poses.items():
                yield from visit(label, target, cycle, velocity_pct=100.0, settle_s=self.settle_s)
            yield Checkpoint(f"cycle {cycle}")


def grid_targets(spread: int = 4, size: int = 16, pitch_mm: float = 10.0, first_mm: float = -75.0):
    """(i, j, x_mm, y_mm) of ``spread`` x ``spread`` sensors evenly spread over the horizontal screen."""
    cells = np.round(np.linspace(1, size - 2, spread)).astype(int)
    return [(int(i), int(j), first_mm + pitch_mm * i, first_mm + pitch_mm * j) for j in cells for i in cells]


@register
class LaserGridHits(_DeltaProtocol):
    """Thesis §8.4.3: hit repeatability of 16 sensors x 25 attempts at three heights."""

    name = "lasergrid_hits"
    version = "1"
    title = "Laser-grid hit repeatability (thesis §8.4.3), 16 sensors x 25 attempts"

    attempts = IntegerParameter(GRID_HIT_ATTEMPTS, minimum=1, description="attempts per sensor and height (thesis: 25)")
    heights_mm = FloatListParameter(
        (-140.0, -170.0, -200.0),
        unit="mm",
        minimum=-260.0,
        maximum=-100.0,
        description="z of the end effector (thesis: 14, 17, 20 cm below the base)",
    )
    spread = IntegerParameter(4, minimum=1, maximum=16, description="sensors per side of the tested spread")
    offset_mm = FloatListParameter(
        GRID_OFFSET_MM,
        length=2,
        unit="mm",
        minimum=0.0,
        maximum=50.0,
        description="range of the random re-approach offset",
    )
    seed = IntegerParameter(
        0,
        minimum=0,
        maximum=2**63 - 1,
        counts=False,
        description="seed of the re-approach offsets (the plan is reproducible)",
    )

    def steps(self) -> Plan:
        rng = np.random.default_rng(self.seed)
        low, high = self.offset_mm
        for z in self.heights_mm:
            for i, j, x, y in grid_targets(self.spread):
                label = f"H{i},{j}@{-z:g}"
                for attempt in range(1, self.attempts + 1):
                    angle = rng.uniform(0, 2 * np.pi)
                    radius = rng.uniform(low, high)
                    yield Move((x + radius * np.cos(angle), y + radius * np.sin(angle), z), 100.0, f"{label}/pre")
                    yield Move((x, y, z), 100.0, label)
                    yield Settle(self.settle_s)
                    yield Capture(
                        label,
                        attempt,
                        kind="grid_hit",
                        commanded=commanded_values((x, y, z)),
                        conditions={"expected_i": i, "expected_j": j},
                    )
                yield Checkpoint(f"sensor ({i}, {j}) at z = {z:g} mm")
