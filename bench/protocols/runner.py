"""The runner: performs a protocol's steps on a rig, stores every sample at once, and settles the run's status.

One synchronous loop with explicit states (bluesky's RunEngine without the event loop). The legal transitions
are in ``TRANSITIONS``; an illegal request raises :class:`TransitionError`. Requests, which may come from another
thread or a signal handler, are honoured at safe points:

- ``request_pause()``: at the next ``Checkpoint`` (between cycles) the runner enters PAUSED and calls
  ``on_pause(runner)``, which must call ``resume()``, ``stop()``, ``abort()`` or ``halt()``;
- ``stop()``: ends at the next ``Checkpoint``, then runs the protocol's clean-up steps (status ``aborted``,
  reason "stopped ...", resumable);
- ``abort(reason)``: after the current step, stops the robot, then runs the clean-up steps (status ``aborted``);
- ``halt()``: after the current step, stops the robot and runs nothing more (status ``aborted``, "halted");
- an exception (or Ctrl-C) stops the robot (status ``failed``, or ``aborted`` for Ctrl-C).

``robot.shutdown()`` runs in ``finally`` in every case. Resuming regenerates the protocol from the stored
configuration, replays it without acting up to the last ``Checkpoint`` before the first missing sample, then acts
from there, skipping every step whose sample is already stored (its stored values are sent back instead).
"""

from __future__ import annotations

import enum
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self

from bench.errors import BenchError, ConfigError
from bench.protocols.base import Protocol, protocol_from_config
from bench.protocols.plan import iterate, preflight
from bench.protocols.rig import Rig
from bench.protocols.steps import (
    ActuatorMove,
    Capture,
    Checkpoint,
    Move,
    Plan,
    Prompt,
    Settle,
    Step,
)
from bench.store import Store

__all__ = ["TRANSITIONS", "RunResult", "RunState", "Runner", "TransitionError", "resume_point"]

_log = logging.getLogger(__name__)


class RunState(enum.Enum):
    IDLE = "idle"
    RUNNING = "running"
    PAUSED = "paused"
    STOPPING = "stopping"
    ABORTING = "aborting"
    HALTING = "halting"
    FINISHED = "finished"


S = RunState
#: Legal state transitions of the runner.
TRANSITIONS: dict[RunState, frozenset[RunState]] = {
    S.IDLE: frozenset({S.RUNNING}),
    S.RUNNING: frozenset({S.PAUSED, S.STOPPING, S.ABORTING, S.HALTING, S.FINISHED}),
    S.PAUSED: frozenset({S.RUNNING, S.STOPPING, S.ABORTING, S.HALTING}),
    S.STOPPING: frozenset({S.ABORTING, S.HALTING, S.FINISHED}),
    S.ABORTING: frozenset({S.HALTING, S.FINISHED}),
    S.HALTING: frozenset({S.FINISHED}),
    S.FINISHED: frozenset(),
}


class TransitionError(BenchError):
    """A request the runner's current state does not allow (e.g. resume while running)."""


class _Halt(Exception):
    """Internal: leave the step loop now."""


@dataclass(frozen=True)
class RunResult:
    """How a run ended: ``exit_status`` is the stored status (completed, aborted, failed)."""

    run_id: int
    exit_status: str
    reason: str | None
    samples: int
    exception: BaseException | None = None


def _sample_steps(protocol: Protocol, stored: dict[int, Any]) -> tuple[int | None, int]:
    """(index of the first sample step not stored or None, index of the last Checkpoint before it or 0)."""
    plan, reply, index, checkpoint = protocol.steps(), None, 0, 0
    while True:
        try:
            step = plan.send(reply)
        except StopIteration:
            return None, checkpoint
        if isinstance(step, Checkpoint):
            checkpoint = index
        if isinstance(step, (Capture, Prompt)) and step_stores_sample(step):
            if index not in stored:
                return index, checkpoint
            reply = stored[index]
        else:
            reply = None
        index += 1


def step_stores_sample(step: Step) -> bool:
    return isinstance(step, Capture) or (isinstance(step, Prompt) and step.field is not None)


def resume_point(protocol: Protocol, stored: dict[int, Any]) -> int | None:
    """Index of the step a resumed run acts from (the last Checkpoint before the first missing sample), or None
    when every sample is stored."""
    missing, checkpoint = _sample_steps(protocol, stored)
    return None if missing is None else checkpoint


