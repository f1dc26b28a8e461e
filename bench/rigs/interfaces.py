"""The rig: the robot, the instrument and the operator a runner performs steps with (structural interfaces).

The runner only knows these three small interfaces (bluesky's ``Movable`` and ``Readable``), so the same
runner drives a real robot over ``/dev/ttyUSB0``, a simulator over a pseudo-terminal, or a recording stand-in
in tests. Concrete rigs are built in :mod:`bench.simulators.rig` (simulators) and by the CLI (hardware).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any
from typing import Protocol as Interface

from bench.steps import Capture, Prompt

__all__ = ["Entry", "Instrument", "Measurement", "Mover", "Operator", "Rig"]


class Mover(Interface):
    """A robot: moves to a target in mm and degrees, stops at once, and shuts down to a safe state.

    ``stop()`` must be safe to call from another thread while ``move_to`` waits for the move to end (the runner's
    :meth:`~bench.protocols.runner.Runner.emergency_stop`): it sends the stop at once, and the waiting move then
    returns or raises. The pkm5 driver sends only its ``STOP`` line in that case (the move ends with ``ERR 8
    STOPPED``); the delta4 driver's stop is one ``G`` byte (the move then misses its ``z`` and raises).
    """

    def move_to(self, target: tuple[float, ...], *, velocity_pct: float) -> None: ...

    def stop(self) -> None: ...

    def shutdown(self) -> None: ...

    def settings(self) -> dict[str, Any]: ...


@dataclass(frozen=True)
class Measurement:
    """What an instrument returns for a capture: values with the unit in every key, and the raw data."""

    values: Mapping[str, float]
    raw: Any = None


class Instrument(Interface):
    """Measures the attained pose (or whatever ``capture.kind`` asks for)."""

    def measure(self, capture: Capture) -> Measurement: ...

    def settings(self) -> dict[str, Any]: ...


class Entry(float):
    """A reading as the operator (or the calliper's data line) gave it: the number, and ``typed``, the text it was
    read from (``"12,34"``, ``"0.4865 in"``, a gauge's ``"+012.34 mm"``). The runner stores the text beside the
    value, so a misread entry can be traced to what was typed. It is a float for everything else.

    >>> entry = Entry(12.34, "12,34")
    >>> entry + 1.0, entry.typed
    (13.34, '12,34')
    """

    typed: str

    def __new__(cls, value: float, typed: str) -> Entry:
        entry = super().__new__(cls, value)
        entry.typed = typed
        return entry

    def __repr__(self) -> str:
        return f"Entry({float(self)!r}, {self.typed!r})"


class Operator(Interface):
    """Answers prompts: a reading within the prompt's bounds (an :class:`Entry` when it was typed or read from a
    gauge's line, so that the text is kept), or None to confirm an instruction.

    An operator who will not answer (Cancel, the window closing) raises :class:`bench.errors.PromptWithdrawn`: the
    run ends as ``aborted`` and can be resumed. None for a reading prompt is a defect of the operator, not a
    withdrawal, and fails the run.
    """

    def ask(self, prompt: Prompt) -> float | None: ...


@dataclass
class Rig:
    """Everything a run acts on.

    ``speed_factor`` is how much faster than real time the rig runs (a simulator started with
    ``--speed-factor``; 1 for hardware): settle times are divided by it and sample times multiplied by it, so
    ``t_s`` counts the rig's own seconds (:meth:`time_base`); ``clock`` is the wall clock those times are read from
    (monotonic). ``sleep`` is None for a real or simulated rig, so that the runner waits out a ``Settle`` on an event
    an emergency stop can cut short; a test stand-in may pass a function (e.g. one that returns at once).
    """

    robot: Mover
    instrument: Instrument
    operator: Operator
    speed_factor: float = 1.0
    calibration_ids: tuple[int, ...] = ()
    sleep: Callable[[float], None] | None = None
    clock: Callable[[], float] = time.monotonic
    closers: list[Callable[[], None]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def time_base(self) -> str:
        """What a sample's ``t_s`` counts: ``wall s``, or ``simulated s (wall x speed factor F)`` on a rig that runs
        F times faster than real time."""
        if self.speed_factor == 1:
            return "wall s"
        return f"simulated s (wall x speed factor {self.speed_factor:g})"

    def settings(self) -> dict[str, Any]:
        """Robot and instrument settings (plus ``extra``, e.g. the simulator's seed), stored with the run."""
        return {
            "robot": self.robot.settings(),
            "instrument": self.instrument.settings(),
            "speed_factor": self.speed_factor,
            "time_base": self.time_base(),
            **self.extra,
        }

    def close(self) -> None:
        """Release what the rig started (simulator processes, ports), newest first."""
        while self.closers:
            self.closers.pop()()
