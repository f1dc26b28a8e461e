"""The runner: performs a protocol's steps on a rig, stores every sample at once, and settles the run's status.

One synchronous loop with explicit states (bluesky's RunEngine without the event loop). The legal transitions
are in ``TRANSITIONS``; an illegal request raises :class:`TransitionError`. Requests, which may come from another
thread or a signal handler, are honoured at safe points:

- ``request_pause()``: at the next ``Checkpoint`` (between cycles) the runner enters PAUSED and calls
  ``on_pause(runner)``, which must call ``resume()``, ``stop()``, ``abort()`` or ``halt()``;
- ``stop()``: ends at the next ``Checkpoint``, then runs the protocol's clean-up steps (status ``aborted``,
  reason "stopped ...", resumable);
- ``abort(reason)``: after the current step (a ``Settle`` is cut short), stops the robot, then runs the clean-up
  steps (status ``aborted``);
- ``halt()``: after the current step (a ``Settle`` is cut short), stops the robot and runs nothing more (status
  ``aborted``, "halted");
- ``emergency_stop()``: sends the robot's stop at once from the calling thread, cuts a ``Settle`` short, ends a
  move in flight (the driver's stop makes it return or raise), then runs nothing more (status ``aborted``,
  "emergency stop", resumable); an exception the interrupted step raises is part of the stop, not a failure;
- a prompt the operator withdraws (the operator raises :class:`bench.errors.PromptWithdrawn`) ends the run at once,
  without clean-up moves since the operator may be at the robot (status ``aborted``, "prompt withdrawn by the
  operator: <prompt>", resumable);
- an exception (or Ctrl-C) stops the robot (status ``failed``, or ``aborted`` for Ctrl-C).

Before anything is stored or moved, the runner pre-flights the plan (:meth:`Runner.preflight`) by the model of the
rig's own robot and the geometry it commands by (a kinematic calibration in force included), in one walk of the plan
that also counts its samples and, for a resume, finds the step to act from. Every ``Move`` and ``ActuatorMove`` is
then commanded only to a target that walk proved; a target the plan chooses during the run (an adaptive protocol's
corrected command) is checked alone by the same model before it is commanded, and refused (the run fails) when it
is out of reach. No other module pre-flights for the runner.

Each sample's commit starts the moment it is taken and runs on the store's writer thread
(:class:`bench.store.sample_writer.SampleWriter`) while the next ``Move`` and ``Settle`` steps go on (a
``Checkpoint`` queues the store's checkpoint behind it); the runner waits for both before anything else (the next
capture or prompt, a pause, the end of the run), a failed commit fails the run there, before anything else is
measured, and a sample is counted and shown to ``on_sample`` only once it is durable (what a power cut can lose:
the module :mod:`bench.store.sample_writer`).

``robot.shutdown()`` runs in ``finally`` in every case. The runner owns its run (``Store.claim``) from the moment it
is stored or resumed until its status is settled; resuming a run another live process owns is refused with
:class:`bench.store.RunOwned` before anything is moved or written. Resuming regenerates the protocol from the stored
configuration, replays it without acting up to the last ``Checkpoint`` before the first missing sample, then acts
from there, skipping every step whose sample is already stored (its stored values are sent back instead).

A rig whose instruments are relative (the mice) brings a registration record (``rig.registration``, made by
:mod:`bench.rigs.registration`); the runner files it in the run's settings, ``registrations``, one per segment (the
start and every resume), with the step it acts from. A sample belongs to the last registration stored before it
(by ``utc`` against the sample's ``wall_utc``).

Sample times ``t_s`` are seconds since the run started in the rig's time base (:meth:`Rig.time_base`, stored in
the run settings as ``time_base``): wall seconds on hardware, simulated seconds (wall x speed factor) on a
sped-up simulator, so that drift and stabilisation windows mean the same on both. Everything the host does
between moves counts too: 2 ms of host time at speed factor 10 000 are 20 simulated seconds. A resumed run
continues after the last stored ``t_s``, so ``t_s`` never decreases within a run.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from bench.errors import ConfigError, PromptWithdrawn
from bench.protocols.base import Protocol
from bench.protocols.plan import PlanSummary, preflight
from bench.protocols.progress import ProgressBar
from bench.protocols.recording import SampleRecorder
from bench.protocols.resume import resumable_protocol, stored_replies
from bench.protocols.run_state import TRANSITIONS, RunControl, RunResult, RunState, TransitionError
from bench.rigs.interfaces import Entry, Rig
from bench.steps import (
    ActuatorMove,
    Capture,
    Checkpoint,
    MountedPayload,
    Move,
    Plan,
    Prompt,
    Settle,
    Step,
)
from bench.store import Store

__all__ = ["TRANSITIONS", "RunResult", "RunState", "Runner", "TransitionError"]

_log = logging.getLogger(__name__)


class Runner(RunControl):
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
    on_start : callable, optional
        ``on_start(runner)`` once the run is stored (or reopened) and before its first step: ``runner.run_id``,
        ``runner.samples_total`` and ``runner.samples_stored`` (already stored when resuming) are set.
    on_sample : callable, optional
        ``on_sample(runner, sample)`` once each sample is durable in the store; ``sample`` is a dict with
        ``step_index``, ``kind``, ``pose``, ``cycle``, ``t_s``, ``values`` and ``raw`` (as stored).

    Attributes
    ----------
    current_step : Step or None
        The step being performed (None between steps), e.g. for a window to show what the rig is doing.
    plan : PlanSummary or None
        The run's pre-flight (its counts, targets and duration; set before ``on_start``).
    """

    def __init__(
        self,
        rig: Rig,
        store: Store,
        *,
        progress: bool = False,
        on_pause: Callable[[Runner], None] | None = None,
        on_start: Callable[[Runner], None] | None = None,
        on_sample: Callable[[Runner, dict[str, Any]], None] | None = None,
    ) -> None:
        self.rig = rig
        self.store = store
        self.progress = progress
        self.on_pause = on_pause or (lambda runner: runner.resume())
        self.on_start = on_start
        self.on_sample = on_sample
        super().__init__()
        self.run_id: int | None = None
        self.current_step: Step | None = None
        self.samples_total = 0
        self.samples_stored = 0
        self._bar: ProgressBar | None = None
        self._recorder: SampleRecorder | None = None
        self._payload = MountedPayload()  # what this run segment knows is on the end effector
        self.plan: PlanSummary | None = None  # the run's pre-flight: what it proved reachable

    # ---- requests (pause, resume, stop, abort, halt: bench.protocols.run_state.RunControl) ------------------

    def emergency_stop(self, reason: str = "emergency stop") -> None:
        """Stop the robot now and end the run as soon as the current step returns, with nothing more run.

        Safe to call from any thread (a window's e-stop button) and in any state. The robot's ``stop()`` is sent
        from the calling thread at once (a move in flight then returns or raises, see
        :class:`bench.rigs.interfaces.Mover`), a Settle is cut short, no further step starts and no clean-up step
        runs; the run ends ``aborted`` with ``reason`` and can be resumed. Before a run starts it stops the robot
        and the run, once started, ends before its first step; after the run has finished it does nothing (the
        robot is shut down).
        """
        with self._lock:
            if self.state is RunState.FINISHED:
                return
            self._emergency = True
            self._reason = reason
            if self.state not in (RunState.IDLE, RunState.HALTING):
                self._transition_locked(RunState.HALTING)
        _log.warning("runner: emergency stop")
        self._stop_robot(emergency=True)
        self._wake.set()

    # ---- running ---------------------------------------------------------------------------------------------

    def run(self, protocol: Protocol, *, campaign: str | None = None, plan: PlanSummary | None = None) -> RunResult:
        """Pre-flight ``protocol`` by this rig's robot, store a new run, perform it; returns how it ended.

        ``plan``: the pre-flight of this very protocol made before the rig opened (``bench run`` needs its
        capabilities first); its targets are then checked again by this rig's geometry without a second walk.
        """
        plan = self.preflight(protocol, earlier=plan)
        settings = self.rig.settings()
        registration = self.rig.registration
        if registration is not None:  # segment 1 (bench.rigs.registration); a resume appends its own
            settings["registrations"] = [{**registration, "segment": 1, "from_step": 0}]
        run_id = self.store.start_run(
            protocol_name=protocol.name,
            protocol_version=protocol.version,
            robot=protocol.robot,
            config=protocol.config(),
            settings=settings,
            calibration_ids=self.rig.calibration_ids,
            campaign=campaign,
        )
        return self._perform(protocol, plan, run_id, stored={}, start_at=0)

    def preflight(
        self, protocol: Protocol, stored: Mapping[int, Any] | None = None, *, earlier: PlanSummary | None = None
    ) -> PlanSummary:
        """The run's pre-flight, in one walk of the plan (:func:`bench.protocols.plan.preflight`), by the model of
        this rig's robot and the geometry it commands by (a kinematic calibration in force included): every target
        and stroke proved before anything moves, ``UnreachableTarget`` naming the refused ones otherwise; with
        ``stored`` (a resume) the plan is walked as it ran. ``earlier``: a pre-flight of ``protocol`` already made
        (with the same ``stored`` replies), whose distinct targets are checked again by this rig's geometry instead
        of a walk."""
        robot = self.rig.robot
        if robot.kind != protocol.robot:
            raise ConfigError(
                f"{protocol.source}: robot = {protocol.robot!r}, but this rig's robot is {robot.kind!r}; expected "
                "a rig of the protocol's robot"
            )
        made_alike = (protocol.name, robot.kind, len(stored or {}))
        if earlier is not None and (earlier.protocol, earlier.robot, earlier.stored_samples) == made_alike:
            again = earlier.checked_by(robot.geometry)
            if again is not None:
                return again.refuse_unless_ok(protocol.source)
        return preflight(protocol, geometry=robot.geometry, stored=stored)

    def resume_run(self, run_id: int, *, plan: PlanSummary | None = None) -> RunResult:
        """Continue stored run ``run_id`` at its last checkpoint, without storing any sample twice. ``plan``: its
        pre-flight made before the rig opened, with the stored replies (:func:`bench.protocols.resume.stored_replies`)
        while this process owned the run."""
        self.store.claim(run_id)  # first: a run another live process drives is refused before anything is read
        try:
            return self._resume_owned(run_id, plan)
        except BaseException:
            if self.state is RunState.IDLE:  # refused before it started: the ownership goes back at once
                self.store.release(run_id)
            raise

    def _resume_owned(self, run_id: int, earlier: PlanSummary | None) -> RunResult:
        record = self.store.run(run_id)
        protocol = resumable_protocol(record, self.rig)
        stored = stored_replies(self.store, run_id)
        plan = self.preflight(protocol, stored, earlier=earlier)
        stored_base = record.settings.get("time_base", "wall s (runs stored before time bases were recorded)")
        if stored_base != self.rig.time_base():
            _log.warning(
                "run %d: stored t_s in %s, continues in %s (t_s stays monotonic)",
                run_id,
                stored_base,
                self.rig.time_base(),
            )
        start_at = plan.resume_at
        registration = self.rig.registration
        if registration is not None:  # a new segment: the instruments were registered again (bench.rigs.registration)
            self.store.add_registration(run_id, {**registration, "from_step": start_at})
        elif record.settings.get("registrations"):
            raise ConfigError(
                f"run {run_id}: its instruments were registered at a check pose, this rig's were not; "
                "resume it on the rig that made it"
            )
        self.store.set_status(run_id, "running")
        return self._perform(
            protocol, plan, run_id, stored=stored, start_at=start_at if start_at is not None else 10**12
        )

    def _perform(
        self, protocol: Protocol, plan: PlanSummary, run_id: int, *, stored: dict[int, Any], start_at: int
    ) -> RunResult:
        self.run_id = run_id
        self.plan = plan
        with self._lock:
            self._transition_locked(RunState.RUNNING)
            if self._emergency:  # stopped before the run started: it ends before its first step
                self._transition_locked(RunState.HALTING)
        status = "completed"
        exception: BaseException | None = None
        self.samples_total, self.samples_stored = plan.samples, len(stored)
        self._bar = ProgressBar(self.progress, total=self.samples_total, done=self.samples_stored, label=protocol.name)
        self._recorder = None
        self._payload = MountedPayload()
        try:
            self._recorder = SampleRecorder(self.store, self.rig, run_id, self._durable)
            with self._bar:
                self._call_hook(self.on_start, self)
                self._loop(protocol.steps(), run_id, stored, start_at)
                if self.state in (RunState.ABORTING, RunState.HALTING):
                    self._stop_robot()
                if self.state is not RunState.HALTING:
                    self._wake.clear()  # an abort cut the main steps short, not the clean-up's settles
                    self._loop(protocol.final_steps(), run_id, {}, 0, final=True)
                self._await_commit()
            ended_early = self.state in (RunState.STOPPING, RunState.ABORTING, RunState.HALTING)
            self._payload_off()  # after the run's end is decided: a stop asked during it changes nothing
            if ended_early:
                status = "aborted"
            else:
                protocol.on_completed(self.store, run_id)
        except KeyboardInterrupt as exc:
            # a signal handler names its signal (bench.commands.campaign: SIGTERM, SIGHUP); a bare one is Ctrl-C
            status, exception = "aborted", exc
            self._reason = f"interrupted ({exc.args[0] if exc.args else 'Ctrl-C'})"
            self._stop_robot()
        except Exception as exc:  # noqa: BLE001 - any failure is stored with its reason, then reported
            if self._emergency:  # the stop ended the step it interrupted (e.g. a move: ERR STOPPED)
                status = "aborted"
                _log.warning(
                    "run %d: %s ended the step %r: %s: %s",
                    run_id,
                    self._reason,
                    self.current_step,
                    type(exc).__name__,
                    exc,
                )
            else:
                status, exception, self._reason = "failed", exc, f"{type(exc).__name__}: {exc}"
            self._stop_robot()
        finally:
            self.current_step = None
            self._shutdown()
            failure = None if self._recorder is None else self._recorder.close()  # None: it never opened
            if failure is not None and status != "failed":  # the last sample's commit failed: it is not stored
                status, exception, self._reason = "failed", failure, f"{type(failure).__name__}: {failure}"
            elif failure is not None:  # both failed: the stored reason names the lost sample too
                self._reason = f"{self._reason}; the last sample's commit failed: {type(failure).__name__}: {failure}"
            reason = None if status == "completed" else self._reason
            self.store.set_status(run_id, status, reason)
            self.store.checkpoint()  # the end of a run segment: the .db file alone is complete
            self.store.release(run_id)  # settled: any process may resume it now
            self.state = RunState.FINISHED
        _log.info("run %d %s%s", run_id, status, f": {reason}" if reason else "")
        return RunResult(run_id, status, reason, len(self.store.stored_steps(run_id)), exception)

    def _loop(self, plan: Plan, run_id: int, stored: dict[int, Any], start_at: int, *, final: bool = False) -> None:
        reply, index = None, 0
        ending = (RunState.HALTING,) if final else (RunState.ABORTING, RunState.HALTING)
        while True:
            if self.state in ending:
                return
            try:
                step = plan.send(reply)
            except StopIteration:
                return
            if index in stored:
                reply = stored[index]
            elif index < start_at:
                reply = None
                self._payload.skipped(step)
            else:
                again = self._payload.to_confirm_before(step, clean_up=final)
                if again is not None:  # a resume: the payload in force here may have come off since the stop
                    self._act(again, run_id, index)
                    if self.state in ending:
                        return
                    self._payload.performed(again)
                self.current_step = step
                reply = self._act(step, run_id, index)
                self.current_step = None
                if self.state is not RunState.HALTING:  # not a withdrawn prompt
                    self._payload.performed(step)
            if isinstance(step, Checkpoint) and not final and index >= start_at:
                # the .db file alone holds every sample so far once this checkpoint has run on the writer thread,
                # during the next move (the next sample is stored after it); a pause or an end waits for it here
                assert self._recorder is not None, "a checkpoint outside a run"
                self._recorder.checkpoint()
                if self._pause_requested or self.state is not RunState.RUNNING:
                    self._await_commit()
                if self._at_checkpoint(step):
                    return
            index += 1

    def _payload_off(self) -> None:
        """After the clean-up (the robot home), ask for a payload still on to come off (:class:`MountedPayload`).
        A withdrawn confirmation does not change how the run ended: its samples are stored; the log says the
        payload may still be on."""
        prompt = self._payload.removal()
        if prompt is None or self.state is RunState.HALTING:
            return
        try:
            self.rig.operator.ask(prompt)
        except PromptWithdrawn as exc:
            _log.warning(
                "run %d: the operator did not confirm %r (%s): the %g kg payload may still be on the end effector",
                self.run_id,
                prompt.text,
                exc,
                self._payload.load_kg,
            )
            return
        self._payload.performed(prompt)

    def _at_checkpoint(self, step: Checkpoint) -> bool:
        """Handle pause and stop requests; True when the run must end here."""
        if self._pause_requested and self.state is RunState.RUNNING:
            # (a request from another thread may have come after the loop's look): the operator is told only once
            # every sample so far is durable and the .db file holds them (at once if the loop waited already)
            self._await_commit()
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
        if isinstance(step, (Move, ActuatorMove)) and self.state is RunState.HALTING:
            return None  # an emergency stop came after the loop's check: never start a move after it
        if isinstance(step, Move):
            assert self.plan is not None, "a move before the run's pre-flight"
            self.plan.require(step)  # proved by the pre-flight, or (an adaptive plan's) checked alone now
            rig.robot.move_to(tuple(step.target), velocity_pct=step.velocity_pct)
            return None
        if isinstance(step, ActuatorMove):
            assert self.plan is not None, "a move before the run's pre-flight"
            self.plan.require(step)
            rig.robot.move_actuator(step.axis, step.stroke_mm, velocity_pct=step.velocity_pct)
            return None
        if isinstance(step, Settle):
            self._settle(step.duration_s / rig.speed_factor)
            return None
        if not isinstance(step, (Move, ActuatorMove, Settle, Checkpoint)):
            self._await_commit()  # only motion overlaps a commit: a failed one stops the run before this step
        if isinstance(step, Capture):
            measured = rig.instrument.measure(step)
            values = {**step.commanded, **measured.values, **step.conditions}
            self._record(index, values, kind=step.kind, pose=step.pose, cycle=step.cycle, raw=measured.raw)
            return values
        if isinstance(step, Prompt):
            try:
                answer = rig.operator.ask(step)
            except PromptWithdrawn as exc:
                self._withdrawn(step, exc)
                return None
            if step.field is not None:
                if answer is None:
                    raise ConfigError(
                        f"prompt {step.text!r}: no value given for {step.field}; an operator who "
                        "will not answer raises PromptWithdrawn"
                    )
                values = {**step.commanded, step.field: float(answer), **step.conditions}
                raw = {"field": step.field, "entered": float(answer)}
                if isinstance(answer, Entry):  # the text as typed (or the gauge's line), beside the value
                    raw["typed"] = answer.typed
                self._record(index, values, kind=step.kind, pose=step.pose or None, cycle=step.cycle or None, raw=raw)
            return answer
        if isinstance(step, Checkpoint):
            return None
        raise ConfigError(
            f"protocol yielded {step!r}, expected a Move, ActuatorMove, Settle, Capture, Prompt or Checkpoint"
        )

    def _settle(self, wait_s: float) -> None:
        if self.rig.sleep is not None:  # a test stand-in
            self.rig.sleep(wait_s)
        else:
            self._wake.wait(wait_s)

    def _record(self, index: int, values: dict[str, float], **sample: Any) -> None:
        assert self._recorder is not None, "a sample outside a run"
        self._recorder.add(index, values, **sample)

    def _await_commit(self) -> None:
        """Wait until the last sample taken is durable (raising the failure of its commit); it is reported then."""
        if self._recorder is not None:
            self._recorder.await_commit()

    def _durable(self, sample: dict[str, Any]) -> None:
        """A sample's commit is durable: count it, advance the bar, tell ``on_sample``."""
        self.samples_stored += 1
        if self._bar is not None:
            self._bar.advance()
        self._call_hook(self.on_sample, self, sample)

    @staticmethod
    def _call_hook(hook: Callable[..., None] | None, *args: Any) -> None:
        """An observer's failure is logged, never the run's: the sample it was told about is already stored."""
        if hook is None:
            return
        try:
            hook(*args)
        except Exception:  # noqa: BLE001
            _log.exception("runner: hook %r failed", hook)

    def _withdrawn(self, prompt: Prompt, exc: PromptWithdrawn) -> None:
        """End now (no clean-up moves: the operator may be at the robot), unless already ending at once."""
        with self._lock:
            if self.state is RunState.HALTING:
                return  # e.g. the emergency stop withdrew the prompt: its reason stands
            detail = f" ({exc})" if str(exc) else ""
            self._transition_locked(RunState.HALTING)
            self._reason = f"prompt withdrawn by the operator: {prompt.text}{detail}"

    def _stop_robot(self, *, emergency: bool = False) -> None:
        """Stop the robot (best effort); an emergency stop latches where the robot offers it (no move after it)."""
        robot = self.rig.robot
        try:
            (robot.emergency_stop if emergency else robot.stop)()
        except Exception as exc:  # noqa: BLE001 - stopping is best effort; shutdown follows
            _log.error("robot stop failed: %s", exc)

    def _shutdown(self) -> None:
        try:
            self.rig.robot.shutdown()
        except Exception as exc:  # noqa: BLE001
            _log.error("robot shutdown failed: %s", exc)
