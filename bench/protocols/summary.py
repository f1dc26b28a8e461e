"""What a plan will do and what its pre-flight proved: :class:`PlanSummary` (counts, distinct targets and their
check, actuator strokes, duration), made by one walk of the plan (:func:`bench.protocols.plan.summarize`), and the
proof the runner asks before every move (:meth:`PlanSummary.require`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from bench.errors import UnreachableTarget
from bench.protocols.kinematics import DEFAULT_SINGULARITY_THRESHOLD, PreflightModel, robot_model
from bench.steps import ActuatorMove, Move

__all__ = ["AxisStrokes", "PlanSummary", "StrokeTally", "model_of", "target_key"]


@dataclass(frozen=True)
class AxisStrokes:
    """The strokes one actuator of the actuator bench will be commanded to, pre-flighted against its window."""

    axis: int
    window_mm: tuple[float, float]  #: the stroke window the driver enforces, mm from full retraction
    strokes_mm: tuple[float, ...]  #: distinct commanded strokes, ascending
    moves: int
    move_s: float  #: estimated time of its moves at the commanded velocity
    refused: tuple[str, ...] = ()  #: one line per refused move


@dataclass(frozen=True)
class PlanSummary:
    """What a protocol will do: counts, distinct targets and their pre-flight, and the estimated duration."""

    protocol: str
    robot: str
    counts: dict[str, int]
    labels: tuple[str, ...]
    targets: np.ndarray
    reachable: np.ndarray
    reasons: tuple[str, ...]
    proximity: np.ndarray
    move_s: float
    settle_s: float
    prompt_s: float
    capture_s: float
    #: per actuator of the actuator bench, its commanded strokes and their pre-flight
    strokes: tuple[AxisStrokes, ...] = ()
    #: settings beyond a documented failure or limit (:meth:`bench.protocols.base.Protocol.limit_warnings`)
    warnings: tuple[str, ...] = ()
    #: steps of the plan that store a sample (captures and reading prompts; the clean-up plan stores none)
    samples: int = 0
    #: of those, the operator's readings (prompts for a value)
    readings: int = 0
    #: the step a resumed run acts from (the last checkpoint before the first sample not stored); None: all stored
    resume_at: int | None = None
    #: the stored samples (of a run being resumed) the walk sent back to the plan; 0 for a new run
    stored_samples: int = 0
    #: what a station must provide to run it (:func:`required_capabilities`)
    capabilities: frozenset[str] = frozenset()

    #: the model (with the geometry) the targets were checked by, and the singularity threshold
    model: PreflightModel | None = field(default=None, repr=False, compare=False)
    threshold: float = DEFAULT_SINGULARITY_THRESHOLD

    @cached_property
    def _proved(self) -> frozenset[tuple[float, ...]]:
        return frozenset(tuple(row) for row in self.targets[self.reachable].tolist())

    def require(self, step: Move | ActuatorMove) -> None:
        """Refuse (``UnreachableTarget``) the target of ``step`` unless it is proved reachable: one this pre-flight
        proved, or, for a target the plan chose only during the run (it adapts to the readings), checked here alone
        by the same model before it is commanded."""
        if isinstance(step, ActuatorMove):
            if not any(a.axis == step.axis and float(step.stroke_mm) in a.strokes_mm for a in self.strokes):
                StrokeTally(self.model.geometry if self.model else None).check(step)
            return
        model = self.model or robot_model(self.robot)
        key = target_key(model, step.target)
        if key in self._proved:
            return
        check = model.check(np.array([key]), self.threshold)
        if not check.reachable[0]:
            raise UnreachableTarget(
                f"target {step.label or 'of the run'} {_describe(np.array(key), self.robot)} is not reachable: "
                f"{check.reason[0]} (the plan chose it during the run; nothing was moved to it)"
            )

    @property
    def actuator_problems(self) -> tuple[str, ...]:
        """Refused actuator-bench moves (stroke outside the actuator's window), one line each."""
        return tuple(line for axis in self.strokes for line in axis.refused)

    @property
    def estimated_s(self) -> float:
        return self.move_s + self.settle_s + self.prompt_s + self.capture_s

    @property
    def ok(self) -> bool:
        return bool(np.all(self.reachable)) and not self.actuator_problems

    def problems(self) -> list[str]:
        """One line per refused target, naming its label and coordinates."""
        return [
            f"target {self.labels[i]} {_describe(self.targets[i], self.robot)} is not reachable: {self.reasons[i]}"
            for i in np.flatnonzero(~self.reachable)
        ] + list(self.actuator_problems)

    def refuse_unless_ok(self, source: str) -> PlanSummary:
        """This summary, or ``UnreachableTarget`` naming the first refused target (and how many more)."""
        if not self.ok:
            problems = self.problems()
            more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
            raise UnreachableTarget(f"{source}: {problems[0]}{more}")
        return self

    def checked_by(self, geometry: Any) -> PlanSummary | None:
        """This pre-flight's distinct targets checked again by ``geometry`` (the robot's, e.g. a kinematic
        calibration in force), without walking the plan again; None when that takes a walk (actuator-bench strokes
        by another geometry than they were checked by). The duration estimate stays the first geometry's."""
        model = model_of(self.robot, geometry)
        if self.model is not None and model.geometry is self.model.geometry:
            return self
        if self.strokes:
            return None
        check = model.check(self.targets, self.threshold)
        return replace(
            self,
            reachable=check.reachable,
            reasons=tuple(str(r) for r in check.reason),
            proximity=check.proximity,
            model=model,
        )

    def lines(self) -> list[str]:
        """The human-readable summary printed by ``bench run --dry-run``."""
        out = [
            f"protocol {self.protocol} on {self.robot}: " + ", ".join(f"{n} {kind}" for kind, n in self.counts.items())
        ]
        out.append(
            f"estimated duration {_hms(self.estimated_s)} (moves {_hms(self.move_s)}, settling "
            f"{_hms(self.settle_s)}, captures {_hms(self.capture_s)}, prompts {_hms(self.prompt_s)}) at "
            "real speed"
        )
        out.extend(f"WARNING: {line}" for line in self.warnings)
        if self.labels or not self.strokes:
            out.append(f"{len(self.labels)} distinct targets:")
        for i, label in enumerate(self.labels):
            status = "ok" if self.reachable[i] else f"REFUSED: {self.reasons[i]}"
            out.append(
                f"  {label:>8}  {_describe(self.targets[i], self.robot)}  "
                f"singularity proximity {self.proximity[i]:.3f}  {status}"
            )
        if self.strokes:
            moves = sum(a.moves for a in self.strokes)
            out.append(
                f"actuator bench: {len(self.strokes)} actuator(s), {moves} single-axis moves "
                f"({_hms(sum(a.move_s for a in self.strokes))}); strokes in mm from full retraction:"
            )
        for a in self.strokes:
            status = (
                "ok"
                if not a.refused
                else f"REFUSED: {a.refused[0]}" + (f" (and {len(a.refused) - 1} more)" if len(a.refused) > 1 else "")
            )
            out.append(
                f"  actuator {a.axis}  strokes {', '.join(f'{v:g}' for v in a.strokes_mm)} mm  window "
                f"{a.window_mm[0]:g}-{a.window_mm[1]:g} mm  {a.moves} moves  {_hms(a.move_s)}  {status}"
            )
        return out


def _describe(target: np.ndarray, robot: str) -> str:
    fields = robot_model(robot).target_fields
    return "(" + ", ".join(f"{f.rsplit('_', 1)[0]} {v:.2f} {f.rsplit('_', 1)[1]}" for f, v in zip(fields, target)) + ")"


def _hms(seconds: float) -> str:
    seconds = round(seconds)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def model_of(robot: str, geometry: Any) -> PreflightModel:
    """The pre-flight model of ``robot`` by ``geometry`` (None or the documented one: the cached model)."""
    model = robot_model(robot)
    if geometry is None or geometry is getattr(model.kinematics, "geometry", None):
        return model
    return replace(model, geometry=geometry)


def target_key(model: PreflightModel, target: Sequence[float]) -> tuple[float, ...]:
    """``target`` as a row of ``model``'s target fields in floats (a short pkm5 row padded with zero angles), so that
    equal targets give equal keys (1 == 1.0)."""
    row = tuple(float(v) for v in target)
    width = len(model.target_fields)
    return row + (0.0,) * (width - len(row)) if len(row) < width else row


class StrokeTally:
    """Per actuator, in order of first use: the distinct strokes of a pkm5's actuator-bench moves, each checked
    exactly as the driver's ``move_actuator`` checks it (``steps_for_stroke``: the 0-66 mm window of ``geometry``,
    default the documented one), and the time of its moves from the home stroke at the rated speed scaled by the
    commanded velocity; fed one move at a time."""

    def __init__(self, geometry: Any = None) -> None:
        self.geometry = geometry
        self.per_axis: dict[Any, dict[str, Any]] = {}
        self.where: dict[int, int] | None = None

    def check(self, move: ActuatorMove) -> int:
        """The step target of ``move`` (``UnreachableTarget`` outside the actuator's window)."""
        from bench.robots.pkm5_kinematics import steps_for_stroke
        from motion import pkm5

        self.geometry = self.geometry or pkm5.DEFAULT_GEOMETRY
        return abs(steps_for_stroke(move.axis, move.stroke_mm, self.geometry))

    def add(self, move: ActuatorMove) -> None:
        from bench.robots.pkm5 import RATED_SPEED_STEPS_S
        from motion import pkm5

        geometry = self.geometry = self.geometry or pkm5.DEFAULT_GEOMETRY
        if self.where is None:
            self.where = dict(enumerate(np.round(geometry.home_stroke_mm / geometry.mm_per_step).astype(int), start=1))
        axis = self.per_axis.setdefault(move.axis, {"strokes": set(), "moves": 0, "s": 0.0, "refused": []})
        axis["moves"] += 1
        axis["strokes"].add(float(move.stroke_mm))
        try:
            target = self.check(move)
        except UnreachableTarget as exc:
            axis["refused"].append(f"target {move.label or 'actuator move'}: {exc}")
            return
        speed = max(1.0, RATED_SPEED_STEPS_S * move.velocity_pct / 100.0)
        axis["s"] += abs(target - self.where[move.axis]) / speed
        self.where[move.axis] = target

    def axes(self) -> tuple[AxisStrokes, ...]:
        from bench.robots.pkm5_kinematics import stroke_range_mm

        where = self.where or {}
        return tuple(
            AxisStrokes(
                number,
                stroke_range_mm(number, self.geometry) if number in where else (float("nan"),) * 2,
                tuple(sorted(a["strokes"])),
                a["moves"],
                a["s"],
                tuple(a["refused"]),
            )
            for number, a in self.per_axis.items()
        )
