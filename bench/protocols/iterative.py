"""Iterative correction from the sensor: the delta thesis's closed-loop block diagram made real (docs/calibration.md).

For each target: move to the command (first the target itself), settle, measure, and correct the command by the
measured error, ``c_{k+1} = c_k - (m_k - T)`` on every position axis the instrument measured, until the error is
within ``tolerance_mm`` on each measured axis or ``iterations`` moves were made. Every iteration is a ``pose``
sample of its own: pose = the target's label, cycle = the iteration, ``cmd_*`` = the command of that iteration (in
iteration 1 the target itself), so the stored run holds each iteration's error, measured - the cycle-1 command.
The plan adapts to the readings: the run's pre-flight proves the first command of every target, and the runner
checks every corrected one alone, by the same model and geometry, before it is commanded
(:meth:`bench.protocols.plan.PlanSummary.require`).
"""

from __future__ import annotations

import numpy as np

from bench.protocols.base import Protocol, register
from bench.protocols.parameters import FloatParameter, IntegerParameter, PoseTableParameter
from bench.steps import Capture, Move, Plan, Settle, commanded_values

__all__ = ["IterativeCorrection", "corrected_command"]

_AXES = ("x_mm", "y_mm", "z_mm")


def corrected_command(command, target, measured: dict) -> tuple[tuple[float, ...], dict[str, float]]:
    """The next command ``c - (m - T)`` on the position axes ``measured`` holds (finite), and the errors ``m - T``
    by axis; the other coordinates keep their command."""
    errors = {
        axis: float(measured[axis]) - float(target[i])
        for i, axis in enumerate(_AXES)
        if i < len(target) and axis in measured and np.isfinite(measured[axis])
    }
    nxt = list(command)
    for i, axis in enumerate(_AXES):
        if axis in errors:
            nxt[i] = float(command[i]) - errors[axis]
    return tuple(nxt), errors


@register
class IterativeCorrection(Protocol):
    """Move, measure, correct the command by the measured error, repeat until within tolerance (per target)."""

    name = "iterative_correction"
    version = "1"
    title = "Iterative correction of the command from the measured position"

    poses = PoseTableParameter({"T1": (110.0, 0.0, 320.0)}, description="labelled targets (mm, deg)")
    tolerance_mm = FloatParameter(
        0.05,
        unit="mm",
        minimum=0.0,
        maximum=100.0,
        description="largest |error| on every measured axis that ends the correction",
    )
    iterations = IntegerParameter(3, minimum=1, maximum=20, description="most moves per target")
    settle_s = FloatParameter(0.5, unit="s", minimum=0.0, maximum=600.0, description="dwell before each reading")

    def steps(self) -> Plan:
        for label, target in self.poses.items():
            command = tuple(float(v) for v in target)
            for iteration in range(1, self.iterations + 1):
                yield Move(command, 100.0, f"{label}/{iteration}")
                if self.settle_s > 0:
                    yield Settle(self.settle_s)
                measured = yield Capture(label, iteration, commanded=commanded_values(command))
                command, errors = corrected_command(command, target, measured or {})
                if errors and max(abs(e) for e in errors.values()) <= self.tolerance_mm:
                    break

    def final_steps(self) -> Plan:
        yield from self.return_home()
