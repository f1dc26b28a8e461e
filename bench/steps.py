"""The frozen steps a protocol yields, and the stubs that compose them (bluesky's ``Msg`` and plan stubs).

A protocol never calls a driver: it yields ``Move``, ``Settle``, ``Capture``, ``Prompt`` and ``Checkpoint`` and
the runner (or a dry run) performs them and sends each step's result back through ``yield``. Targets are in mm
and degrees: ``(x_mm, y_mm, z_mm[, alpha_deg, beta_deg])`` for the pkm5, ``(x_mm, y_mm, z_mm)`` for the delta4.
"""

from __future__ import annotations

from collections.abc import Generator, Mapping
from dataclasses import dataclass
from dataclasses import field as _field
from typing import Any

__all__ = [
    "ActuatorMove",
    "Capture",
    "Checkpoint",
    "MountedPayload",
    "Move",
    "Payload",
    "Plan",
    "Prompt",
    "Settle",
    "Step",
    "commanded_values",
    "confirms_payload",
    "payload_removal",
    "visit",
]


@dataclass(frozen=True)
class Move:
    """Move the robot to ``target`` (mm, degrees) at ``velocity_pct`` of its rated velocity."""

    target: tuple[float, ...]
    velocity_pct: float = 100.0
    label: str = ""


@dataclass(frozen=True)
class ActuatorMove:
    """Actuator bench only (000 §8.4): move actuator ``axis`` (1-6) to ``stroke_mm`` from full retraction while the
    other actuators hold; the rig's robot must have been opened on the actuator bench, or the move is refused."""

    axis: int
    stroke_mm: float
    velocity_pct: float = 100.0
    label: str = ""


@dataclass(frozen=True)
class Settle:
    """Wait ``duration_s`` seconds (simulated time is divided by the rig's speed factor)."""

    duration_s: float


@dataclass(frozen=True)
class Capture:
    """Take one sample with the rig's instrument, stored at once as kind ``kind``.

    ``commanded`` holds the commanded values (``cmd_x_mm``...) and ``conditions`` the test conditions
    (``velocity_pct``, ``load_kg``...); both are stored with the measured values. The runner sends back the stored
    values (a dict, unit in every key).
    """

    pose: str
    cycle: int
    kind: str = "pose"
    commanded: Mapping[str, float] = _field(default_factory=dict)
    conditions: Mapping[str, float] = _field(default_factory=dict)


@dataclass(frozen=True)
class Prompt:
    """Ask the operator for one reading (``field`` in ``unit``, within bounds) or, with ``field=None``, to confirm.

    A reading is stored at once as a sample of kind ``kind``; the runner sends back the value (or None).
    """

    text: str
    field: str | None = None
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    pose: str = ""
    cycle: int = 0
    kind: str = "manual"
    commanded: Mapping[str, float] = _field(default_factory=dict)
    conditions: Mapping[str, float] = _field(default_factory=dict)


@dataclass(frozen=True)
class Checkpoint:
    """A safe point between visits: the only place a run pauses, stops, or resumes from."""

    label: str = ""


Step = Move | ActuatorMove | Settle | Capture | Prompt | Checkpoint
#: A protocol's step generator: yields steps, receives each step's result.
Plan = Generator[Step, Any, None]

_AXES_PKM5 = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "cmd_a_deg", "cmd_b_deg")


def commanded_values(target: tuple[float, ...]) -> dict[str, float]:
    """The tidy-table commanded columns of a target: alpha -> ``cmd_a_deg``, beta -> ``cmd_b_deg``."""
    return {name: float(value) for name, value in zip(_AXES_PKM5, target)}


def payload_removal(load_kg: float) -> Prompt:
    """The confirmation that the ``load_kg`` payload is off the end effector."""
    return Prompt(f"Remove the {load_kg:g} kg payload from the end effector, then confirm", conditions={"load_kg": 0.0})


def confirms_payload(step: object) -> bool:
    """Whether ``step`` is a payload confirmation: a prompt without a reading whose conditions state ``load_kg``."""
    return isinstance(step, Prompt) and step.field is None and "load_kg" in step.conditions


class Payload:
    """The payload a walk of a plan has asked for, so that a protocol asks only when it changes. A plan is walked
    more than once (counted, pre-flighted, run): a protocol makes one at the start of its steps. What is actually
    on the robot is the runner's business (:class:`MountedPayload`)."""

    def __init__(self) -> None:
        self.mounted_kg = 0.0  # a plan starts without a payload

    def mount(self, load_kg: float) -> Plan:
        """Ask the operator to mount ``load_kg`` (to take the payload off, for 0) when it differs from the last."""
        if load_kg != self.mounted_kg:
            yield (
                payload_removal(self.mounted_kg)
                if load_kg == 0
                else Prompt(
                    f"Mount a payload of {load_kg:g} kg on the end effector, then confirm",
                    conditions={"load_kg": load_kg},
                )
            )
        self.mounted_kg = load_kg


class MountedPayload:
    """What a run knows of the payload on the end effector: the load of the last payload confirmation the operator
    gave (:func:`confirms_payload`). The runner keeps one per run segment:

    - a resume skips the steps before its resume point, the payload confirmation in force there with them; it is
      asked again before the first step performed that is not a checkpoint, since the payload may have come off
      since (a stopped run's clean-up asks for that), unless that step is itself a payload confirmation (the next
      block's), and not at all when only the clean-up is left (the payload is taken as on, so that its removal is
      asked);
    - after the protocol's clean-up, a payload still on is asked to come off (:meth:`removal`), so that no run
      leaves a payload for the next one to measure under unawares.
    """

    def __init__(self) -> None:
        self.load_kg = 0.0
        self._skipped: Prompt | None = None

    def skipped(self, step: object) -> None:
        """A step before the resume point, not performed."""
        if confirms_payload(step):
            self._skipped = step  # type: ignore[assignment]

    def to_confirm_before(self, step: object, *, clean_up: bool) -> Prompt | None:
        """The skipped payload confirmation to ask again before performing ``step`` (None: none; see above)."""
        if self._skipped is None or isinstance(step, Checkpoint):
            return None
        prompt, self._skipped = self._skipped, None
        if clean_up:
            self.performed(prompt)
        return None if clean_up or confirms_payload(step) else prompt

    def performed(self, step: object) -> None:
        """A step performed (a confirmation: the operator confirmed it)."""
        if confirms_payload(step):
            self.load_kg = float(step.conditions["load_kg"])  # type: ignore[attr-defined]

    def removal(self) -> Prompt | None:
        """The confirmation that the payload still on is off (None: none is on)."""
        return payload_removal(self.load_kg) if self.load_kg else None


def visit(
    label: str,
    target: tuple[float, ...],
    cycle: int,
    *,
    velocity_pct: float,
    settle_s: float,
    conditions: Mapping[str, float] | None = None,
) -> Plan:
    """Stub: move to ``target``, settle, capture; returns the captured values."""
    yield Move(target, velocity_pct, label)
    if settle_s > 0:
        yield Settle(settle_s)
    values = yield Capture(
        label,
        cycle,
        commanded=commanded_values(target),
        conditions={"velocity_pct": velocity_pct, **(conditions or {})},
    )
    return values
