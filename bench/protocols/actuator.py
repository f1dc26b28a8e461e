"""The dissertation's linear-actuator accuracy/repeatability test on the actuator bench (000 §8.4; pkm5.md §6.9).

The six actuators stand free under a beam, before assembly (on the assembled robot one leg cannot move alone):
per actuator and commanded travel (10/20/30/40/50 mm), the actuator goes to its start stroke, the operator zeroes
the depth gauge on it, and then, 10 times, the actuator returns to the start stroke and travels to start + travel,
where the operator enters the gauge reading. Every approach is from below (unidirectional). With
``approach = "bidirectional"`` the run is instead ISO 230-2's linear cycle (iso9283.md §7.1 [U]): per actuator, after
zeroing at the start stroke, ``cycles`` times (ISO 230-2: 5) the targets start + travel are approached in increasing
order (direction ↑, from below, after a move ``overrun_mm`` below the lowest target or to the start stroke if lower)
and then, after an overrun ``overrun_mm`` past the highest target, in decreasing order (direction ↓, from above);
every reading stores ``direction`` (+1 ↑, -1 ↓) beside its ``cycle``. The run stores
``fixture = "actuator-bench"``, and the rig's driver must be opened on the bench, or every move is refused.
:func:`actuator_results` turns a run's readings into the dissertation's figures with
:func:`bench.metrology.actuator_tables.analyze_actuators` (Eqs. 8.1-8.3, Table 8-1).
"""

from __future__ import annotations

from typing import Any

from bench.errors import ConfigError
from bench.metrology.documents import ACTUATOR_REPEATS, ACTUATOR_TRAVELS_MM
from bench.protocols.base import Protocol, register
from bench.protocols.parameters import (
    ChoiceParameter,
    FloatListParameter,
    FloatParameter,
    IntegerParameter,
)
from bench.steps import ActuatorMove, Checkpoint, Plan, Prompt, Settle

__all__ = ["ActuatorAccuracy", "actuator_results"]

#: Stroke window of every pkm5 actuator, mm from full retraction (stroke end - leg-length offset, Table 4-2).
STROKE_MM = 66.0
#: ISO 230-2 [U] (iso9283.md §7.1): approaches per target and direction of the standard test cycle.
ISO230_2_CYCLES = 5


