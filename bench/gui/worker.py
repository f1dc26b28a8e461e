"""The campaign worker: runs queued protocols (or resumes a stored run) with bench's runner in a QThread.

The worker owns everything that touches the rig and the store during a run: it opens its own
:class:`bench.store.Store` (a SQLite connection belongs to the thread that made it), builds the rig with the same
function as ``bench run`` (:func:`bench.commands.campaign.build_rig`), and drives :class:`bench.protocols.Runner`.
It talks to the window only through Qt signals. Requests from the window (pause, resume, stop, abort, halt) go to
the runner's own thread-safe request methods; the runner honours them at its safe points.

Two small adapters connect the runner to the window without changing it:

- :class:`ObservedStore` forwards every call to the store and, once a sample is committed, reports it, so the
  live view shows only what is already on disk;
- :meth:`CampaignWorker.answer_prompt` is the simulated operator's ``answer`` callable: it asks the window for a
  calliper reading and waits for the operator's entry (or a cancellation).
"""

from __future__ import annotations

import argparse
import logging
import queue
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from PySide6.QtCore import QThread, Signal

from bench.errors import BenchError
from bench.protocols import Prompt, Protocol, Runner, RunState, TransitionError
from bench.protocols.plan import iterate
from bench.protocols.runner import step_stores_sample
from bench.store import Store

__all__ = ["CampaignWorker", "ObservedStore", "PromptCancelled", "RigSpec", "WindowOperator", "count_samples"]

_log = logging.getLogger(__name__)

#: How often a waiting worker looks at its cancellation flag, s.
_POLL_S = 0.05


class PromptCancelled(BenchError):
    """A calliper prompt the operator could not answer because the run was stopped or the window closed."""


@dataclass(frozen=True)
class RigSpec:
    """Where a campaign runs: the robot, and the simulator (``port`` None) or a serial port with two mice.

    The fields are those of ``bench run``'s rig options; :meth:`namespace` hands them to the CLI's own
    :func:`bench.commands.campaign.build_rig`.
    """

    robot: str = "pkm5"
    port: str | None = None
    seed: int = 0
    speed_factor: float = 10000.0
    mouse_xy: str | None = None
    mouse_xz: str | None = None
    simulated_calliper: bool = False

    def namespace(self) -> argparse.Namespace:
        return argparse.Namespace(port=self.port, seed=self.seed, speed_factor=self.speed_factor,
                                  mouse_xy=self.mouse_xy, mouse_xz=self.mouse_xz)


def count_samples(protocol: Protocol) -> int:
    """Samples a run of ``protocol`` stores (captures and reading prompts), from a dry run."""
    return sum(1 for step in iterate(protocol, final=False) if step_stores_sample(step))


class ObservedStore:
    """A :class:`Store` that calls ``on_start(run_id)`` and ``on_sample(run_id, step_index, fields)`` after the
    store has committed a new run or a sample; every other call goes straight to the store."""

    def __init__(self, store: Store, on_start: Callable[[int], None],
                 on_sample: Callable[[int, int, dict[str, Any]], None]) -> None:
        self._store = store
        self._on_start = on_start
        self._on_sample = on_sample

    def __getattr__(self, name: str) -> Any:
        return getattr(self._store, name)

    def start_run(self, **kwargs: Any) -> int:
        run_id = self._store.start_run(**kwargs)
        self._on_start(run_id)
        return run_id

    def add_sample(self, run_id: int, step_index: int, **kwargs: Any) -> None:
        self._store.add_sample(run_id, step_index, **kwargs)
        self._on_sample(run_id, step_index, kwargs)


