"""Dry runs: iterate a protocol without hardware, list its moves, pre-flight every target, estimate the duration.

Like bluesky's ``summarize_plan`` and ``check_limits``: the generator is driven with stand-in results (a capture
"measures" its commanded values, a prompt answers the middle of its range), every ``Move`` target is checked with
motion/ (reach, joint limits, singularity proximity) and every ``ActuatorMove`` stroke against the actuator's window
(actuator bench) before anything moves, and the time is estimated from the robot's actuator speeds plus the settle
times, the captures (a streamed arrival records for its ``hold_s``) and the prompts.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from bench.protocols.base import Protocol
from bench.protocols.kinematics import DEFAULT_SINGULARITY_THRESHOLD
from bench.protocols.summary import AxisStrokes, PlanSummary, StrokeTally, model_of, target_key
from bench.steps import ActuatorMove, Capture, Checkpoint, Move, Prompt, Settle, Step

__all__ = [
    "AxisStrokes",
    "PlanSummary",
    "capture_s",
    "dry_run_result",
    "iterate",
    "preflight",
    "required_capabilities",
    "step_stores_sample",
    "summarize",
    "walk",
]

#: Time a capture and a prompt are assumed to take in the estimate, s (a prompt waits for a person).
CAPTURE_S = 0.05
PROMPT_S = 10.0


def capture_s(step: Capture) -> float:
    """Real time one capture takes: a streamed capture (``conditions["hold_s"]``, e.g. an ``arrival``) records for
    its hold window after the move is reported done (its lead window lies in the move, already counted); any other
    capture :data:`CAPTURE_S`."""
    return float(step.conditions.get("hold_s", CAPTURE_S))


def dry_run_result(step: Step) -> Any:
    """The stand-in result a dry run sends back for ``step``."""
    if isinstance(step, Capture):
        return {k.removeprefix("cmd_"): v for k, v in step.commanded.items()}
    if isinstance(step, Prompt) and step.field is not None:
        low = step.minimum if step.minimum is not None else 0.0
        high = step.maximum if step.maximum is not None else low
        return (low + high) / 2
    return None


def iterate(protocol: Protocol, *, final: bool = True) -> Iterator[Step]:
    """Every step of ``protocol`` (then of its clean-up plan), driven with :func:`dry_run_result`."""
    for _, step in walk(protocol, final=final):
        yield step


def walk(
    protocol: Protocol, *, final: bool = True, stored: Mapping[int, Any] | None = None
) -> Iterator[tuple[int | None, Step]]:
    """``(index, step)`` for every step of ``protocol``'s plan (then ``(None, step)`` for its clean-up plan), driven
    with ``stored[index]`` where a sample is stored (a resumed run: its plan as it ran) and :func:`dry_run_result`
    elsewhere."""
    replies = stored or {}
    for main in (True, False) if final else (True,):
        plan = protocol.steps() if main else protocol.final_steps()
        reply, index = None, 0
        while True:
            try:
                step = plan.send(reply)
            except StopIteration:
                break
            yield (index if main else None), step
            reply = replies[index] if main and index in replies and step_stores_sample(step) else dry_run_result(step)
            index += 1


def step_stores_sample(step: Step) -> bool:
    """A step whose result is a stored sample: a capture, or a prompt for a reading."""
    return isinstance(step, Capture) or (isinstance(step, Prompt) and step.field is not None)


#: The capability a capture of each kind needs from the station (the kinds the protocol library captures).
_CAPTURE_NEEDS = {
    "pose": "pose",
    "mouse": "mouse_counts",
    "arrival": "arrival",
    "path": "arrival",
    "positioning": "arrival",
    "grid_hit": "grid_hit",
}


def required_capabilities(protocol: Protocol) -> frozenset[str]:
    """What a station must provide to run ``protocol``, read from its own plan (so it cannot drift from the steps):
    a capability per capture kind, ``reading`` when an operator reading is prompted, and the fixture the protocol
    moves (``actuator_bench`` or ``assembled``). A station provides them by its fixture and its sensors
    (:meth:`bench.rigs.station.Station.capabilities`).
    :attr:`PlanSummary.capabilities` is the same, from the pre-flight's walk."""
    needs = _fixture_need(protocol)
    for step in iterate(protocol):
        _add_need(needs, step)
    return frozenset(needs)


def _fixture_need(protocol: Protocol) -> set[str]:
    return {str(getattr(protocol, "fixture", "assembled")).replace("-", "_")}


def _add_need(needs: set[str], step: Step) -> None:
    if isinstance(step, Capture):
        needs.add(_CAPTURE_NEEDS.get(step.kind, step.kind))
    elif isinstance(step, Prompt) and step.field is not None:
        needs.add("reading")


