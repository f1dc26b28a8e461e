"""bench.protocols: scripted test protocols (generators of frozen steps), their pre-flight, and the runner.

A protocol is a TOML file (``protocol = "<name>"`` plus typed parameters) and a :class:`Protocol` class whose
``steps()`` generator yields ``Move``/``Settle``/``Capture``/``Prompt``/``Checkpoint``. :func:`preflight` checks
every target with motion/ before anything moves; :class:`Runner` performs the steps on a :class:`Rig` and stores
every sample at once in a :class:`bench.store.Store`.
"""

from bench.protocols import actuator, delta, dissertation, iso9283, iterative, path, positioning_time  # noqa: F401 - registers the protocol library
from bench.protocols.base import (
    PROTOCOLS,
    Protocol,
    load_protocol,
    protocol_from_config,
    register,
)
from bench.protocols.plan import PlanSummary, preflight, summarize
from bench.protocols.runner import Runner, RunResult, RunState, TransitionError
from bench.rigs.interfaces import Measurement, Rig
from bench.steps import Capture, Checkpoint, Move, Prompt, Settle

__all__ = [
    "PROTOCOLS",
    "Capture",
    "Checkpoint",
    "Measurement",
    "Move",
    "PlanSummary",
    "Prompt",
    "Protocol",
    "Rig",
    "RunResult",
    "RunState",
    "Runner",
    "Settle",
    "TransitionError",
    "load_protocol",
    "preflight",
    "protocol_from_config",
    "register",
    "summarize",
]
