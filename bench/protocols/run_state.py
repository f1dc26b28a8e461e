"""The runner's states, their legal transitions, and how a run ended (:mod:`bench.protocols.runner`)."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from bench.errors import BenchError

__all__ = ["TRANSITIONS", "RunResult", "RunState", "TransitionError"]


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