#: Moves timed together in :func:`summarize`: the dry run holds one such chunk, never the whole plan, so a plan of
#: 10^6 steps is summarised in memory bounded by its distinct targets and linear time.
_MOVES_PER_CHUNK = 4096


class _MoveTimer:
    """The estimated time of a stream of moves, from the robot's home, timed a chunk at a time."""

    def __init__(self, model: Any) -> None:
        self.model = model
        self.last = model.as_targets([model.home])[0]
        self.targets: list[tuple[float, ...]] = []
        self.velocity: list[float] = []
        self.seconds = 0.0

    def add(self, target: tuple[float, ...], velocity_pct: float) -> None:
        self.targets.append(target)
        self.velocity.append(velocity_pct)
        if len(self.targets) == _MOVES_PER_CHUNK:
            self.flush()

    def flush(self) -> float:
        if self.targets:
            ends = self.model.as_targets(self.targets)
            starts = np.vstack([self.last[None, :], ends[:-1]])
            self.seconds += float(self.model.move_s(starts, ends, np.array(self.velocity, dtype=float)).sum())
            self.last = ends[-1]
            self.targets, self.velocity = [], []
        return self.seconds


def summarize(
    protocol: Protocol,
    *,
    singularity_threshold: float | None = None,
    geometry: Any = None,
    stored: Mapping[int, Any] | None = None,
) -> PlanSummary:
    """Dry-run ``protocol`` in one walk of its plan: count its steps and samples, pre-flight every distinct target
    and actuator stroke, estimate its duration, and (``stored``: the samples of a run being resumed, by step index)
    find the step a resume acts from.

    ``singularity_threshold`` defaults to the protocol's ``min_inverse_condition``; ``geometry`` (default: the
    documented one) is the geometry the robot commands by (a kinematic calibration in force). The plan is streamed:
    memory holds its distinct targets and strokes and one chunk of moves (:data:`_MOVES_PER_CHUNK`), whatever its
    length.
    """
    if singularity_threshold is None:
        singularity_threshold = getattr(protocol, "min_inverse_condition", DEFAULT_SINGULARITY_THRESHOLD)
    model = model_of(protocol.robot, geometry)
    counts: Counter[str] = Counter()
    timer = _MoveTimer(model)
    strokes = StrokeTally(geometry)
    distinct: dict[tuple[float, ...], str] = {}
    settle_s = captures_s = 0.0
    samples = readings = checkpoint = 0
    missing = None
    needs = _fixture_need(protocol)
    names: dict[type, str] = {}  # per step type, its count's name ("moves")
    for index, step in walk(protocol, stored=stored):
        kind = type(step)
        counts[names.get(kind) or names.setdefault(kind, kind.__name__.lower() + "s")] += 1
        if index is not None and missing is None:  # where a resume acts from: the last checkpoint before a gap
            if isinstance(step, Checkpoint):
                checkpoint = index
            elif step_stores_sample(step) and index not in (stored or {}):
                missing = index
        if isinstance(step, Move):
            key = target_key(model, step.target)
            if key not in distinct:
                distinct[key] = step.label or str(counts["moves"] - 1)
            timer.add(key, step.velocity_pct)
        elif isinstance(step, ActuatorMove):
            strokes.add(step)
        elif isinstance(step, Settle):
            settle_s += step.duration_s
        elif isinstance(step, Capture):
            captures_s += capture_s(step)
        if index is not None and step_stores_sample(step):
            samples += 1
            readings += isinstance(step, Prompt)
        _add_need(needs, step)
    targets = np.array(list(distinct), dtype=float).reshape(-1, len(model.target_fields))
    check = model.check(targets, singularity_threshold)
    move_s = timer.flush() if check.reachable.all() else 0.0
    axes = strokes.axes()
    return PlanSummary(
        protocol.name,
        protocol.robot,
        dict(counts),
        tuple(distinct.values()),
        targets,
        check.reachable,
        tuple(str(r) for r in check.reason),
        check.proximity,
        move_s + sum(a.move_s for a in axes),
        settle_s,
        counts["prompts"] * PROMPT_S,
        captures_s,
        axes,
        protocol.limit_warnings(),
        samples=samples,
        readings=readings,
        resume_at=None if missing is None else checkpoint,
        stored_samples=len(stored or {}),
        capabilities=frozenset(needs),
        model=model,
        threshold=singularity_threshold,
    )


def preflight(protocol: Protocol, **kwargs: Any) -> PlanSummary:
    """:func:`summarize`, raising ``UnreachableTarget`` naming every refused target before anything moves."""
    return summarize(protocol, **kwargs).refuse_unless_ok(protocol.source)
