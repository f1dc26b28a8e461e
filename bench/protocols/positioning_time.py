"""ISO 9283 clause 9, minimum positioning time, for the pkm5: the Table 19 step sequence from P1, streamed.

Spec: ``shared/reference/iso9283.md`` §6.15. Each cycle starts at rest at P1 and steps through P1+1 .. P1+7, the
step distances of Table 19 (-10, +20, -50, +100, -200, +500, -1000 mm) read as per-axis increments with
Dx = Dy = Dz (`bench.metrology.minimum_positioning_targets`, [U]). Every target is pre-flighted (reachability,
joint limits, singularity proximity) when the protocol is loaded; a target outside the workspace is skipped, as the
standard presumably intends [U], and the next step starts from the last pose kept (its commanded distance is then
the difference of the two). The skipped steps are stored with the run (``skipped_steps``) and listed in the
report's deviations table.

Every step is one Move followed at once by a streamed capture of kind ``positioning`` (like the arrival of
``iso9283_stabilisation``, :data:`bench.rigs.mice.POSITIONING`): the instrument's position from ``lead_s`` before
the controller reports the move done to ``hold_s`` after it, where ``lead_s`` = the commanded move's duration (the
firmware's constant-speed profile: the leg with the most steps at the set step rate, `PreflightModel.move_s`) plus
``rest_s`` of rest at the previous pose, so each series runs from rest to rest. The positioning time is computed at
analysis time (`bench.reports.positioning_time`) for any limit band; 3 cycles (Table 5 [N]) at 100 % of the rated
velocity, optionally at further velocities and loads.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from bench.errors import ConfigError
from bench.metrology.iso9283_path import MIN_POSITIONING_STEPS_MM, minimum_positioning_targets
from bench.protocols.base import Protocol, register
from bench.protocols.kinematics import robot_model
from bench.protocols.parameters import FloatListParameter, FloatParameter, IntegerParameter
from bench.rigs.mice import POSITIONING
from bench.steps import Capture, Checkpoint, Move, Payload, Plan, Settle, commanded_values

__all__ = ["MinimumPositioningTime", "PositioningStep"]

#: The longest streamed window a capture may ask for (s): the simulated instrument's limit, and minutes of data.
MAX_WINDOW_S = 60.0


class PositioningStep(NamedTuple):
    """One kept step of the sequence."""

    number: int  #: its number in ISO Table 19
    distance_mm: float  #: commanded per-axis distance from the previous kept pose (Dx = Dy = Dz)
    target: tuple[float, ...]  #: the commanded pose, mm


@register
class MinimumPositioningTime(Protocol):
    """ISO 9283 9: the Table 19 steps from P1, each arrival streamed from rest to rest, 3 cycles."""

    name = "iso9283_positioning_time"
    version = "1"
    title = "ISO 9283 minimum positioning time (9)"
    robots = ("pkm5",)
    #: The design the analysis reads (stored with the run): the steps kept and the steps skipped with the reason.
    design_keys = ("steps", "skipped_steps")

    p1_mm = FloatListParameter(
        (110.0, 0.0, 320.0), length=3, unit="mm", description="start pose P1 of the step sequence (the cube centre)"
    )
    steps_mm = FloatListParameter(
        MIN_POSITIONING_STEPS_MM,
        unit="mm",
        minimum=-1000.0,
        maximum=1000.0,
        description="step distances from the previous pose, Dx = Dy = Dz (ISO Table 19)",
    )
    cycles = IntegerParameter(3, minimum=1, description="cycles (ISO Table 5: 3)")
    velocities_pct = FloatListParameter(
        (100.0,),
        unit="%",
        minimum=0.1,
        maximum=100.0,
        description="velocities, % of rated (ISO 9: 100 %, and optimised ones)",
    )
    loads_kg = FloatListParameter(
        (0.0,), unit="kg", minimum=0.0, maximum=30.0, description="loads, kg (ISO 6.6: 100 % rated, optionally 10 %)"
    )
    settle_s = FloatParameter(
        1.0,
        unit="s",
        minimum=0.0,
        maximum=600.0,
        description="dwell at P1 before each cycle (the sequence starts at rest)",
    )
    rest_s = FloatParameter(
        0.5, unit="s", minimum=0.05, maximum=10.0, description="streamed rest before each step's move starts"
    )
    hold_s = FloatParameter(
        3.0,
        unit="s",
        minimum=0.1,
        maximum=MAX_WINDOW_S,
        description="streamed time after the move is reported done (the settling)",
    )

    def validate(self) -> None:
        if not self.steps_mm or any(d == 0 for d in self.steps_mm):
            raise ConfigError(f"{self.source}: steps_mm = {list(self.steps_mm)}, expected non-zero step distances")
        model = robot_model(self.robot)
        if not model.check(model.as_targets([tuple(self.p1_mm)]), self.min_inverse_condition).reachable[0]:
            raise ConfigError(f"{self.source}: p1_mm = {list(self.p1_mm)}: outside the {self.robot} workspace")
        if not self.kept_steps:
            raise ConfigError(
                f"{self.source}: steps_mm = {list(self.steps_mm)}: no step target lies in the "
                f"{self.robot} workspace from p1_mm = {list(self.p1_mm)} "
                f"({self.skipped_steps[0]['reason']})"
            )
        for velocity in self.velocities_pct:
            longest = max(self._move_s(velocity))
            if longest + self.rest_s > MAX_WINDOW_S:
                raise ConfigError(
                    f"{self.source}: a step takes {longest:.1f} s at {velocity:g} %; with rest_s it "
                    f"exceeds the {MAX_WINDOW_S:g} s streamed window, expected shorter steps_mm or a "
                    "higher velocity"
                )

    @cached_property
    def _plan(self) -> tuple[tuple[PositioningStep, ...], tuple[dict[str, Any], ...]]:
        model = robot_model(self.robot)
        targets = minimum_positioning_targets(self.p1_mm, self.steps_mm)
        check = model.check(model.as_targets([tuple(t) for t in targets]), self.min_inverse_condition)
        kept, skipped, previous = [], [], np.asarray(self.p1_mm, float)
        for number, (target, ok, reason) in enumerate(zip(targets, check.reachable, check.reason), start=1):
            if not ok:
                skipped.append(
                    {"step": number, "target_mm": [round(float(v), 6) for v in target], "reason": str(reason)}
                )
                continue
            distance = float(np.mean(target - previous))  # Dx = Dy = Dz: every axis moves the same
            kept.append(PositioningStep(number, distance, tuple(round(float(v), 6) for v in target)))
            previous = target
        return tuple(kept), tuple(skipped)

    @property
    def kept_steps(self) -> tuple[PositioningStep, ...]:
        """The steps driven, in order: (Table 19 number, per-axis distance from the previous kept pose, target)."""
        return self._plan[0]

    @property
    def skipped_steps(self) -> tuple[dict[str, Any], ...]:
        """The steps left out by the pre-flight: number, target and why."""
        return self._plan[1]

    def _move_s(self, velocity_pct: float) -> list[float]:
        """The commanded duration of every kept step at ``velocity_pct`` (s), the firmware's constant-speed move."""
        model = robot_model(self.robot)
        poses = [tuple(self.p1_mm)] + [s.target for s in self.kept_steps]
        starts, ends = model.as_targets(poses[:-1]), model.as_targets(poses[1:])
        return [float(v) for v in model.move_s(starts, ends, np.full(len(ends), velocity_pct))]

    def config(self) -> dict[str, Any]:
        steps = [{"step": s.number, "distance_mm": s.distance_mm, "target_mm": list(s.target)} for s in self.kept_steps]
        return {**super().config(), "steps": steps, "skipped_steps": [dict(s) for s in self.skipped_steps]}

    def steps(self) -> Plan:
        payload = Payload()
        for load in self.loads_kg:
            yield from payload.mount(load)
            for velocity in self.velocities_pct:
                durations = self._move_s(velocity)
                for cycle in range(1, self.cycles + 1):
                    yield Move(tuple(self.p1_mm), velocity, "P1")
                    if self.settle_s > 0:
                        yield Settle(self.settle_s)
                    for step, move_s in zip(self.kept_steps, durations):
                        yield Move(step.target, velocity, f"step {step.number}")
                        yield Capture(
                            f"step {step.number}",
                            cycle,
                            kind=POSITIONING,
                            commanded=commanded_values(step.target),
                            conditions={
                                "velocity_pct": velocity,
                                "load_kg": load,
                                "step": step.number,
                                "step_distance_mm": step.distance_mm,
                                "lead_s": round(move_s + self.rest_s, 3),
                                "hold_s": self.hold_s,
                            },
                        )
                    yield Checkpoint(f"load {load:g} kg, {velocity:g} %, cycle {cycle}")

    def final_steps(self) -> Plan:
        yield from self.return_home()
