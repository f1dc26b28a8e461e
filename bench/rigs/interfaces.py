"""The rig: the robot, the instrument and the operator a runner performs steps with (structural interfaces).

The runner only knows these three small interfaces (bluesky's ``Movable`` and ``Readable``), so the same
runner drives a real robot over ``/dev/ttyUSB0``, a simulator over a pseudo-terminal, or a recording stand-in
in tests. Rigs are built by :mod:`bench.rigs.builder` (a station, real or rehearsed) and
:mod:`bench.simulators.rig` (the bare simulators).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any
from typing import Protocol as Interface

from bench.rigs.station import Station, station_identity
from bench.steps import Capture, Prompt

__all__ = [
    "Entry",
    "Instrument",
    "KinematicCalibration",
    "Measurement",
    "Mover",
    "Operator",
    "Rig",
    "SimulatorRecord",
]


class Mover(Interface):
    """A robot: moves to a target in mm and degrees, stops at once, and shuts down to a safe state.

    Everything the runner calls on a robot, and nothing more. ``kind`` names the robot's record in
    :mod:`bench.robot_kinds` and ``geometry`` is the geometry it commands every move by (None: the documented one;
    a kinematic calibration in force replaces it): the runner's pre-flight checks each target by that model and
    geometry, the very ones the move is then commanded by.

    ``stop()`` and ``emergency_stop()`` must be safe to call from another thread while ``move_to`` waits for the
    move to end (the runner's :meth:`~bench.protocols.runner.Runner.emergency_stop`): they send the stop at once,
    and the waiting move then returns or raises. ``emergency_stop()`` also refuses every later move until a person
    releases it. The pkm5 driver sends only its ``STOP`` line in that case (the move ends with ``ERR 8 STOPPED``);
    the delta4 driver's stop is one ``G`` byte (the move then misses its ``z`` and raises). ``move_actuator`` moves
    one actuator of an actuator bench; a robot without one raises :class:`bench.errors.ConfigError`.
    """

    @property
    def kind(self) -> str: ...

    @property
    def geometry(self) -> Any: ...

    def move_to(self, target: tuple[float, ...], *, velocity_pct: float) -> None: ...

    def move_actuator(self, axis: int, stroke_mm: float, *, velocity_pct: float) -> None: ...

    def stop(self) -> None: ...

    def emergency_stop(self) -> None: ...

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


@dataclass(frozen=True)
class KinematicCalibration:
    """The kinematic calibration a rig commands by, as the run stores it (``settings.kinematic_calibration``):
    ``id`` None when none is in force, and ``reason`` why (or why this one)."""

    reason: str
    id: int | None = None
    name: str | None = None
    version: int | None = None
    source_run_id: int | None = None

    def settings(self) -> dict[str, Any]:
        """The stored record: ``{"id": None, "reason": ...}`` for none, every field for one in force."""
        if self.id is None:
            return {"id": None, "reason": self.reason}
        return {
            "id": self.id,
            "name": self.name,
            "version": self.version,
            "source_run_id": self.source_run_id,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class SimulatorRecord:
    """What the simulators standing in for the hardware were started with (``settings.simulator`` of a run), so a
    resume starts them alike: the seed, ``ideal`` (no error model), the seed of the true geometry, and for a station
    rehearsal the station file and the simulator's log of true poses."""

    seed: int
    ideal: bool = False
    true_geometry_seed: int | None = None
    station: str | None = None
    truth_log: str | None = None

    def settings(self) -> dict[str, Any]:
        """The stored record: the seed, then only what differs from the default."""
        out: dict[str, Any] = {"seed": self.seed}
        if self.station is not None:
            out["station"] = self.station
        if self.truth_log is not None:
            out["truth_log"] = self.truth_log
        if self.ideal:
            out["ideal"] = True
        if self.true_geometry_seed is not None:
            out["true_geometry_seed"] = self.true_geometry_seed
        return out


@dataclass
class Rig:
    """Everything a run acts on.

    ``speed_factor`` is how much faster than real time the rig runs (a simulator started with
    ``--speed-factor``; 1 for hardware): settle times are divided by it and sample times multiplied by it, so
    ``t_s`` counts the rig's own seconds (:meth:`time_base`); ``clock`` is the wall clock those times are read from
    (monotonic). ``sleep`` is None for a real or simulated rig, so that the runner waits out a ``Settle`` on an event
    an emergency stop can cut short; a test stand-in may pass a function (e.g. one that returns at once).

    What the run stores about the rig besides its devices' settings (:meth:`settings`): the ``station`` it was built
    from (its settings and the device under test), the ``registration`` of its relative instruments at home (the
    mice: :mod:`bench.rigs.registration`; the runner files it per run segment), the ``kinematic_calibration`` in
    force (:mod:`bench.calibration.compensate`; None: none was selected) and the ``simulator`` standing in.
    """

    robot: Mover
    instrument: Instrument
    operator: Operator
    speed_factor: float = 1.0
    calibration_ids: tuple[int, ...] = ()
    sleep: Callable[[float], None] | None = None
    clock: Callable[[], float] = time.monotonic
    closers: list[Callable[[], None]] = field(default_factory=list)
    station: Station | None = None
    registration: dict[str, Any] | None = None
    kinematic_calibration: KinematicCalibration | None = None
    simulator: SimulatorRecord | None = None

    def time_base(self) -> str:
        """What a sample's ``t_s`` counts: ``wall s``, or ``simulated s (wall x speed factor F)`` on a rig that runs
        F times faster than real time."""
        if self.speed_factor == 1:
            return "wall s"
        return f"simulated s (wall x speed factor {self.speed_factor:g})"

    def settings(self) -> dict[str, Any]:
        """Robot and instrument settings, the time base, and what the rig records beside them (the station and
        device under test, the kinematic calibration in force, the simulator), stored with the run. The
        registration is not among them: the runner files it per run segment."""
        out: dict[str, Any] = {
            "robot": self.robot.settings(),
            "instrument": self.instrument.settings(),
            "speed_factor": self.speed_factor,
            "time_base": self.time_base(),
        }
        if self.station is not None:
            out["station"] = self.station.settings()
            out["dut"] = station_identity(self.station)
        if self.kinematic_calibration is not None:
            out["kinematic_calibration"] = self.kinematic_calibration.settings()
        if self.simulator is not None:
            out["simulator"] = self.simulator.settings()
        return out

    def close(self) -> None:
        """Release what the rig started (simulator processes, ports), newest first."""
        while self.closers:
            self.closers.pop()()