class CampaignWorker(QThread):
    """Runs ``jobs`` one after the other: each job is a :class:`Protocol` to run or an ``int`` run id to resume.

    Signals carry plain data; the window never calls the runner except through :meth:`request`.
    """

    run_started = Signal(int, int, int)  #: run id, samples the run will store in all, samples already stored
    sample_stored = Signal(int, dict)  #: run id, {"step_index", "kind", "pose", "cycle", "t_s", "values"}
    state_changed = Signal(str)  #: the runner's state (running, paused, stopping, ...)
    prompt_requested = Signal(object)  #: a :class:`Prompt` waiting for a reading
    run_finished = Signal(object)  #: a :class:`bench.protocols.RunResult`
    failed = Signal(str)  #: a job that could not start (bad configuration, simulator did not start...)
    message = Signal(str)  #: a line for the log

    def __init__(self, store_path: str, jobs: list[Protocol | int], rig_spec: RigSpec, *,
                 campaign: str | None = None, parent: Any = None) -> None:
        super().__init__(parent)
        self.store_path = store_path
        self.jobs = list(jobs)
        self.rig_spec = rig_spec
        self.campaign = campaign
        self.runner: Runner | None = None
        self._answers: queue.Queue[float | None] = queue.Queue()
        self._decided = queue.Queue()
        self._cancelled = False
        self._total = 0

    # ---- requests from the window (GUI thread) ---------------------------------------------------------------

    def request(self, action: str) -> None:
        """``pause``, ``resume``, ``stop``, ``abort`` or ``halt`` the current run through the runner.

        A request the runner's state does not allow (e.g. resume while running) is reported on ``message``.
        """
        runner = self.runner
        if runner is None:
            self.message.emit(f"{action}: no run in progress")
            return
        methods = {"pause": runner.request_pause, "resume": runner.resume, "stop": runner.stop,
                   "abort": runner.abort, "halt": runner.halt}
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

    def shut_down(self, reason: str = "window closed") -> None:
        """End safely: stop at the next checkpoint (resumable), cancel any reading prompt, drop the queue."""
        self._cancelled = True
        self.jobs.clear()
        runner = self.runner
        if runner is not None:
            try:
                runner.stop(f"stopped: {reason}")
            except TransitionError:
                pass  # already stopping, aborting or finished
        self._answers.put(None)
        self._decided.put("stop")

    def answer(self, value: float | None) -> None:
        """The operator's reading for the pending prompt, or None to cancel it."""
        self._answers.put(value)

    # ---- the thread ------------------------------------------------------------------------------------------

    def run(self) -> None:
        from bench.commands.campaign import build_rig

        with Store(self.store_path) as store:
            observed = ObservedStore(store, self._started, self._stored)
            while self.jobs and not self._cancelled:
                job, robot = self.jobs.pop(0), "robot"
                try:
                    robot = store.run(job).robot if isinstance(job, int) else job.robot
                    stored = store.run(job).settings if isinstance(job, int) else None
                    self.message.emit(f"starting the {robot} rig ({self.rig_spec.port or 'simulator'})")
                    rig = build_rig(self.rig_spec.namespace(), robot, store, stored=stored)
                except BenchError as exc:
                    self.failed.emit(str(exc))
                    continue
                except Exception as exc:  # noqa: BLE001 - reported in the window, never a silent thread death
                    _log.exception("rig for %s could not start", robot)
                    self.failed.emit(f"rig for {robot}: {type(exc).__name__}: {exc}")
                    continue
                try:
                    self._run_job(job, rig, observed)
                finally:
                    rig.close()
                    self.runner = None

    def _run_job(self, job: Protocol | int, rig: Any, store: ObservedStore) -> None:
        if hasattr(rig.operator, "answer"):  # the simulated operator: it also tells the simulator the payload
            if not self.rig_spec.simulated_calliper:
                rig.operator.answer = self.answer_prompt
        else:  # hardware: the person at the window answers instead of the terminal
            rig.operator = WindowOperator(self)
        self.runner = Runner(rig, store, on_pause=self._on_pause)
        self.state_changed.emit("running")
        try:
            if isinstance(job, int):
                from bench.protocols import protocol_from_config

                record = store.run(job)
                self._total = count_samples(protocol_from_config(record.config, source=f"run {job}"))
                self.run_started.emit(job, self._total, record.n_samples)
                result = self.runner.resume_run(job)
            else:
                self._total = count_samples(job)
                result = self.runner.run(job, campaign=self.campaign)
        except BenchError as exc:  # refused before the run started (pre-flight, resume checks)
            self.failed.emit(str(exc))
            return
        self.state_changed.emit("finished")
        self.run_finished.emit(result)

    def _started(self, run_id: int) -> None:
        self.run_started.emit(run_id, self._total, 0)

    def _stored(self, run_id: int, step_index: int, fields: dict[str, Any]) -> None:
        sample = {"step_index": step_index, "kind": fields.get("kind", "pose"), "pose": fields.get("pose"),
                  "cycle": fields.get("cycle"), "t_s": fields.get("t_s"), "values": dict(fields.get("values", {}))}
        self.sample_stored.emit(run_id, sample)

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
        """
        while not self._answers.empty():  # a stale cancellation from an earlier prompt
            self._answers.get_nowait()
        if self._cancelled:
            raise PromptCancelled(f"prompt {prompt.text!r}: not asked, the window is closing")
        self.prompt_requested.emit(prompt)
        started = time.monotonic()
        while True:
            try:
                value = self._answers.get(timeout=_POLL_S)
            except queue.Empty:
                continue
            if value is None:
                wanted = f"no reading for {prompt.field}" if prompt.field else "not confirmed"
                raise PromptCancelled(f"prompt {prompt.text!r}: cancelled after {time.monotonic() - started:.0f} s, "
                                      f"{wanted}")
            return None if prompt.field is None else float(value)


class WindowOperator:
    """The rig's operator on hardware: every prompt (reading or confirmation) is answered in the window."""

    def __init__(self, worker: CampaignWorker) -> None:
        self.worker = worker

    def ask(self, prompt: Prompt) -> float | None:
        return self.worker.answer_prompt(prompt)