class Runner:
    """Runs protocols on a rig into a store.

    Parameters
    ----------
    rig : Rig
        Robot, instrument and operator.
    store : Store
        Where the run and every sample go.
    progress : bool
        Show a Rich progress bar with ETA on stderr.
    on_pause : callable, optional
        Called with the runner when it pauses at a checkpoint; must resume, stop, abort or halt it. Default:
        resume at once.
    """

    def __init__(self, rig: Rig, store: Store, *, progress: bool = False,
                 on_pause: Callable[[Runner], None] | None = None) -> None:
        self.rig = rig
        self.store = store
        self.progress = progress
        self.on_pause = on_pause or (lambda runner: runner.resume())
        self.state = RunState.IDLE
        self._lock = threading.Lock()
        self._pause_requested = False
        self._reason: str | None = None
        self.run_id: int | None = None

    # ---- requests --------------------------------------------------------------------------------------------

    def _transition(self, new: RunState) -> None:
        with self._lock:
            if new not in TRANSITIONS[self.state]:
                raise TransitionError(f"runner: cannot go from {self.state.value} to {new.value}")
            _log.info("runner: %s -> %s", self.state.value, new.value)
            self.state = new

    def request_pause(self) -> None:
        """Pause at the next Checkpoint."""
        if self.state is not RunState.RUNNING:
            raise TransitionError(f"runner: cannot pause while {self.state.value}")
        self._pause_requested = True

    def resume(self) -> None:
        """Leave PAUSED and continue."""
        if self.state is not RunState.PAUSED:
            raise TransitionError(f"runner: cannot resume while {self.state.value}")
        self._transition(RunState.RUNNING)

    def stop(self, reason: str = "stopped by the operator") -> None:
        """End cleanly at the next Checkpoint."""
        self._reason = reason
        self._transition(RunState.STOPPING)

    def abort(self, reason: str = "aborted by the operator") -> None:
        """Stop the robot after the current step and end (clean-up steps still run)."""
        self._reason = reason
        self._transition(RunState.ABORTING)

    def halt(self, reason: str = "halted by the operator") -> None:
        """Stop the robot after the current step and end without clean-up steps."""
        self._reason = reason
        self._transition(RunState.HALTING)

    # ---- running ---------------------------------------------------------------------------------------------

    def run(self, protocol: Protocol, *, campaign: str | None = None) -> RunResult:
        """Pre-flight ``protocol``, store a new run, perform it; returns how it ended."""
        preflight(protocol)
        run_id = self.store.start_run(protocol_name=protocol.name, protocol_version=protocol.version,
                                      robot=protocol.robot, config=protocol.config(), settings=self.rig.settings(),
                                      calibration_ids=self.rig.calibration_ids, campaign=campaign)
        return self._perform(protocol, run_id, stored={}, start_at=0)

    def resume_run(self, run_id: int) -> RunResult:
        """Continue stored run ``run_id`` at its last checkpoint, without storing any sample twice."""
        record = self.store.run(run_id)
        if record.status == "completed":
            raise ConfigError(f"run {run_id}: already completed, nothing to resume")
        protocol = protocol_from_config(record.config, source=f"run {run_id}")
        if protocol.version != record.protocol_version:
            raise ConfigError(f"run {run_id}: protocol {protocol.name} is now version {protocol.version}, the run "
                              f"used version {record.protocol_version}; cannot resume across versions")
        if tuple(sorted(self.rig.calibration_ids)) != tuple(record.calibration_ids):
            raise ConfigError(f"run {run_id}: calibrations in force {sorted(self.rig.calibration_ids)} differ from "
                              f"the run's {list(record.calibration_ids)}; cannot resume")
        preflight(protocol)
        stored = {s.step_index: self._reply_of(s) for s in self.store.samples(run_id)}
        start_at = resume_point(protocol, stored)
        self.store.set_status(run_id, "running")
        return self._perform(protocol, run_id, stored=stored,
                             start_at=start_at if start_at is not None else 10**12)

    @staticmethod
    def _reply_of(sample: Any) -> Any:
        if isinstance(sample.raw, dict) and "field" in sample.raw and "entered" in sample.raw:  # a prompt's reading
            return sample.values[sample.raw["field"]]
        return dict(sample.values)

    def _perform(self, protocol: Protocol, run_id: int, *, stored: dict[int, Any],
                 start_at: int) -> RunResult:
        self.run_id = run_id
        self._transition(RunState.RUNNING)
        status, exception = "completed", None
        offset_s = max((s.t_s for s in self.store.samples(run_id)), default=0.0)
        self._t0 = time.monotonic() - offset_s
        bar = _Progress(self.progress, total=_count_samples(protocol), done=len(stored), label=protocol.name)
        try:
            with bar:
                self._loop(protocol.steps(), run_id, stored, start_at, bar)
                if self.state in (RunState.ABORTING, RunState.HALTING):
                    self._stop_robot()
                if self.state is not RunState.HALTING:
                    self._loop(protocol.final_steps(), run_id, {}, 0, None, final=True)
            if self.state in (RunState.STOPPING, RunState.ABORTING, RunState.HALTING):
                status = "aborted"
            else:
                protocol.on_completed(self.store, run_id)
        except KeyboardInterrupt as exc:
            status, exception, self._reason = "aborted", exc, "interrupted (Ctrl-C)"
            self._stop_robot()
        except Exception as exc:  # noqa: BLE001 - any failure is stored with its reason, then reported
            status, exception, self._reason = "failed", exc, f"{type(exc).__name__}: {exc}"
            self._stop_robot()
        finally:
            self._shutdown()
            reason = None if status == "completed" else self._reason
            self.store.set_status(run_id, status, reason)
            self.state = RunState.FINISHED
        _log.info("run %d %s%s", run_id, status, f": {reason}" if reason else "")
        return RunResult(run_id, status, reason, len(self.store.stored_steps(run_id)), exception)

    def _loop(self, plan: Plan, run_id: int, stored: dict[int, Any], start_at: int, bar: _Progress | None,
              *, final: bool = False) -> None:
        reply, index = None, 0
        while True:
            if not final and self.state in (RunState.ABORTING, RunState.HALTING):
                return
            try:
                step = plan.send(reply)
            except StopIteration:
                return
            if index in stored:
                reply = stored[index]
            elif index < start_at:
                reply = None
            else:
                reply = self._act(step, run_id, index)
                if bar is not None and step_stores_sample(step):
                    bar.advance()
            if isinstance(step, Checkpoint) and not final and index >= start_at and self._at_checkpoint(step):
                return
            index += 1

    def _at_checkpoint(self, step: Checkpoint) -> bool:
        """Handle pause and stop requests; True when the run must end here."""
        if self._pause_requested and self.state is RunState.RUNNING:
            self._pause_requested = False
            self._transition(RunState.PAUSED)
            _log.warning("paused at checkpoint %s", step.label)
            self.on_pause(self)
            if self.state is RunState.PAUSED:
                raise TransitionError("runner: on_pause returned without resuming, stopping or aborting")
        if self.state is RunState.STOPPING:
            self._reason = f"{self._reason} at checkpoint {step.label}".strip()
            return True
        return self.state in (RunState.ABORTING, RunState.HALTING)

    def _act(self, step: Step, run_id: int, index: int) -> Any:
        rig = self.rig
        if isinstance(step, Move):
            rig.robot.move_to(tuple(step.target), velocity_pct=step.velocity_pct)
            return None
        if isinstance(step, ActuatorMove):
            if not hasattr(rig.robot, "move_actuator"):
                raise ConfigError(f"{step!r}: this rig's robot has no actuator-bench mode")
            rig.robot.move_actuator(step.axis, step.stroke_mm, velocity_pct=step.velocity_pct)
            return None
        if isinstance(step, Settle):
            rig.sleep(step.duration_s / rig.speed_factor)
            return None
        if isinstance(step, Capture):
            measured = rig.instrument.measure(step)
            values = {**step.commanded, **measured.values, **step.conditions}
            self.store.add_sample(run_id, index, values=values, kind=step.kind, pose=step.pose, cycle=step.cycle,
                                  t_s=time.monotonic() - self._t0, raw=measured.raw)
            return values
        if isinstance(step, Prompt):
            answer = rig.operator.ask(step)
            if step.field is not None:
                if answer is None:
                    raise ConfigError(f"prompt {step.text!r}: no value given for {step.field}")
                values = {**step.commanded, step.field: float(answer), **step.conditions}
                self.store.add_sample(run_id, index, values=values, kind=step.kind, pose=step.pose or None,
                                      cycle=step.cycle or None, t_s=time.monotonic() - self._t0,
                                      raw={"field": step.field, "entered": answer})
            return answer
        if isinstance(step, Checkpoint):
            return None
        raise ConfigError(f"protocol yielded {step!r}, expected a Move, ActuatorMove, Settle, Capture, Prompt or "
                          "Checkpoint")

    def _stop_robot(self) -> None:
        try:
            self.rig.robot.stop()
        except Exception as exc:  # noqa: BLE001 - stopping is best effort; shutdown follows
            _log.error("robot stop failed: %s", exc)

    def _shutdown(self) -> None:
        try:
            self.rig.robot.shutdown()
        except Exception as exc:  # noqa: BLE001
            _log.error("robot shutdown failed: %s", exc)


def _count_samples(protocol: Protocol) -> int:
    return sum(1 for step in iterate(protocol, final=False) if step_stores_sample(step))


class _Progress:
    """A Rich progress bar (samples stored, ETA) on stderr, or nothing."""

    def __init__(self, enabled: bool, *, total: int, done: int, label: str) -> None:
        self.enabled = enabled
        if enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )
            self._bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("ETA"), TimeRemainingColumn(), console=Console(stderr=True),
                                 transient=False)
            self._task = self._bar.add_task(label, total=total, completed=done)

    def __enter__(self) -> Self:
        if self.enabled:
            self._bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            self._bar.stop()

    def advance(self) -> None:
        if self.enabled:
            self._bar.advance(self._task)
