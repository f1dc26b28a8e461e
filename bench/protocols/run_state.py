"""The runner's states, the requests that move between them, and how a run ended (:mod:`bench.protocols.runner`)."""

from __future__ import annotations

import enum
import logging
import threading
from dataclasses import dataclass

from bench.errors import BenchError

__all__ = ["TRANSITIONS", "RunControl", "RunResult", "RunState", "TransitionError"]

_log = logging.getLogger("bench.protocols.runner")


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


@dataclass(frozen=True)
class RunResult:
    """How a run ended: ``exit_status`` is the stored status (completed, aborted, failed)."""

    run_id: int
    exit_status: str
    reason: str | None
    samples: int
    exception: BaseException | None = None


class RunControl:
    """The run's state and the requests that change it (thread-safe: a window or a signal handler asks, the run's
    own thread honours them at its safe points); :class:`bench.protocols.runner.Runner` is one."""

    def __init__(self) -> None:
        self.state = RunState.IDLE
        self._lock = threading.Lock()
        self._wake = threading.Event()  # set to cut a Settle short (abort, halt, emergency stop)
        self._pause_requested = False
        self._emergency = False
        self._reason: str | None = None

    def _transition(self, new: RunState) -> None:
        with self._lock:
            self._transition_locked(new)

    def _transition_locked(self, new: RunState) -> None:
        if new not in TRANSITIONS[self.state]:
            raise TransitionError(f"runner: cannot go from {self.state.value} to {new.value}")
        _log.info("runner: %s -> %s", self.state.value, new.value)
        self.state = new

    def _end(self, new: RunState, reason: str) -> None:
        """Go to an ending state with ``reason``; a refused request leaves the reason of the current end alone."""
        with self._lock:
            self._transition_locked(new)
            self._reason = reason

    @property
    def pause_requested(self) -> bool:
        """A pause is asked for and the run has not reached its checkpoint yet."""
        return self._pause_requested

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
        self._end(RunState.STOPPING, reason)

    def abort(self, reason: str = "aborted by the operator") -> None:
        """Stop the robot after the current step (a Settle is cut short) and end; clean-up steps still run."""
        self._end(RunState.ABORTING, reason)
        self._wake.set()

    def halt(self, reason: str = "halted by the operator") -> None:
        """Stop the robot after the current step (a Settle is cut short) and end without clean-up steps."""
        self._end(RunState.HALTING, reason)
        self._wake.set()
