"""The delta4 (ATmega128) wire protocol: servo-byte mappings, command encoding, report tokens and their framing.

Reference: ``shared/reference/delta4-lasergrid.md`` §5 and ``docs/protocol-delta4.md``. PC -> MCU: ``E`` (start),
``G`` (stop), ``P``/``Q``/``R``/``S`` + three digits + ``X`` (servo 1-4 reference, 0-255), ``z`` (ack). MCU -> PC:
``z`` (all servos in place), sensor hits ``H<digits>X`` / ``V<digits>X`` (horizontal / vertical screen), ``h`` / ``v``
(no hit on that screen) and, from older firmware, untagged ``<digits>X``. The documents disagree on the byte <->
angle mapping, so both are explicit :class:`ServoMapping` objects (§5.8). Parsers raise only
:class:`bench.robots.link.WireProtocolError`.

This project's extension (``docs/protocol-delta4.md``, "Pot readback"): the query ``A``, which no documented host
sends, is answered ``p<ddd>X q<ddd>X r<ddd>X s<ddd>X``, the four TLC548 pot ADC counts of servos 1-4; counts map to
angles on :data:`POT_SCALE` (§5.4, §5.8 b: 0-255 over the calibrated stops).

Its second extension ("Fine servo references"): the capability query ``C`` is answered ``c<ddddd>X``, the angle
step the controller positions a servo on (1e-5 deg; the shipped firmware: one 62.5 ns PWM tick, 0.01125 deg), and
then ``F<n><ddddd>X`` sets servo n (1-4) to theta_R in hundredths of a degree (:class:`FineReference`), instead of a
byte (0.745 deg a step under ``legacy_vb``). The original firmware answers no ``C``, so it never receives an ``F``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.errors import UnreachableTarget
from bench.robots.link import FramedLink, WireProtocolError

__all__ = [
    "CAPABILITY_QUERY",
    "FINE_LETTER",
    "FineReference",
    "POT_LETTERS",
    "POT_QUERY",
    "POT_SCALE",
    "SERVO_LETTERS",
    "CalibratedMapping",
    "Delta4Link",
    "LegacyVbMapping",
    "ServoMapping",
    "Token",
    "fine_from_settings",
    "format_capability_reply",
    "format_fine_command",
    "format_pot_reply",
    "format_servo_command",
    "parse_token",
    "mapping_from_settings",
    "round_half_up",
]

SERVO_LETTERS = b"PQRS"
#: The pot query (this project's extension) and the letters of its four reply tokens, servos 1-4.
POT_QUERY = b"A"
POT_LETTERS = b"pqrs"
#: The capability query (fine references; its answer ``c<ddddd>X``) and the fine reference's letter.
CAPABILITY_QUERY = b"C"
FINE_LETTER = b"F"
_MAX_DIGITS = 3
_CAPABILITY_DIGITS = 5


def round_half_up(value: np.ndarray) -> np.ndarray:
    """Round halves up (127.5 -> 128), explicitly, as §5.7 item 4 asks; numpy's rint rounds halves to even."""
    return np.floor(np.asarray(value, dtype=float) + 0.5).astype(np.int64)


