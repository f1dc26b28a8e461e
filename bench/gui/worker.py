"""The campaign worker: runs queued protocols (or resumes a stored run) with bench's runner in a QThread.

The worker owns everything that touches the rig and the store during a run: it opens its own
:class:`bench.store.Store` (a SQLite connection belongs to the thread that made it), builds the rig with the same
function as ``bench run`` (:func:`bench.launch.open_rig`), and drives :class:`bench.protocols.Runner`.
It talks to the window only through Qt signals. Requests from the window (pause, resume, stop, abort, halt) go to
the runner's own thread-safe request methods; the runner honours them at its safe points. The emergency stop goes
to :meth:`bench.protocols.Runner.emergency_stop` at once, from the stop thread of :mod:`bench.gui.estop` (never
the window's thread: a driver's stop may wait for its acknowledgement).

The runner's hooks report to the window: ``on_start`` (run id, samples in all, samples already stored) and
``on_sample`` (after the store committed it, so the live view shows only what is already on disk). At the start of
a resumed run the samples already stored are read in the worker's thread and sent once (``samples_loaded``);
every sample carries its ``step_index`` and the wall-clock time it was stored (``wall_s``, Unix seconds), so the
live view can de-duplicate and draw in real time.
:meth:`CampaignWorker.answer_prompt` is the operator's ``answer``: it asks the window for a calliper reading and
waits for the operator's entry, or raises :class:`bench.errors.PromptWithdrawn` when the operator cancels.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import queue
import time
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from PySide6.QtCore import QThread, Signal

from bench.calibration.compensate import NEWEST, describe_in_force
from bench.errors import BenchError, PromptWithdrawn
from bench.launch import RigRequest, open_rig, resuming
from bench.protocols import Prompt, Protocol, Runner, RunState, TransitionError, protocol_from_config
from bench.protocols.plan import PlanSummary, preflight
from bench.protocols.resume import stored_replies
from bench.rigs.interfaces import Entry
from bench.store import Store

__all__ = ["CampaignWorker", "RigSpec", "WindowOperator"]

_log = logging.getLogger(__name__)

#: How often a waiting worker looks at its cancellation flag, s.
_POLL_S = 0.05


@dataclass(frozen=True)
class RigSpec:
    """Where a campaign runs: the robot, and a station file (``simulate``: rehearsed on simulators), a serial port
    with two mice, or the simulator (neither). :meth:`request` hands it to :func:`bench.launch.open_rig`, the
    same function ``bench run`` uses."""

    robot: str = "pkm5"
    port: str | None = None
    seed: int = 0
    speed_factor: float = 10000.0
    mouse_xy: str | None = None
    mouse_xz: str | None = None
    #: "guided" for an x-z mouse on vertical guides; None: on the platform (the station default)
    mouse_xz_mount: str | None = None
    simulated_calliper: bool = False
    station: str | None = None
    simulate: bool = False
    #: the kinematic calibration the runs command by: NEWEST (a resume: its run's own), OFF, or a calibration id
    kinematic_calibration: int | str = NEWEST

    def request(self) -> RigRequest:
        # the seed and the speed factor are the simulators'; real hardware (a port, a station not rehearsed) has
        # neither, and open_rig refuses them there
        hardware = self.port is not None or (self.station is not None and not self.simulate)
        return RigRequest(
            station=self.station,
            port=self.port,
            mouse_xy=self.mouse_xy,
            mouse_xz=self.mouse_xz,
            mouse_xz_mount=self.mouse_xz_mount,
            simulate=self.simulate,
            seed=None if hardware else self.seed,
            speed_factor=None if hardware else self.speed_factor,
            kinematic_calibration=self.kinematic_calibration,
        )


class CampaignWorker(QThread):
    """Runs ``jobs`` one after the other: each job is a :class:`Protocol` to run or an ``int`` run id to resume.

    Signals carry plain data; the window never calls the runner except through :meth:`request`.
    """

    run_started = Signal(int, int, int)  #: run id, samples the run will store in all, samples already stored
    samples_loaded = Signal(int, float, list)  #: run id, its start (Unix s), the samples stored before (resume)
    sample_stored = Signal(int, dict)  #: run id, {"step_index", "kind", "pose", "cycle", "t_s", "values", "raw"}
    state_changed = Signal(str)  #: the runner's state (running, paused, stopping, ...)
    prompt_requested = Signal(object)  #: a :class:`Prompt` waiting for a reading
    run_finished = Signal(object)  #: a :class:`bench.protocols.RunResult`
    failed = Signal(str)  #: a job that could not start (bad configuration, simulator did not start...)
    message = Signal(str)  #: a line for the log

    def __init__(
        self,
        store_path: str,
        jobs: list[Protocol | int],
        rig_spec: RigSpec,
        *,
        campaign: str | None = None,
        parent: Any = None,
    ) -> None:
        super().__init__(parent)
        self.store_path = store_path
        self.jobs = list(jobs)
        self.rig_spec = rig_spec
        self.campaign = campaign
        self.runner: Runner | None = None
        self._answers: queue.Queue[float | PromptWithdrawn] = queue.Queue()
        self._decided = queue.Queue()
        self._cancelled = False
        self._emergency = False
        self.reading_number: tuple[int, int] | None = None  #: (k, n) of the reading being asked
        self._readings = (0, 0)

    # ---- requests from the window (GUI thread) ---------------------------------------------------------------

    def request(self, action: str) -> None:
        """``pause``, ``resume``, ``stop``, ``abort`` or ``halt`` the current run through the runner.

        A request the runner's state does not allow (e.g. resume while running) is reported on ``message``.
        """
        runner = self.runner
        if runner is None:
            self.message.emit(f"{action}: no run in progress")
            return
        methods = {
            "pause": runner.request_pause,
            "resume": runner.resume,
            "stop": runner.stop,
            "abort": runner.abort,
            "halt": runner.halt,
        }
        try:
            methods[action]()
        except TransitionError as exc:
            self.message.emit(str(exc))
            return
        if action in ("stop", "abort", "halt"):
            self.jobs.clear()  # the queue ends with the run the operator ended
        if runner.state is not RunState.PAUSED:
            self._decided.put(action)
        self.state_changed.emit(runner.state.value if action != "pause" else "pause requested")

    def emergency_stop(self) -> None:
        """Stop the robot now and end the run (aborted, resumable, no clean-up moves); drop the queue.

        Called on the stop thread (:class:`bench.gui.estop.EmergencyStop`), never the window's: the runner sends the
        robot's stop from here, at once, and may wait for its acknowledgement. A pending prompt is withdrawn, and a
        run whose rig is still starting ends before its first step. Touches no widget (signals only).
        """
        self._emergency = True
        self.jobs.clear()
        runner = self.runner
        if runner is not None:
            runner.emergency_stop()
            self.state_changed.emit(runner.state.value)
        self.withdraw("emergency stop")
        self._decided.put("halt")

    def shut_down(self, reason: str = "window closed") -> None:
        """End safely: stop at the next checkpoint (resumable), withdraw any pending prompt, drop the queue."""
        self._cancelled = True
        self.jobs.clear()
        runner = self.runner
        if runner is not None:
            try:
                runner.stop(f"stopped: {reason}")
            except TransitionError:
                pass  # already stopping, aborting or finished
        self.withdraw(reason)
        self._decided.put("stop")

    def answer(self, value: float) -> None:
        """The operator's reading for the pending prompt (any number confirms an instruction)."""
        self._answers.put(value)

    def withdraw(self, why: str) -> None:
        """Withdraw the pending prompt: the run ends aborted (resumable) with ``why`` in its reason."""
        self._answers.put(PromptWithdrawn(why))

    # ---- the thread ------------------------------------------------------------------------------------------

    def run(self) -> None:
        try:  # a store that cannot be written (damaged after an unclean end, another application's) ends the queue
            opened = Store(self.store_path)
        except BenchError as exc:
            self.jobs.clear()
            self.failed.emit(str(exc))
            return
        with opened as store:
            while self.jobs and not self._cancelled:
                with contextlib.ExitStack() as held:
                    self._start_job(self.jobs.pop(0), store, held)

    def _start_job(self, job: Protocol | int, store: Store, held: contextlib.ExitStack) -> None:
        """Open the rig of ``job`` and run it; a resume is held as ``bench resume`` holds it (:func:`resuming`) until
        ``held`` closes, so the window refuses and accepts a resume exactly as the command line does."""
        robot = "robot"
        try:
            stored = None
            if isinstance(job, int):
                stored = held.enter_context(resuming(store, job)).settings
                protocol = protocol_from_config(store.run(job).config, source=f"run {job}", stored=True)
            else:
                protocol = job
            robot = protocol.robot
            # the one walk of the plan (a resumed one as it ran) before the rig opens: its capabilities, and a
            # plain refusal before anything starts; the runner re-checks it by the rig's geometry
            early = preflight(protocol, stored=stored_replies(store, job) if isinstance(job, int) else None)
            request = self.rig_spec.request()
            if isinstance(job, int):  # a resume keeps the run's own seed and speed factor (its time base)
                request = dataclasses.replace(request, seed=None, speed_factor=None)
            self.message.emit(f"starting the {robot} rig ({request.describe()})")
            rig = open_rig(
                request,
                store,
                robot=robot,
                stored=stored,
                fixture=getattr(protocol, "fixture", "assembled"),
                requires=early.capabilities,
                protocol=f"protocol {protocol.name!r}",
                operator=None if request.simulator_default else WindowOperator(self),
            )
            self.message.emit(describe_in_force(rig))
        except BenchError as exc:
            self.failed.emit(str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - reported in the window, never a silent thread death
            _log.exception("rig for %s could not start", robot)
            self.failed.emit(f"rig for {robot}: {type(exc).__name__}: {exc}")
            return
        try:
            self._run_job(job, rig, store, early)
        finally:
            rig.close()
            self.runner = None

    def _run_job(self, job: Protocol | int, rig: Any, store: Store, early: PlanSummary) -> None:
        assembled = rig.robot.settings().get("fixture", "assembled") == "assembled"
        if self.rig_spec.request().simulator_default and assembled and not self.rig_spec.simulated_calliper:
            # the simulated operator still tells the simulator the payload; the person types the readings
            # (on the simulated actuator bench the simulated depth gauge reads the travel itself)
            rig.operator.answer = self.answer_prompt
        runner = Runner(
            rig,
            store,
            on_pause=self._on_pause,
            on_start=lambda r: self._started(r, job, store),
            on_sample=lambda r, sample: self.sample_stored.emit(r.run_id, dict(sample, wall_s=time.time())),
        )
        self.runner = runner
        if self._emergency:  # pressed while the rig was starting (emergency_stop saw no runner yet)
            runner.emergency_stop()
        self.state_changed.emit("starting")  # "running" once the runner is (its on_start)
        try:
            if isinstance(job, int):
                result = runner.resume_run(job, plan=early)
            else:
                result = runner.run(job, campaign=self.campaign, plan=early)
        except BenchError as exc:  # refused before the run started (pre-flight, resume checks)
            self.failed.emit(str(exc))
            return
        self.state_changed.emit("finished")
        self.run_finished.emit(result)

    def _started(self, runner: Runner, job: Protocol | int, store: Store) -> None:
        """The runner's ``on_start`` (worker thread): tell the window, with what a resumed run already holds."""
        run_id = runner.run_id
        self.run_started.emit(run_id, runner.samples_total, runner.samples_stored)
        self.state_changed.emit(runner.state.value)
        record = store.run(run_id)
        stored = store.samples(run_id) if runner.samples_stored else []
        self.samples_loaded.emit(
            run_id,
            _unix_s(record.started_utc),
            [
                {
                    "step_index": s.step_index,
                    "kind": s.kind,
                    "pose": s.pose,
                    "cycle": s.cycle,
                    "t_s": s.t_s,
                    "wall_s": _unix_s(s.wall_utc),
                    "values": s.values,
                    "raw": s.raw,
                }
                for s in stored
            ],
        )
        total = runner.plan.readings if runner.plan is not None else 0  # the run's pre-flight counted them
        taken = sum(1 for s in stored if isinstance(s.raw, dict) and "field" in s.raw and "entered" in s.raw)
        self._readings = (taken, total)

    def _on_pause(self, runner: Runner) -> None:
        """Called by the runner (worker thread) at a checkpoint: wait until the window resumes, stops or aborts."""
        self.state_changed.emit("paused")
        while runner.state is RunState.PAUSED:
            if self._cancelled:
                runner.stop("stopped: window closed while paused")
                break
            try:
                self._decided.get(timeout=_POLL_S)
            except queue.Empty:
                continue
        self.state_changed.emit(runner.state.value)

    def answer_prompt(self, prompt: Prompt) -> float | None:
        """Ask the window for the reading (or, when ``prompt.field`` is None, the confirmation) and wait for it.

        Called in the worker thread, by the simulated operator (as its ``answer``) or by :class:`WindowOperator`.

        Raises
        ------
        PromptWithdrawn
            The operator cancelled the dialog, the window closed or the emergency stop was pressed.
        """
        while not self._answers.empty():  # a stale withdrawal from an earlier prompt
            self._answers.get_nowait()
        if self._cancelled or self._emergency:
            raise PromptWithdrawn("not asked: " + ("the window is closing" if self._cancelled else "emergency stop"))
        if prompt.field is not None:
            taken, total = self._readings
            self._readings = (taken + 1, max(total, taken + 1))
            self.reading_number = self._readings
        self.prompt_requested.emit(prompt)
        value = self._answers.get()
        if isinstance(value, PromptWithdrawn):
            raise value
        if prompt.field is None:
            return None
        return value if isinstance(value, Entry) else float(value)  # an Entry keeps the text as typed


def _unix_s(utc: str) -> float:
    """Unix seconds of a stored ISO 8601 UTC time (``2026-12-01T23:05:01.123456+00:00``)."""
    return datetime.fromisoformat(utc.replace("Z", "+00:00")).timestamp()


class WindowOperator:
    """The rig's operator on hardware: every prompt (reading or confirmation) is answered in the window."""

    def __init__(self, worker: CampaignWorker) -> None:
        self.worker = worker

    def ask(self, prompt: Prompt) -> float | None:
        return self.worker.answer_prompt(prompt)
