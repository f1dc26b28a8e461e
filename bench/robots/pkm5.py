"""Driver for the 5-DOF PKM controller (firmware ``firmware/pkm5/pkm5.c`` or ``bench sim pkm5``).

Speaks the line protocol of ``docs/protocol-pkm5.md`` over an open pyserial port, through the tagged exchange of
:mod:`bench.robots.pkm5_exchange` (tags, retries, noise, heartbeat). Every target is pre-flighted in
:mod:`motion.pkm5` (IK reachability and leg limits) before a byte is sent; a refused target raises
:class:`bench.errors.UnreachableTarget`. A move is never re-sent (except to a version-3 controller, which answers a
repeated MOVE without executing it again): if its acceptance is lost the driver asks ``POS`` and either waits for
``DONE`` (moving), accepts (already there) or raises; a lost ``DONE`` is recovered through ``POS`` too (the
heartbeat's replies while waiting, and one last ``POS`` at the deadline): the controller idle at the target is the
move done; otherwise a missing ``DONE`` sends ``STOP`` and raises.

Opened with ``fixture="actuator-bench"`` (the six actuators free-standing, 000 §8.4),
:meth:`Pkm5Controller.move_actuator` drives one axis to an absolute stroke while the others hold, checked against that actuator's stroke window only; on
the assembled robot (the default) it is refused, since one leg cannot move alone (6 legs, 5 DOF).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.errors import ConfigError, LinkError, LinkTimeout, UnreachableTarget
from bench.robot_kinds import robot_kind
from bench.robots import pkm5_kinematics as kinematics
from bench.robots import pkm5_wire as wire
from bench.robots.link import WireProtocolError
from bench.robots.pkm5_exchange import (
    HEARTBEAT_S,
    NOISE_REFUSALS,
    RECEIVE_BUFFER_BYTES,
    ControllerError,
    TaggedExchange,
    checked_number,
    holding_line,
)
from motion import pkm5

__all__ = [
    "DEFAULT_BAUDRATE",
    "RATED_SPEED_STEPS_S",
    "RECEIVE_BUFFER_BYTES",
    "ControllerError",
    "Identity",
    "Pkm5Controller",
    "Position",
]

_log = logging.getLogger(__name__)
#: A STOP from another thread goes out again every STOP_RESEND_S until acknowledged, at most STOP_SENDS times (1 s)
STOP_RESEND_S = 0.1
STOP_SENDS = 10

#: The controller's documented baud rate (docs/protocol-pkm5.md; the robot registry's record).
DEFAULT_BAUDRATE = robot_kind("pkm5").baud
#: The documents' firmware speed, taken as the rated (100 %) velocity of the pkm5: 200 steps/s (000 App. B.2).
RATED_SPEED_STEPS_S = 200


@dataclass(frozen=True)
class Identity:
    device: str
    protocol_version: int
    firmware_version: str


@dataclass(frozen=True)
class Position:
    """Actuator positions in absolute steps from the zero of each leg, and the controller state."""

    steps: tuple[int, ...]
    state: str  # IDLE, MOVING or DISABLED


class Pkm5Controller(TaggedExchange):
    """One PKM5 controller on an open serial port.

    Parameters
    ----------
    port : serial.SerialBase
        Open port from ``serial.serial_for_url`` (pty path, ``loop://``, ``spy://``, hardware).
    geometry : motion.pkm5.Geometry, optional
        Kinematic and calibration parameters used for the pre-flight (default ``motion.pkm5.DEFAULT_GEOMETRY``).
    speed_steps_s : int
        Speed of the leading axis, steps/s (firmware range 1-1000; the documents' sketch used 200).
    reply_timeout_s : float
        Deadline for each reply, s.
    retries : int
        Extra attempts for an idempotent command whose reply timed out or was corrupted.
    move_margin_s : float
        Slack added to a move's announced duration (x1.5) before ``DONE`` is declared late, s.
    heartbeat_s : float
        Interval of the ``POS`` heartbeat while a move runs, s (default :data:`HEARTBEAT_S`, a third of the
        firmware's default link watchdog); a firmware built with a longer watchdog, or one emulated slower than
        real time, takes a longer one. A beat more than one interval late goes out even if the last is unanswered.
    fixture : {"assembled", "actuator-bench"}
        What the controller drives: the assembled robot (pose moves only) or free-standing actuators
        (:meth:`move_actuator` only makes sense, and is only allowed, on the bench).
    """

    def __init__(
        self,
        port: Any,
        *,
        geometry: Any = None,
        speed_steps_s: int = RATED_SPEED_STEPS_S,
        reply_timeout_s: float = 1.0,
        retries: int = 2,
        move_margin_s: float = 2.0,
        fixture: str = kinematics.ASSEMBLED,
        heartbeat_s: float = HEARTBEAT_S,
    ) -> None:
        if fixture not in kinematics.FIXTURES:
            raise ConfigError(
                f"Pkm5Controller: fixture = {fixture!r}, expected one of "
                f"{', '.join(repr(f) for f in kinematics.FIXTURES)}"
            )
        super().__init__(port, reply_timeout_s=reply_timeout_s, retries=retries, heartbeat_s=heartbeat_s)
        self.fixture = fixture
        self.geometry = geometry or pkm5.DEFAULT_GEOMETRY
        self.speed_steps_s = int(checked_number("speed_steps_s", speed_steps_s, 1, 1000))
        self.move_margin_s = float(checked_number("move_margin_s", move_margin_s, 0, 600))
        self._stop_latched = False
        self._identity: Identity | None = None
        self._stops_requested = 0  # stop() calls so far: a MOVE is never re-sent across one (under _write)

    # -- description -------------------------------------------------------------------------------------------
    def settings(self) -> dict[str, Any]:
        """Plain-dict settings stored with every run."""
        return {
            "driver": type(self).__name__,
            "port": self.link.port_name,
            "baudrate": getattr(self.link.port, "baudrate", None),
            "protocol_version": self._version,
            "speed_steps_s": self.speed_steps_s,
            "reply_timeout_s": self.reply_timeout_s,
            "retries": self.retries,
            "move_margin_s": self.move_margin_s,
            "fixture": self.fixture,
            "firmware": None if self._identity is None else vars(self._identity),
        }

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v!r}" for k, v in self.settings().items() if k != "driver")
        return f"{type(self).__name__}({shown})"

    # -- commands ----------------------------------------------------------------------------------------------
    def identify(self) -> Identity:
        """Ask ``ID`` and negotiate the highest protocol both sides speak: ``PROTOCOL 2`` (CRC-16 lines) with a
        controller that offers 2, version 1 with one that offers 1 (firmware 1.x). A controller already on a
        version-2 link (an earlier host negotiated it; no line takes it back to version 1) refuses the version-1
        ``ID`` with a CRC-16 ``ERR #0 2 CHECKSUM``: the driver then asks in version 2. A device other than a
        bench-pkm5 raises LinkError."""
        offered = " or ".join(str(v) for v in wire.PROTOCOL_VERSIONS)
        for attempt in range(1, self.retries + 2):
            self._version = 1
            try:  # one try per attempt: a version-2 link answers in CRC-16, which a retry in version 1 cannot read
                fields = self._exchange("ID", idempotent=False).fields
            except ControllerError as exc:
                if exc.code not in NOISE_REFUSALS or attempt > self.retries:
                    raise
                self._noisy = True
                continue
            except LinkTimeout as exc:
                if not self._link_is_crc(exc):
                    if attempt > self.retries:
                        raise
                    continue
                self._version = 2
                fields = self._exchange("ID").fields
            if (
                len(fields) != 4
                or fields[0] != "ID"
                or fields[1] != wire.DEVICE_NAME
                or fields[2] not in [str(v) for v in wire.PROTOCOL_VERSIONS]
            ):
                raise LinkError(
                    f"{self.link.port_name}: 'ID' answered {' '.join(fields)!r}, expected "
                    f"'ID {wire.DEVICE_NAME} {offered} <firmware version>' (wrong device?)"
                )
            version = int(fields[2])
            if version == 1:
                break
            try:  # a lost OK leaves the controller's framing unknown: ask ID again (a CRC-16 refusal tells)
                self._exchange("PROTOCOL", (version,))
            except (LinkTimeout, WireProtocolError) as exc:
                if attempt > self.retries:
                    raise
                _log.warning("%s: PROTOCOL %d not confirmed (%s); identifying again", self.link.port_name, version, exc)
                continue
            self._version = version
            break
        self._identity = Identity(fields[1], version, fields[3])
        return self._identity

    def _link_is_crc(self, exc: Exception) -> bool:
        """Whether a failed version-1 exchange met a controller framing its lines in CRC-16 (a version-2 link)."""
        return any(_verifies(line, 2) for line in getattr(exc, "dropped", ()))

    def position(self) -> Position:
        reply = self._exchange("POS")
        state = reply.fields[1 + wire.AXES] if len(reply.fields) == 2 + wire.AXES else "?"
        return Position(reply.ints(1, wire.AXES), state)

    def enable(self) -> None:
        """Enable the drivers; also releases a latched emergency stop."""
        self._exchange("ENABLE")
        with self._write:
            self._stop_latched = False

    def disable(self) -> None:
        self._exchange("DISABLE")

    def set_position(self, steps: Any) -> None:
        """Declare the current actuator positions (absolute steps), e.g. after homing by hand."""
        self._exchange("SETPOS", _as_steps(steps))

    def stop(self) -> Position | None:
        """Stop all axes now; returns where they stopped.

        Safe from another thread while a command waits for its replies (an emergency stop during a move): the
        ``STOP`` line goes out at once and again every :data:`STOP_RESEND_S` until the waiting command reads its
        acknowledgement (the move then ends with the controller's ``ERR #move 8 STOPPED``), at most
        :data:`STOP_SENDS` times; None is returned, or LinkError when no STOP was acknowledged. Takes no lock a
        waiting mover holds (only the write lock, held for one write).
        """
        with self._write:
            self._stops_requested += 1
        if not self._line.acquire(blocking=False):
            self._stop_acknowledged.clear()
            for _ in range(STOP_SENDS):
                tag = next(self._tags)
                self._stops_sent.add(tag)
                with self._write:
                    self.link.write(b"\n" + wire.format_command("STOP", (), tag, self._version), command="STOP")
                if self._stop_acknowledged.wait(STOP_RESEND_S):
                    return None
                if self._line.acquire(blocking=False):  # the mover has ended: confirm the stop ourselves
                    try:
                        return Position(self._exchange("STOP").ints(1, wire.AXES), "IDLE")
                    finally:
                        self._line.release()
            raise LinkError(f"{self.link.port_name}: STOP sent {STOP_SENDS} times, none acknowledged")
        try:
            return Position(self._exchange("STOP").ints(1, wire.AXES), "IDLE")
        finally:
            self._line.release()

    def emergency_stop(self) -> Position | None:
        """:meth:`stop` that latches: every later move is refused (``LinkError``) until :meth:`enable`. Safe from
        any thread."""
        with self._write:
            self._stop_latched = True
        return self.stop()

    def move_steps(self, steps: Any, *, speed_steps_s: int | None = None) -> tuple[int, ...]:
        """Pre-flight ``steps`` (6 absolute targets), move, and wait for ``DONE``; returns the reached steps."""
        targets = _as_steps(steps)
        self._preflight_steps(targets)
        return self._move(targets, speed_steps_s)

    def move_to_pose(self, pose: Any, *, speed_steps_s: int | None = None) -> tuple[int, ...]:
        """Move to ``pose`` = (x_mm, y_mm, z_mm, alpha_deg, beta_deg) after the IK pre-flight."""
        return self._move(self.steps_for_pose(pose), speed_steps_s)

    def move_actuator(self, axis: int, stroke_mm: float, *, speed_steps_s: int | None = None) -> tuple[int, ...]:
        """Actuator bench only: move actuator ``axis`` (1-6) to ``stroke_mm`` (mm from full retraction, 0-66)
        while the other axes hold; returns the reached steps.

        Refused (``UnreachableTarget``) unless the controller was opened with ``fixture="actuator-bench"``, and for a
        stroke outside the actuator's window; nothing is sent then.
        """
        if self.fixture != kinematics.ACTUATOR_BENCH:
            raise UnreachableTarget(
                f"move_actuator(axis={axis!r}, stroke_mm={stroke_mm!r}): refused on the "
                f"{self.fixture} robot, one leg cannot move alone (6 legs, 5 DOF); expected a "
                f"controller opened with fixture='{kinematics.ACTUATOR_BENCH}'"
            )
        target = kinematics.steps_for_stroke(axis, stroke_mm, self.geometry)
        where = self.position()
        if where.state != "IDLE":
            raise LinkError(f"{self.link.port_name}: move_actuator: the controller is {where.state}, expected IDLE")
        targets = list(where.steps)
        targets[axis - 1] = target
        return self._move(tuple(targets), speed_steps_s)

    def steps_for_pose(self, pose: Any) -> tuple[int, ...]:
        """Absolute step targets of ``pose`` (x_mm, y_mm, z_mm, alpha_deg, beta_deg); UnreachableTarget if refused."""
        return kinematics.steps_for_pose(pose, self.geometry)

    def _preflight_steps(self, steps: tuple[int, ...]) -> None:
        kinematics.check_steps(steps, self.geometry)

    @holding_line
    def _move(self, targets: tuple[int, ...], speed_steps_s: int | None) -> tuple[int, ...]:
        speed = int(
            checked_number("speed_steps_s", self.speed_steps_s if speed_steps_s is None else speed_steps_s, 1, 1000)
        )
        tag = next(self._tags)
        line = wire.format_command("MOVE", (*targets, speed), tag, self._version)
        stops_before = self._stops_requested
        # Version 3 controllers answer a MOVE with the tag of the last one they accepted without executing it again,
        # so a MOVE whose OK does not come (corrupted either way) is re-sent as it was; never across a stop().
        sends = 1 + (self.retries if self._version >= 3 else 0)
        try:
            for send in range(1, sends + 1):
                with self._write:
                    if self._stop_latched:
                        raise LinkError(
                            f"{self.link.port_name}: MOVE to {targets} refused: an emergency stop is "
                            "latched; enable() the controller to move again"
                        )
                    if self._stops_requested != stops_before:
                        raise LinkError(f"{self.link.port_name}: MOVE #{tag} not re-sent: stop() was called")
                    self._send(line, command="MOVE")
                try:
                    # heartbeats while waiting: a lost OK must not leave the watchdog without a valid line
                    reply = self._await(tag, "MOVE", ("OK", "DONE"), self.reply_timeout_s, heartbeat=True)
                    break
                except (LinkTimeout, WireProtocolError) as exc:  # acceptance lost (noise)
                    if send < sends:
                        _log.warning("%s: MOVE #%d not acknowledged (%s); sent again", self.link.port_name, tag, exc)
                        self._noisy = True
                        continue
                    _log.warning(
                        "%s: MOVE #%d acceptance lost (%s); querying the controller", self.link.port_name, tag, exc
                    )
                    return self._recover_move(tag, targets, speed)
            if reply.kind == "DONE":
                return reply.ints(0, wire.AXES)
            duration_s = reply.ints(1, 1)[0] / 1000.0
            return self._await_done(tag, targets, 1.5 * duration_s + self.move_margin_s)
        except (LinkTimeout, WireProtocolError, KeyboardInterrupt):
            self._stop_quietly()
            raise

    def _await_done(self, tag: int, targets: tuple[int, ...], timeout_s: float) -> tuple[int, ...]:
        """Wait for the ``DONE`` of move ``tag``; a lost one is recovered through ``POS`` (see the module)."""
        try:
            return self._await(tag, "MOVE", ("DONE",), timeout_s, heartbeat=True, done_at=targets).ints(0, wire.AXES)
        except LinkTimeout:
            where = self.position()  # one last look: idle at the target is the move done, its DONE lost
            if where.state == "IDLE" and where.steps == targets:
                _log.warning(
                    "%s: MOVE #%d: DONE lost; POS shows the controller idle at the target", self.link.port_name, tag
                )
                return where.steps
            raise

    def _recover_move(self, tag: int, targets: tuple[int, ...], speed: int) -> tuple[int, ...]:
        """After a lost ``OK``: wait for ``DONE`` if the controller is moving, accept if it is already there."""
        where = self.position()
        if where.state == "MOVING":
            remaining_s = max(abs(t - s) for t, s in zip(targets, where.steps)) / speed
            return self._await_done(tag, targets, 1.5 * remaining_s + self.move_margin_s)
        if where.steps == targets:
            return where.steps
        raise LinkError(
            f"{self.link.port_name}: MOVE #{tag} not confirmed: the controller is {where.state} at "
            f"{where.steps}, expected a move to {targets}"
        )

    # -- lifecycle ---------------------------------------------------------------------------------------------
    @holding_line
    def _stop_quietly(self) -> None:
        try:
            tag = next(self._tags)
            self._send(wire.format_command("STOP", (), tag, self._version), command="STOP")
            self._await(tag, "STOP", ("OK",), self.reply_timeout_s)
        except (LinkError, OSError) as exc:
            _log.warning("%s: STOP not confirmed: %s", self.link.port_name, exc)

    def shutdown(self) -> None:
        """Safe state: stop all motion (best effort, bounded wait) and close the port. Drivers stay enabled so
        the actuators keep their holding torque."""
        if not getattr(self.link.port, "is_open", True):  # shut down already (a rig closes what it opened)
            return
        self._stop_quietly()
        self.link.close()

    def __enter__(self) -> Pkm5Controller:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.shutdown()


def _verifies(line: bytes, version: int) -> bool:
    try:
        wire.decode_line(line, version)
    except WireProtocolError:
        return False
    return True


def _as_steps(steps: Any) -> tuple[int, ...]:
    array = np.asarray(steps)
    if array.shape != (wire.AXES,) or not np.issubdtype(array.dtype, np.integer):
        raise ConfigError(f"steps = {steps!r}, expected {wire.AXES} integers (absolute steps per actuator)")
    return tuple(int(s) for s in array)
