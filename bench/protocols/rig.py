"""The rig: the robot, the instrument and the operator a runner performs steps with (structural interfaces).

The runner only knows these three small interfaces (bluesky's ``Movable`` and ``Readable``), so the same
runner drives a real robot over ``/dev/ttyUSB0``, a simulator over a pseudo-terminal, or a recording stand-in
in tests. Concrete rigs are built in :mod:`bench.protocols.simrig` (simulators) and by the CLI (hardware).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any
from typing import Protocol as Interface

from bench.protocols.steps import Capture, Prompt

__all__ = ["Instrument", "Measurement", "Mover", "Operator", "Rig"]


class Mover(Interface):
    """A robot: moves to a target in mm and degrees, stops at once, and shuts down to a safe state."""

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


class Operator(Interface):
    """Answers prompts: a reading within the prompt's bounds, or None to confirm an instruction."""

    def ask(self, prompt: Prompt) -> float | None: ...


@dataclass
class Rig:
    """Everything a run acts on; ``speed_factor`` divides settle times (simulated rigs run faster than real)."""

    robot: Mover
    instrument: Instrument
    operator: Operator
    speed_factor: float = 1.0
    calibration_ids: tuple[int, ...] = ()
    sleep: Callable[[float], None] = time.sleep
    closers: list[Callable[[], None]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def settings(self) -> dict[str, Any]:
        """Robot and instrument settings (plus ``extra``, e.g. the simulator's seed), stored with the run."""
        return {"robot": self.robot.settings(), "instrument": self.instrument.settings(),
                "speed_factor": self.speed_factor, **self.extra}

    def close(self) -> None:
        """Release what the rig started (simulator processes, ports), newest first."""
        while self.closers:
            self.closers.pop()()