@register
class ActuatorAccuracy(Protocol):
    """000 §8.4: each actuator commanded 10-50 mm from its zeroed start, 10 repeats, travel read by depth gauge."""

    name = "actuator_accuracy"
    version = "1"
    title = "Linear-actuator accuracy and repeatability (000 §8.4, Tables A.1-A.7, 8-1)"
    robots = ("pkm5",)

    fixture = ChoiceParameter(
        "actuator-bench",
        choices=("actuator-bench",),
        description="the actuators free-standing; single-axis moves are refused otherwise",
    )
    actuators = FloatListParameter((1, 2, 3, 4, 5, 6), minimum=1, maximum=6, description="actuators tested, 1-6")
    distances_mm = FloatListParameter(
        ACTUATOR_TRAVELS_MM,
        unit="mm",
        minimum=0.1,
        maximum=STROKE_MM,
        description="commanded travels (000: 10, 20, 30, 40, 50 mm)",
    )
    repeats = IntegerParameter(ACTUATOR_REPEATS, minimum=2, description="repeats per travel (000: 10)")
    start_mm = FloatParameter(
        5.0,
        unit="mm",
        minimum=0.0,
        maximum=STROKE_MM,
        description="stroke where the gauge is zeroed, mm from full retraction (home: 5 mm)",
    )
    velocity_pct = FloatParameter(100.0, unit="%", minimum=0.1, maximum=100.0, description="velocity")
    settle_s = FloatParameter(1.0, unit="s", minimum=0.0, maximum=600.0, description="dwell before a reading")
    approach = ChoiceParameter(
        "up",
        choices=("up", "bidirectional"),
        description="up: every target from below (000 §8.4); bidirectional: ISO 230-2 "
        "linear cycles, each target approached up and down",
    )
    cycles = IntegerParameter(
        ISO230_2_CYCLES,
        minimum=2,
        description="bidirectional cycles: approaches per target and direction (ISO 230-2: 5)",
    )
    overrun_mm = FloatParameter(
        2.0,
        unit="mm",
        minimum=0.0,
        maximum=10.0,
        description="bidirectional: travel past the last target before each reversal",
    )

    def validate(self) -> None:
        if any(a != int(a) for a in self.actuators) or len(set(self.actuators)) != len(self.actuators):
            raise ConfigError(f"{self.source}: actuators = {list(self.actuators)}, expected distinct whole numbers 1-6")
        if self.approach == "bidirectional":
            low, high = self._reversals()
            if low < 0.0 or high > STROKE_MM:
                raise ConfigError(
                    f"{self.source}: overrun_mm = {self.overrun_mm:g}: the reversals at {low:g} and "
                    f"{high:g} mm stroke, expected both within 0-{STROKE_MM:g} mm (the actuator's "
                    "stroke)"
                )
        if self.start_mm + max(self.distances_mm) > STROKE_MM:
            raise ConfigError(
                f"{self.source}: start_mm + max(distances_mm) = "
                f"{self.start_mm + max(self.distances_mm):g} mm, expected <= {STROKE_MM:g} mm "
                "(the actuator's stroke)"
            )

    def _reversals(self) -> tuple[float, float]:
        """Strokes of the two reversals of a bidirectional cycle: below the lowest target, past the highest (mm)."""
        return (
            min(self.start_mm, self.start_mm + min(self.distances_mm) - self.overrun_mm),
            self.start_mm + max(self.distances_mm) + self.overrun_mm,
        )

    def steps(self) -> Plan:
        if self.approach == "bidirectional":
            yield from self._bidirectional_steps()
            return
        for axis in (int(a) for a in self.actuators):
            for distance in self.distances_mm:
                label = f"A{axis}/{distance:g}mm"
                yield ActuatorMove(axis, self.start_mm, self.velocity_pct, f"A{axis}/start")
                yield Prompt(
                    f"Actuator {axis} at {self.start_mm:g} mm stroke: zero the depth gauge on it, then confirm",
                    conditions={"zero_actuator": axis},
                )
                for repeat in range(1, self.repeats + 1):
                    yield ActuatorMove(axis, self.start_mm, self.velocity_pct, f"A{axis}/start")
                    yield ActuatorMove(axis, self.start_mm + distance, self.velocity_pct, label)
                    yield Settle(self.settle_s)
                    yield Prompt(
                        f"Actuator {axis}, {distance:g} mm, repeat {repeat}: depth gauge travel",
                        field="travel_mm",
                        unit="mm",
                        minimum=-1.0,
                        maximum=STROKE_MM + 1.0,
                        pose=label,
                        cycle=repeat,
                        kind="actuator_travel",
                        commanded={"cmd_travel_mm": distance},
                        conditions={"actuator": axis, "velocity_pct": self.velocity_pct},
                    )
                yield Checkpoint(f"actuator {axis}, {distance:g} mm")

    def _bidirectional_steps(self) -> Plan:
        """ISO 230-2 linear cycles per actuator: zero at the start, then ``cycles`` x (↑ over the targets, overrun,
        ↓ over the targets, overrun below)."""
        low, high = self._reversals()
        travels = sorted(self.distances_mm)
        for axis in (int(a) for a in self.actuators):
            yield ActuatorMove(axis, self.start_mm, self.velocity_pct, f"A{axis}/start")
            yield Prompt(
                f"Actuator {axis} at {self.start_mm:g} mm stroke: zero the depth gauge on it, then confirm",
                conditions={"zero_actuator": axis},
            )
            for cycle in range(1, self.cycles + 1):
                yield ActuatorMove(axis, low, self.velocity_pct, f"A{axis}/below")
                for direction, order in ((1, travels), (-1, travels[::-1])):
                    for distance in order:
                        yield from self._reading(axis, distance, cycle, direction)
                    if direction == 1:
                        yield ActuatorMove(axis, high, self.velocity_pct, f"A{axis}/overrun")
                yield Checkpoint(f"actuator {axis}, bidirectional cycle {cycle}")

    def _reading(self, axis: int, distance: float, cycle: int, direction: int) -> Plan:
        arrow = "↑" if direction > 0 else "↓"
        label = f"A{axis}/{distance:g}mm{arrow}"
        yield ActuatorMove(axis, self.start_mm + distance, self.velocity_pct, label)
        yield Settle(self.settle_s)
        yield Prompt(
            f"Actuator {axis}, {distance:g} mm approached {'up' if direction > 0 else 'down'} ({arrow}), "
            f"cycle {cycle}: depth gauge travel",
            field="travel_mm",
            unit="mm",
            minimum=-1.0,
            maximum=STROKE_MM + 1.0,
            pose=label,
            cycle=cycle,
            kind="actuator_travel",
            commanded={"cmd_travel_mm": distance},
            conditions={"actuator": axis, "velocity_pct": self.velocity_pct, "direction": direction},
        )

    def final_steps(self) -> Plan:
        from motion import pkm5

        for axis in (int(a) for a in self.actuators):
            yield ActuatorMove(axis, pkm5.DEFAULT_GEOMETRY.home_stroke_mm, 100.0, f"A{axis}/home")


def actuator_results(store: Any, run_id: int) -> dict[int, Any]:
    """Groover accuracy/repeatability (with the mean bias) per actuator of an ``actuator_accuracy`` run.

    Returns ``{actuator: bench.metrology.actuator.GrooverActuator}`` from
    :func:`bench.metrology.actuator_tables.analyze_actuators` on the run's ``actuator_travel`` table (the reduction
    ``bench analyze actuator --robot pkm5`` and the report make); CR is the actuator's leg-length change per step
    (0.00625 mm for actuators 1-4 at full steps, 000 Eq. 8.1). Repeats missing a reading are left out.
    """
    from bench.metrology.actuator_tables import actuator_table, analyze_actuators, robot_control_resolution
    from bench.store import tidy_table

    robot = store.run(run_id).robot
    results = analyze_actuators(
        actuator_table(tidy_table(store, run_id, kind="actuator_travel")),
        control_resolution_mm=robot_control_resolution(robot),
    )
    return {int(r.actuator): r.groover for r in results}