class ServoMapping:
    """Servo angle theta_R (deg) <-> command byte (0-255), with the angle window the mapping accepts."""

    name = "abstract"

    def limits_deg(self) -> np.ndarray:
        """(4, 2) accepted [low, high] servo angle per servo, deg."""
        raise NotImplementedError

    def to_bytes(self, servo_deg: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def to_deg(self, values: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def sent_deg(self, servo_deg: np.ndarray) -> np.ndarray:
        """Where the servos are sent for the angles ``servo_deg``: the angles of their bytes (as
        :meth:`FineReference.sent_deg` for fine references)."""
        return self.to_deg(self.to_bytes(servo_deg))

    def check(self, servo_deg: Any) -> np.ndarray:
        """``servo_deg`` as a (4,) array, or UnreachableTarget naming the servo, the angle and the window."""
        angles = np.asarray(servo_deg, dtype=float)
        if angles.shape != (4,) or not np.all(np.isfinite(angles)):
            raise UnreachableTarget(f"servo_deg = {servo_deg!r}, expected 4 finite angles in degrees")
        limits = self.limits_deg()
        for i, (angle, (low, high)) in enumerate(zip(angles, limits)):
            if not low <= angle <= high:
                raise UnreachableTarget(
                    f"servo {i + 1}: theta_R = {angle:.3f} deg, expected within "
                    f"[{low:g}, {high:g}] deg (mapping {self.name})"
                )
        return angles

    def settings(self) -> dict[str, Any]:
        raise NotImplementedError


@dataclass(frozen=True)
class LegacyVbMapping(ServoMapping):
    """The bytes the documented VB GUI sent: byte = round_half_up(theta_R * 255/190); 30 <= theta_R <= 160."""

    degrees_per_span: float = 190.0
    low_deg: float = 30.0
    high_deg: float = 160.0
    name = "legacy_vb"

    def limits_deg(self) -> np.ndarray:
        return np.tile([self.low_deg, self.high_deg], (4, 1))

    def to_bytes(self, servo_deg: np.ndarray) -> np.ndarray:
        return np.clip(round_half_up(np.asarray(servo_deg) * 255.0 / self.degrees_per_span), 0, 255)

    def to_deg(self, values: np.ndarray) -> np.ndarray:
        return np.asarray(values, dtype=float) * self.degrees_per_span / 255.0

    def settings(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "degrees_per_span": self.degrees_per_span,
            "limits_deg": [self.low_deg, self.high_deg],
        }


@dataclass(frozen=True)
class CalibratedMapping(ServoMapping):
    """Per-servo linear map of the calibrated stops onto 0-255 (§5.8 b).

    ``direction`` +1: count = round_half_up(255 (theta_R - low) / (high - low)); -1 (the literal reading of §5.4):
    count = round_half_up(255 (high - theta_R) / (high - low)).
    """

    stops_deg: tuple[tuple[float, float], ...] = ((30.0, 170.0),) * 4
    direction: tuple[int, ...] = (1, 1, 1, 1)
    name = "calibrated"
    _stops: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        stops = np.asarray(self.stops_deg, dtype=float)
        if stops.shape != (4, 2) or not np.all(stops[:, 1] > stops[:, 0]):
            raise ValueError(f"stops_deg = {self.stops_deg!r}, expected 4 (low, high) pairs with high > low")
        if len(self.direction) != 4 or any(d not in (1, -1) for d in self.direction):
            raise ValueError(f"direction = {self.direction!r}, expected 4 values of +1 or -1")
        object.__setattr__(self, "_stops", stops)

    def limits_deg(self) -> np.ndarray:
        return self._stops.copy()

    def to_bytes(self, servo_deg: np.ndarray) -> np.ndarray:
        low, high = self._stops[:, 0], self._stops[:, 1]
        fraction = (np.asarray(servo_deg, dtype=float) - low) / (high - low)
        fraction = np.where(np.asarray(self.direction) > 0, fraction, 1.0 - fraction)
        return np.clip(round_half_up(255.0 * fraction), 0, 255)

    def to_deg(self, values: np.ndarray) -> np.ndarray:
        low, high = self._stops[:, 0], self._stops[:, 1]
        fraction = np.asarray(values, dtype=float) / 255.0
        fraction = np.where(np.asarray(self.direction) > 0, fraction, 1.0 - fraction)
        return low + fraction * (high - low)

    def settings(self) -> dict[str, Any]:
        return {"name": self.name, "stops_deg": [list(s) for s in self.stops_deg], "direction": list(self.direction)}


MAPPINGS = {"legacy_vb": LegacyVbMapping, "calibrated": CalibratedMapping}

#: The pot ADCs' count <-> angle scale (§5.4, §5.8 b): each TLC548's references are trimmed to its pot's voltages at
#: the two calibrated stops, so count = round_half_up(255 (theta_R - 30) / 140), 140/255 = 0.549 deg per count. The
#: document's literal reading puts 255 at 30 deg (pot wiring decides): pass ``CalibratedMapping(direction=(-1,) * 4)``
#: to the driver then.
POT_SCALE = CalibratedMapping()


@dataclass(frozen=True)
class FineReference:
    """The fine servo reference (this project's extension, docs/protocol-delta4.md "Fine servo references").

    Sent: value = round_half_up(theta_R / 0.01 deg), 0-18000. The controller positions the servo on its own step
    s (``controller_step_deg``, its answer to ``C``; the shipped firmware's PWM tick, 180 deg / 16000 ticks =
    0.01125 deg: pulse_ticks = round_half_up(16000 + value x 16000 / 18000)), so the angle the servo is sent is
    round_half_up(value x 0.01 / s) x s (:meth:`sent_deg`). Accepted angles: the firmware's calibrated stops
    [30, 170] deg (it clamps there).
    """

    controller_step_deg: float = 180.0 / 16000.0
    degrees_per_unit: float = 0.01
    low_deg: float = 30.0
    high_deg: float = 170.0
    name = "fine_centidegree"

    def __post_init__(self) -> None:
        if not 0.0 < self.controller_step_deg < 1.0:
            raise ValueError(f"controller_step_deg = {self.controller_step_deg!r}, expected in (0, 1) deg")

    def check(self, servo_deg: np.ndarray) -> np.ndarray:
        """UnreachableTarget naming the servo outside [30, 170] deg, before anything is sent."""
        angles = np.asarray(servo_deg, dtype=float)
        for i, angle in enumerate(angles):
            if not self.low_deg <= angle <= self.high_deg:
                raise UnreachableTarget(
                    f"servo {i + 1}: theta_R = {angle:.3f} deg, expected within "
                    f"[{self.low_deg:g}, {self.high_deg:g}] deg (fine references)"
                )
        return angles

    def to_values(self, servo_deg: np.ndarray) -> np.ndarray:
        return np.clip(round_half_up(np.asarray(servo_deg, dtype=float) / self.degrees_per_unit), 0, 18000)

    def to_deg(self, values: np.ndarray) -> np.ndarray:
        """The angle the controller positions the servo on for the sent ``values`` (its step grid)."""
        step = self.controller_step_deg
        return round_half_up(np.asarray(values, dtype=float) * self.degrees_per_unit / step + 1e-9) * step

    def sent_deg(self, servo_deg: np.ndarray) -> np.ndarray:
        """Where the servos are sent for the angles ``servo_deg``: the value's angle on the controller's step."""
        return self.to_deg(self.to_values(servo_deg))

    def step_deg(self) -> float:
        return max(self.degrees_per_unit, self.controller_step_deg)

    def settings(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "degrees_per_unit": self.degrees_per_unit,
            "controller_step_deg": self.controller_step_deg,
            "limits_deg": [self.low_deg, self.high_deg],
        }


def fine_from_settings(settings: Any) -> FineReference:
    """The fine reference whose :meth:`FineReference.settings` are ``settings``; ``ConfigError`` names the fault."""
    from bench.errors import ConfigError

    try:
        if settings["name"] == FineReference.name:
            low, high = settings["limits_deg"]
            return FineReference(
                float(settings["controller_step_deg"]), float(settings["degrees_per_unit"]), float(low), float(high)
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(
            f"fine reference settings {settings!r}: {exc!r}, expected those of {FineReference.name}"
        ) from None
    raise ConfigError(f"fine reference settings {settings!r}, expected name {FineReference.name!r}")


def format_fine_command(servo: int, value: int) -> bytes:
    """``F107166X`` style fine reference for servo 0-3 (sent as 1-4) with theta_R in 0.01 deg (five digits)."""
    if not 0 <= servo < 4 or not 0 <= value <= 18000:
        raise ValueError(f"servo {servo}, value {value}: expected servo 0-3 and value 0-18000 (0.01 deg)")
    return FINE_LETTER + f"{servo + 1}{value:05d}X".encode("ascii")


def format_capability_reply(step_deg: float) -> bytes:
    """The answer to :data:`CAPABILITY_QUERY`: ``c01125X`` for a 0.01125 deg positioning step (1e-5 deg units)."""
    units = int(round_half_up(step_deg * 1e5))
    if not 1 <= units <= 99999:
        raise ValueError(f"step_deg = {step_deg!r}, expected in (0, 1) deg")
    return b"c%05dX" % units


def format_servo_command(servo: int, value: int) -> bytes:
    """``P081X`` style message for servo 0-3 with a 0-255 reference (always three digits)."""
    if not 0 <= servo < 4 or not 0 <= value <= 255:
        raise ValueError(f"servo {servo}, value {value}: expected servo 0-3 and value 0-255")
    return bytes([SERVO_LETTERS[servo]]) + f"{value:03d}X".encode("ascii")


def format_pot_reply(counts: Any) -> bytes:
    """The answer to :data:`POT_QUERY`: ``p076Xq081Xr000Xs255X`` for the counts (76, 81, 0, 255) of servos 1-4."""
    values = [int(c) for c in counts]
    if len(values) != 4 or not all(0 <= c <= 255 for c in values):
        raise ValueError(f"counts = {counts!r}, expected 4 values 0-255")
    return b"".join(bytes([letter]) + b"%03dX" % c for letter, c in zip(POT_LETTERS, values))


@dataclass(frozen=True)
class Token:
    """One MCU -> PC token: ``kind`` is 'z', 'h', 'v', 'H', 'V', 'N' (untagged number), a pot count 'p', 'q',
    'r', 's' (servo 1-4) or 'c' (the capability answer, 1e-5 deg); ``value`` for numbers and counts."""

    kind: str
    value: int | None = None


def parse_token(frame: bytes) -> Token:
    """Decode one framed token (see :class:`Delta4Link`)."""
    if frame in (b"z", b"h", b"v"):
        return Token(frame.decode("ascii"))
    if len(frame) < 2 or not frame.endswith(b"X"):
        raise WireProtocolError(
            f"token {frame!r}: expected z, h, v, H<digits>X, V<digits>X, <digits>X or a pot count p/q/r/s<digits>X"
        )
    kind, digits = ("N", frame[:-1]) if frame[:1].isdigit() else (chr(frame[0]), frame[1:-1])
    if kind == "c":
        if not digits.isdigit() or len(digits) != _CAPABILITY_DIGITS or int(digits) == 0:
            raise WireProtocolError(f"token {frame!r}: expected c, five digits (the step, 1e-5 deg, not 0) and X")
        return Token(kind, int(digits))
    if kind not in "HVNpqrs" or not digits.isdigit() or not 1 <= len(digits) <= _MAX_DIGITS:
        raise WireProtocolError(f"token {frame!r}: expected H, V, p, q, r, s or nothing, then 1-3 digits and X")
    value = int(digits)
    if value > 255:
        what = "pot count" if kind in "pqrs" else "sensor index"
        raise WireProtocolError(f"token {frame!r}: {what} {value}, expected 0-255")
    return Token(kind, value)


class Delta4Link(FramedLink):
    """Token framing: single letters, or a letter/digit run closed by ``X``. A run broken by any other byte is
    handed over whole (the parser refuses it) so that noise cannot swallow the next valid token."""

    def _take_frame(self) -> bytes | None:
        pending = self._pending
        if not pending:
            return None
        first = pending[0]
        if first not in b"HVpqrsc0123456789":
            del pending[:1]
            return bytes([first])
        most = _CAPABILITY_DIGITS if first == ord("c") else _MAX_DIGITS
        for end in range(1, len(pending)):
            byte = pending[end]
            if byte == ord("X"):
                frame = bytes(pending[: end + 1])
                del pending[: end + 1]
                return frame
            if not 0x30 <= byte <= 0x39 or end > most + 1:
                frame = bytes(pending[:end])
                del pending[:end]
                return frame
        return None


def mapping_from_settings(settings: Any) -> ServoMapping:
    """The mapping whose :meth:`ServoMapping.settings` are ``settings`` (as a run stores its driver's), so the
    angles a stored run sent can be computed again; ``ConfigError`` names what is wrong."""
    from bench.errors import ConfigError

    try:
        name = settings["name"]
        if name == "legacy_vb":
            low, high = settings["limits_deg"]
            return LegacyVbMapping(float(settings["degrees_per_span"]), float(low), float(high))
        if name == "calibrated":
            return CalibratedMapping(
                tuple(tuple(float(v) for v in pair) for pair in settings["stops_deg"]),
                tuple(int(d) for d in settings["direction"]),
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(
            f"servo mapping settings {settings!r}: {exc!r}, expected those of a {' or '.join(MAPPINGS)} mapping"
        ) from None
    raise ConfigError(f"servo mapping {name!r}, expected one of {', '.join(MAPPINGS)}")


def angles_from_bytes(mapping: ServoMapping, values: np.ndarray) -> np.ndarray:
    """Servo angles, deg, that the bytes ``values`` command under ``mapping`` (the simulator's reading)."""
    return mapping.to_deg(np.asarray(values, dtype=float))


def degrees_per_count(mapping: ServoMapping) -> float:
    """Angle of one byte step, deg (legacy_vb: 190/255 = 0.745; calibrated default: 140/255 = 0.549)."""
    step = mapping.to_deg(np.full(4, 1.0)) - mapping.to_deg(np.zeros(4))
    return float(np.max(np.abs(step))) if np.all(np.isfinite(step)) else math.nan
