"""Driver for the delta4 (4-RSS) controller: the ATmega128 ASCII protocol, or ``bench sim delta4``.

Servo targets go through one explicit :class:`bench.robots.delta4_wire.ServoMapping` (``legacy_vb`` by default,
``calibrated`` as an option; the documents disagree) after the pre-flight: a point is converted by
:mod:`motion.delta4` (reachability, knee and servo limits), and every angle is checked against the mapping's
window, all before a byte is sent. ``z`` ("all servos in place") is awaited with a deadline but not required unless
asked; sensor reports are assembled into :class:`SensorFrame` objects (horizontal screen first). With firmware that
has this project's pot readback (``firmware/delta4``, ``bench sim delta4``), :meth:`Delta4Controller.read_pots` gives
the servo angles the pot ADCs measure; the documented original firmware sends them nowhere (§7.3.4).
:meth:`Delta4Controller.probe_fine_references` asks such firmware for fine references (0.01 deg instead of a byte's
0.745 deg): only a controller that answers the capability query ``C`` is ever sent one, else the bytes stay.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.errors import ConfigError, LinkError, LinkTimeout, UnreachableTarget
from bench.robot_kinds import robot_kind
from bench.robots import delta4_wire as wire
from bench.robots.link import Deadline, WireProtocolError

__all__ = ["DEFAULT_BAUDRATE", "HOME_MM", "home_pose", "Delta4Controller", "MoveResult", "PotReading", "SensorFrame"]

_log = logging.getLogger(__name__)

#: Not stated by the document (§5.3); 9600 8-N-1 is the recommended first guess (the robot registry's record).
DEFAULT_BAUDRATE = robot_kind("delta4").baud
#: The home pose the legacy GUI sends at start-up, (0, 0, -15) cm (003 App. F; delta4-lasergrid.md).
HOME_MM = (0.0, 0.0, -150.0)
_SENSOR_EXPECTED = "a sensor report (H<n>X, V<n>X, h or v)"
_POTS_EXPECTED = "the pot counts p<n>X q<n>X r<n>X s<n>X (firmware with pot readback, docs/protocol-delta4.md)"
_CAPABILITY_EXPECTED = "c<ddddd>X (firmware with fine references, docs/protocol-delta4.md)"


def home_pose() -> tuple[float, ...]:
    """The delta4's home pose (x, y, z mm): :data:`HOME_MM` (the robot registry's ``home``)."""
    return HOME_MM


@dataclass(frozen=True)
class SensorFrame:
    """One report of both screens: indices hit on the horizontal and vertical screens (empty: no hit).

    ``t_first_token_s`` is when the report's first token was read and ``t_monotonic_s`` when the report was closed
    (monotonic clock); tokens are read in wire order, so a report first read after a ``z`` was sent after it.
    """

    horizontal: tuple[int, ...]
    vertical: tuple[int, ...]
    raw: bytes = b""
    t_monotonic_s: float = 0.0
    t_first_token_s: float = 0.0


@dataclass(frozen=True)
class PotReading:
    """The four pot ADC counts (servos 1-4) and the servo angles theta_R, deg, they mean on the driver's pot scale
    (``servo_deg = pot_scale.to_deg(counts)``, 140/255 = 0.549 deg per count); ``t_monotonic_s`` when the last
    count was read."""

    counts: tuple[int, ...]
    servo_deg: tuple[float, ...]
    t_monotonic_s: float = 0.0


@dataclass(frozen=True)
class MoveResult:
    servo_deg: tuple[float, ...]
    command_bytes: tuple[int, ...]  # the byte references sent (empty when fine references were)
    settled: bool  # True if ``z`` arrived before the deadline
    measured: PotReading | None = None  # the pots read after the move (``read_back=True``)
    fine_values: tuple[int, ...] = ()  # the fine references sent, 0.01 deg (empty when bytes were)


@dataclass
class _FrameBuilder:
    horizontal: list[int] = field(default_factory=list)
    vertical: list[int] = field(default_factory=list)
    raw: bytearray = field(default_factory=bytearray)
    in_vertical: bool = False
    closed_vertical: bool = False
    t_first_token_s: float = 0.0


class Delta4Controller:
    """One delta4 controller on an open serial port.

    Parameters
    ----------
    port : serial.SerialBase
        Open port from ``serial.serial_for_url`` (9600 8-N-1 by default; the document does not state it).
    mapping : ServoMapping
        Servo angle <-> byte mapping; must match the firmware (or ``bench sim delta4 --mapping``).
    geometry : motion.delta4.Geometry or motion.delta4.calibration.CalibratedGeometry, optional
        Kinematics for :meth:`move_to` (default ``motion.delta4.NOMINAL``); a kinematic calibration in force puts
        its calibrated geometry here (``DeltaMover.use_geometry``), whose legs the IK then solves.
    settle_timeout_s : float
        How long to wait for ``z`` after a move, s (§5.7 item 7: default 2 s).
    frame_gap_s : float
        Silence that closes a sensor report whose last screen had hits, s.
    pot_scale : CalibratedMapping
        Pot ADC count <-> angle (default :data:`bench.robots.delta4_wire.POT_SCALE`, §5.8 b).
    heartbeat_s : float, optional
        While waiting for ``z``, send a pot query ``A`` every ``heartbeat_s`` (one outstanding at a time), for a
        firmware built with a link watchdog shorter than its moves (``DELTA4_WATCHDOG_MS``). Default None: the
        shipped watchdog (1 s) outlasts the longest move (0.66 s), and the original firmware does not know ``A``.
    """

    def __init__(
        self,
        port: Any,
        *,
        mapping: wire.ServoMapping | None = None,
        geometry: Any = None,
        settle_timeout_s: float = 2.0,
        frame_gap_s: float = 0.03,
        pot_scale: wire.CalibratedMapping | None = None,
        heartbeat_s: float | None = None,
    ) -> None:
        for name, value in (
            ("settle_timeout_s", settle_timeout_s),
            ("frame_gap_s", frame_gap_s),
            ("heartbeat_s", 1.0 if heartbeat_s is None else heartbeat_s),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= 600:
                raise ConfigError(f"Delta4Controller: {name} = {value!r}, expected a number in (0, 600] s")
        self.pot_scale = pot_scale or wire.POT_SCALE
        self.heartbeat_s = None if heartbeat_s is None else float(heartbeat_s)
        self._pot_counts: dict[str, int] = {}
        self._pots: list[PotReading] = []
        #: the latest pot reading received (a :meth:`read_pots` answer or a heartbeat's), or None
        self.last_pots: PotReading | None = None
        self.link = wire.Delta4Link(port)
        self.mapping = mapping or wire.LegacyVbMapping()
        self.geometry = geometry
        self.settle_timeout_s = float(settle_timeout_s)
        self.frame_gap_s = float(frame_gap_s)
        self.started = False
        self._settled = False
        self._frames: list[SensorFrame] = []
        self._builder = _FrameBuilder()
        #: the fine references in use on this connection (:meth:`probe_fine_references`), else None: bytes
        self.fine: wire.FineReference | None = None
        self._fine_state: dict[str, Any] = {"in_use": False, "reason": "not probed: byte references"}
        self._capability: list[int] = []

    def settings(self) -> dict[str, Any]:
        return {
            "driver": type(self).__name__,
            "port": self.link.port_name,
            "baudrate": getattr(self.link.port, "baudrate", None),
            "mapping": self.mapping.settings(),
            "settle_timeout_s": self.settle_timeout_s,
            "frame_gap_s": self.frame_gap_s,
            "pot_scale": self.pot_scale.settings(),
            "heartbeat_s": self.heartbeat_s,
            "fine_reference": dict(self._fine_state),
        }

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v!r}" for k, v in self.settings().items() if k != "driver")
        return f"{type(self).__name__}({shown})"

    # -- commands ----------------------------------------------------------------------------------------------
    def start(self, *, verify_timeout_s: float = 1.0) -> SensorFrame:
        """Send ``E`` and wait for the first sensor report, which proves a delta4 controller is there."""
        self.link.discard_input()
        self.link.write(b"E", command="E (start)")
        self.started = True
        return self.read_sensor_frame(verify_timeout_s, command="E (start)")

    def stop(self) -> None:
        """Send ``G``: the controller stops mechanical control and sensor reporting."""
        self.link.write(b"G", command="G (stop)")
        self.started = False

    def probe_fine_references(self, timeout_s: float = 0.3) -> wire.FineReference | None:
        """Ask the controller (once per connection: cached) whether it takes fine references: send ``C`` and wait
        ``timeout_s`` for ``c<ddddd>X``, its positioning step. Answered: every later move sends ``F<n><ddddd>X``
        (0.01 deg). Silent (the original firmware): bytes stay, a warning says so, and the run settings
        (``fine_reference``) record why."""
        if self._fine_state.get("probed"):
            return self.fine
        self._drain()
        self._capability.clear()
        self.link.write(wire.CAPABILITY_QUERY, command="C (capabilities)")
        deadline = Deadline(timeout_s)
        try:
            while not self._capability:
                self._consume(deadline, "C (capabilities)", _CAPABILITY_EXPECTED)
        except LinkTimeout:
            step = wire.degrees_per_count(self.mapping)
            reason = (
                f"no answer to C within {timeout_s:g} s: byte references ({self.mapping.name}, {step:.3f} deg a step)"
            )
            _log.warning("%s: %s", self.link.port_name, reason)
            self._fine_state = {"in_use": False, "probed": True, "reason": reason}
            return None
        self.fine = wire.FineReference(controller_step_deg=self._capability.pop(0) * 1e-5)
        self._fine_state = {"in_use": True, "probed": True, **self.fine.settings()}
        return self.fine

    def move_servos(
        self, servo_deg: Any, *, wait: bool = True, require_settled: bool = False, read_back: bool = False
    ) -> MoveResult:
        """Send the four servo references ``P..X Q..X R..X S..X`` (theta_R in degrees) after the range check, or
        ``F1..X F2..X F3..X F4..X`` where the controller proved it takes fine references (checked against both
        windows: the same angles pass either way).

        With ``wait``, read until ``z`` or ``settle_timeout_s``; ``require_settled`` turns a missing ``z`` into
        LinkTimeout. ``read_back`` then reads the pots (:meth:`read_pots`, firmware with readback only) into
        ``MoveResult.measured``: where the servos are, not where they were sent. Sensor frames read meanwhile are
        kept for :meth:`read_sensor_frame`.
        """
        angles = self.mapping.check(servo_deg)
        if self.fine is not None:
            fine = self.fine.to_values(self.fine.check(angles))
            values = np.zeros(0, dtype=int)
            message = b"".join(wire.format_fine_command(i, int(v)) for i, v in enumerate(fine))
        else:
            fine = np.zeros(0, dtype=int)
            values = self.mapping.to_bytes(angles)
            message = b"".join(wire.format_servo_command(i, int(v)) for i, v in enumerate(values))
        self._drain()  # a 'z' already on the wire belongs to an earlier move ('z' carries no move identity)
        self._settled = False
        self.link.write(message, command=message.decode("ascii"))
        settled = self.wait_settled(command=message.decode("ascii"), required=require_settled) if wait else False
        measured = self.read_pots() if read_back else None
        return MoveResult(
            tuple(float(a) for a in angles),
            tuple(int(v) for v in values),
            settled,
            measured,
            tuple(int(v) for v in fine),
        )

    def move_to(self, point_mm: Any, **kwargs: Any) -> MoveResult:
        """Move the end effector to ``point_mm`` = (x, y, z) after the :mod:`motion.delta4` pre-flight."""
        return self.move_servos(self.servo_angles_for(point_mm), **kwargs)

    def servo_angles_for(self, point_mm: Any) -> np.ndarray:
        """Servo angles (4,), deg, of ``point_mm``; UnreachableTarget names the point and the reason."""
        from motion import delta4
        from motion.errors import MotionInputError

        geometry = self.geometry or delta4.NOMINAL
        try:
            result = delta4.inverse_kinematics(np.asarray(point_mm, dtype=float).reshape(1, 3), geometry)
        except (MotionInputError, ValueError) as exc:
            raise UnreachableTarget(f"point_mm = {point_mm!r}: {exc}") from exc
        if not result.reachable[0]:
            raise UnreachableTarget(
                f"point_mm = {tuple(float(v) for v in np.ravel(point_mm))}: unreachable ({result.reason[0]})"
            )
        angles = self.mapping.check(result.servo_deg[0])
        return angles if self.fine is None else self.fine.check(angles)

    def wait_settled(
        self, *, timeout_s: float | None = None, command: str = "servo move", required: bool = False
    ) -> bool:
        """Wait for ``z`` (acknowledged with ``z``); False on timeout unless ``required`` (then LinkTimeout)."""
        deadline = Deadline(self.settle_timeout_s if timeout_s is None else timeout_s)
        beat_due_s, answered = time.monotonic(), True
        while not self._settled:
            wait = deadline
            if self.heartbeat_s is not None:
                now_s = time.monotonic()
                answered = answered or bool(self._pots)
                self._pots.clear()
                # A beat goes out once the last one was answered, or one interval late (its answer lost): never a
                # queue of queries that the controller answers slower than they come.
                if now_s >= beat_due_s and (answered or now_s >= beat_due_s + self.heartbeat_s):
                    self.link.write(wire.POT_QUERY, command="A (heartbeat)")
                    beat_due_s, answered = now_s + self.heartbeat_s, False
                wait = Deadline(max(0.0, min(deadline.remaining_s(), beat_due_s - time.monotonic())))
            try:
                self._consume(wait, command, "'z' (all servos in place)")
            except LinkTimeout:
                if wait is not deadline and not deadline.expired():
                    continue
                if required:
                    raise
                _log.warning("%s: no 'z' within %.2f s after %s", self.link.port_name, deadline.timeout_s, command)
                return False
        return True

    def read_sensor_frame(self, timeout_s: float = 0.5, *, command: str = "sensor report") -> SensorFrame:
        """The next complete sensor report (horizontal then vertical screen)."""
        deadline = Deadline(timeout_s)
        while not self._frames:
            self._consume(deadline, command, _SENSOR_EXPECTED)
        return self._frames.pop(0)

    def read_pots(self, timeout_s: float = 0.5) -> PotReading:
        """Send the pot query ``A`` and return the answer: where the servos are, as their pot ADCs measure it.

        Works started or stopped. Only firmware with this project's readback answers (``firmware/delta4``,
        ``bench sim delta4``); the documented original sends its ADC readings nowhere (§7.3.4), so a silent
        controller gives LinkTimeout naming the query. Sensor reports read meanwhile are kept.
        """
        self._drain()  # an answer already on the wire (a heartbeat's) is not this one
        self._pots.clear()
        self.link.write(wire.POT_QUERY, command="A (read pots)")
        deadline = Deadline(timeout_s)
        while not self._pots:
            self._consume(deadline, "A (read pots)", _POTS_EXPECTED)
        return self._pots.pop(0)

    # -- token handling ----------------------------------------------------------------------------------------
    def _drain(self) -> None:
        """Handle every token already received, without waiting."""
        while True:
            try:
                self._consume(Deadline(0.0), "drain", "nothing")
            except LinkTimeout:
                return

    def _consume(self, deadline: Deadline, command: str, expected: str) -> None:
        """Read and handle one token; a report whose last screen had hits is closed after ``frame_gap_s``."""
        builder = self._builder
        wait_s = deadline.remaining_s()
        if builder.in_vertical and not builder.closed_vertical:
            wait_s = min(wait_s, self.frame_gap_s)
        try:
            frame = self.link.read_frame(wait_s, command=command, expected=expected)
        except LinkTimeout:
            if builder.in_vertical:
                self._close_frame()
                return
            raise
        try:
            token = wire.parse_token(frame)
        except WireProtocolError as exc:
            _log.warning("%s: dropped %r while waiting for %s: %s", self.link.port_name, frame, expected, exc)
            return
        self._handle(token, frame)

    def _handle(self, token: wire.Token, frame: bytes) -> None:
        builder = self._builder
        if token.kind == "z":
            self._settled = True
            self.link.write(b"z", command="z (ack)")
            return
        if token.kind in "pqrs":
            self._pot_token(token)
            return
        if token.kind == "c":
            self._capability.append(int(token.value))  # type: ignore[arg-type]
            return
        horizontal_kind = token.kind in ("H", "h") or (token.kind == "N" and not builder.in_vertical)
        if horizontal_kind and builder.in_vertical:
            self._close_frame()
            builder = self._builder
        if not builder.raw:
            builder.t_first_token_s = time.monotonic()
        builder.raw += frame
        if token.kind in ("H", "N") and not builder.in_vertical:
            builder.horizontal.append(int(token.value))  # type: ignore[arg-type]
        elif token.kind in ("V", "N"):
            builder.in_vertical = True
            builder.vertical.append(int(token.value))  # type: ignore[arg-type]
        elif token.kind == "v":
            builder.in_vertical = True
            builder.closed_vertical = True
            self._close_frame()
        # 'h' only marks the horizontal screen as empty

    def _pot_token(self, token: wire.Token) -> None:
        """Collect the pot answer ``p q r s`` (in that order; a broken answer is dropped with a warning)."""
        if token.kind == "p":
            self._pot_counts = {}
        expected = chr(wire.POT_LETTERS[len(self._pot_counts)]) if len(self._pot_counts) < 4 else "p"
        if token.kind != expected:
            _log.warning(
                "%s: dropped pot count %s%03d: expected %s", self.link.port_name, token.kind, int(token.value), expected
            )  # type: ignore[arg-type]
            self._pot_counts = {}
            return
        self._pot_counts[token.kind] = int(token.value)  # type: ignore[arg-type]
        if len(self._pot_counts) == 4:
            counts = tuple(self._pot_counts[chr(letter)] for letter in wire.POT_LETTERS)
            angles = self.pot_scale.to_deg(np.array(counts, dtype=float))
            reading = PotReading(counts, tuple(float(a) for a in angles), time.monotonic())
            self._pots.append(reading)
            self.last_pots = reading
            self._pot_counts = {}

    def _close_frame(self) -> None:
        b = self._builder
        self._frames.append(
            SensorFrame(tuple(b.horizontal), tuple(b.vertical), bytes(b.raw), time.monotonic(), b.t_first_token_s)
        )
        self._builder = _FrameBuilder()

    # -- lifecycle ---------------------------------------------------------------------------------------------
    def shutdown(self) -> None:
        """Safe state: send ``G`` (stop mechanical control) if possible, then close the port."""
        if not getattr(self.link.port, "is_open", True):  # shut down already (a rig closes what it opened)
            return
        try:
            self.stop()
        except LinkError as exc:
            _log.warning("%s: could not send G: %s", self.link.port_name, exc)
        self.link.close()

    def __enter__(self) -> Delta4Controller:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.shutdown()
