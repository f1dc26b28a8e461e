"""Driver for the 5-DOF PKM controller (firmware ``firmware/pkm5/pkm5.c`` or ``bench sim pkm5``).

Speaks the line protocol of ``docs/protocol-pkm5.md`` over an open pyserial port. Every target is pre-flighted in
:mod:`motion.pkm5` (IK reachability and leg limits) before a byte is sent; a refused target raises
:class:`bench.errors.UnreachableTarget`. Replies carry the command's tag, so late replies to an abandoned command
are recognised and dropped; corrupted lines (bad checksum, noise) are dropped and reported if nothing valid follows.
Queries are retried a bounded number of times, also when the controller refuses one as ``SYNTAX`` or ``CHECKSUM``
(line noise corrupted the command; a refused command was not acted on); after noise on the line the next command is
preceded by a newline, which ends whatever noise the controller holds as an empty or refused line. A move is never
re-sent: if its acceptance is lost the driver asks ``POS`` and either waits for ``DONE`` (moving), accepts (already
there) or raises; a lost ``DONE`` is recovered through ``POS`` too (the heartbeat's replies while waiting, and one
last ``POS`` at the deadline): the controller idle at the target is the move done; otherwise a missing ``DONE``
sends ``STOP`` and raises.

Opened with ``fixture="actuator-bench"`` (the six actuators free-standing, 000 §8.4),
:meth:`Pkm5Controller.move_actuator` drives one axis to an absolute stroke while the others hold, checked against that actuator's stroke window only; on
the assembled robot (the default) it is refused, since one leg cannot move alone (6 legs, 5 DOF).
"""

from __future__ import annotations

import functools
import itertools
import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.errors import ConfigError, LinkError, LinkTimeout, UnreachableTarget
from bench.robot_kinds import robot_kind
from bench.robots import pkm5_kinematics as kinematics
from bench.robots import pkm5_wire as wire
from bench.robots.link import Deadline, WireProtocolError
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
#: Interval of the heartbeat (a ``POS`` line) while waiting for ``DONE``: a third of the firmware's default link
#: watchdog (150 ms, docs/protocol-pkm5.md), so that one lost line never trips it.
HEARTBEAT_S = 0.05
#: A STOP from another thread goes out again every STOP_RESEND_S until acknowledged, at most STOP_SENDS times (1 s)
STOP_RESEND_S = 0.1
STOP_SENDS = 10

#: The controller's documented baud rate (docs/protocol-pkm5.md; the robot registry's record).
DEFAULT_BAUDRATE = robot_kind("pkm5").baud
#: Bytes the firmware's receive buffer holds (RX_SIZE, firmware/pkm5/pkm5.c): :meth:`Pkm5Controller.query_many` keeps
#: no more command bytes than that in flight.
RECEIVE_BUFFER_BYTES = 256
_IDEMPOTENT = frozenset({"ID", "POS", "STOP", "ENABLE", "DISABLE", "SETPOS"})
#: Refusals line noise causes (a corrupted command is refused, not acted on): an idempotent command is sent again.
_NOISE_REFUSALS = frozenset({wire.ErrorCode.SYNTAX, wire.ErrorCode.CHECKSUM})
#: The documents' firmware speed, taken as the rated (100 %) velocity of the pkm5: 200 steps/s (000 App. B.2).
RATED_SPEED_STEPS_S = 200


class ControllerError(LinkError):
    """The controller answered ``ERR``; ``code`` is a :class:`bench.robots.pkm5_wire.ErrorCode`."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


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


def _checked_number(name: str, value: Any, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        raise ConfigError(f"Pkm5Controller: {name} = {value!r}, expected a number in [{low}, {high}]")
    return value


def _holding_line(method: Any) -> Any:
    """Run a command holding the controller's line, so that one thread at a time reads the replies."""

    @functools.wraps(method)
    def holding(self: Pkm5Controller, *args: Any, **kwargs: Any) -> Any:
        with self._line:
            return method(self, *args, **kwargs)

    return holding


class Pkm5Controller:
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
        self.fixture = fixture
        self.link = wire.LineLink(port)
        self.geometry = geometry or pkm5.DEFAULT_GEOMETRY
        self.speed_steps_s = int(_checked_number("speed_steps_s", speed_steps_s, 1, 1000))
        self.reply_timeout_s = float(_checked_number("reply_timeout_s", reply_timeout_s, 0.001, 600))
        self.retries = int(_checked_number("retries", retries, 0, 10))
        self.move_margin_s = float(_checked_number("move_margin_s", move_margin_s, 0, 600))
        self.heartbeat_s = float(_checked_number("heartbeat_s", heartbeat_s, 0.001, 60))
        self._tags = itertools.count(1)
        self._line = threading.RLock()  # held by the command reading replies; stop() from elsewhere bypasses it
        # An emergency stop latches: no MOVE is written after it until enable(). The latch and the MOVE/STOP writes
        # share one lock, so a MOVE decided just before an e-stop either reaches the wire first (and STOP ends it) or
        # is refused; it can never follow the STOP.
        self._write = threading.Lock()
        self._noisy = False  # noise seen on the line since the last command: the next one starts with a newline
        self._stop_latched = False
        self._identity: Identity | None = None
        self._version = 1  # link framing; identify() negotiates 2 (CRC-16) with a controller that offers it
        self._stops_sent: set[int] = set()  # tags of STOPs written past a waiting command (another thread's stop)
        self._stop_acknowledged = threading.Event()  # set by the waiting command when one of them is answered
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

    # -- transport ---------------------------------------------------------------------------------------------
    @_holding_line
    def _exchange(
        self, verb: str, args: tuple[int, ...] = (), *, timeout_s: float | None = None, idempotent: bool | None = None
    ) -> wire.Reply:
        """Send one command and return its ``OK`` reply, retrying idempotent commands."""
        idempotent = verb in _IDEMPOTENT if idempotent is None else idempotent
        attempts = 1 + (self.retries if idempotent else 0)
        for attempt in range(1, attempts + 1):
            tag = next(self._tags)
            self._send(wire.format_command(verb, args, tag, self._version), command=verb)
            try:
                return self._await(tag, verb, ("OK",), timeout_s or self.reply_timeout_s)
            except ControllerError as exc:
                if exc.code not in _NOISE_REFUSALS or attempt == attempts:
                    raise
                self._noisy = True  # the command arrived corrupted: end the noise with a newline, then again
                _log.warning("%s: retry %d of %s after: %s", self.link.port_name, attempt, verb, exc)
            except (LinkTimeout, WireProtocolError) as exc:
                if attempt == attempts:
                    raise
                _log.warning("%s: retry %d of %s after: %s", self.link.port_name, attempt, verb, exc)
        raise AssertionError("unreachable")

    def _send(self, line: bytes, *, command: str) -> None:
        """Write one command line; after noise on the line a newline goes first (resynchronises the controller's
        line reader: noise it holds ends as an empty or refused line, whose ``#0`` reply is dropped as stale)."""
        if self._noisy:
            line, self._noisy = b"\n" + line, False
        self.link.write(line, command=command)

    def query(self, verb: str, args: tuple[int, ...] = ()) -> wire.Reply:
        """Send an idempotent command this driver does not know (a protocol extension, e.g. a simulator's own
        verbs) and return its ``OK`` reply; MOVE and the other known verbs have their own methods."""
        _check_extension_verb("query", verb)
        return self._exchange(verb, tuple(args), idempotent=True)

    @_holding_line
    def query_many(self, verb: str, args_list: Any) -> list[wire.Reply]:
        """:meth:`query` for each argument tuple of ``args_list`` in turn, pipelined: as many commands in flight as
        the controller's receive buffer holds (:data:`RECEIVE_BUFFER_BYTES`), so a long read-out (a simulator's
        sampled trace, hundreds of replies) waits for one round trip per batch instead of one per reply. The replies
        come in order; from the first that fails (noise, a timeout) on, the commands go one at a time with
        :meth:`query`'s retries, and the replies still in flight are dropped as stale."""
        _check_extension_verb("query_many", verb)
        commands = [tuple(args) for args in args_list]
        replies: list[wire.Reply] = []
        while len(replies) < len(commands):
            batch: list[int] = []
            lines = b""
            for args in commands[len(replies) :]:
                tag = next(self._tags)  # one that does not fit is skipped: tags only count up
                line = wire.format_command(verb, args, tag, self._version)
                if batch and len(lines) + len(line) + 1 > RECEIVE_BUFFER_BYTES:  # + the newline after noise
                    break
                batch.append(tag)
                lines += line
            self._send(lines, command=verb)
            for tag in batch:
                try:
                    replies.append(self._await(tag, verb, ("OK",), self.reply_timeout_s))
                except (ControllerError, LinkTimeout) as exc:
                    if isinstance(exc, ControllerError):
                        if exc.code not in _NOISE_REFUSALS:
                            raise
                        self._noisy = True  # the command arrived corrupted: the next one starts on a clean line
                    _log.warning(
                        "%s: %s #%d failed in a pipelined batch, the rest one at a time: %s",
                        self.link.port_name,
                        verb,
                        tag,
                        exc,
                    )
                    return replies + [self._exchange(verb, args, idempotent=True) for args in commands[len(replies) :]]
        return replies

    def _await(
        self,
        tag: int,
        verb: str,
        kinds: tuple[str, ...],
        timeout_s: float,
        *,
        heartbeat: bool = False,
        done_at: tuple[int, ...] | None = None,
    ) -> wire.Reply:
        """The next reply with ``tag``; stale tags and corrupted lines are dropped until the deadline.

        With ``heartbeat`` a ``POS`` line goes out every ``heartbeat_s`` (the firmware's link watchdog stops a
        move when the host falls silent); its replies are dropped unseen, except that with ``done_at`` (a move's
        targets) a reply showing the controller idle there stands for the ``DONE`` that noise destroyed."""
        deadline = Deadline(timeout_s)
        expected = f"'{kinds[0]} #{tag} ...' from a {wire.DEVICE_NAME} controller"
        dropped: list[bytes] = []
        beats: set[int] = set()
        next_beat_s = time.monotonic() + self.heartbeat_s
        heard_since_beat = True
        while True:
            wait_s = deadline.remaining_s()
            if heartbeat:
                now_s = time.monotonic()
                # A beat goes out when the controller has said something since the last one, or that one is
                # long overdue (its reply lost): never a queue of beats that a controller answering slower than
                # they come (a 55-byte reply to a 14-byte POS) would take in until its receive buffer overflows.
                if now_s >= next_beat_s and (heard_since_beat or now_s >= next_beat_s + self.heartbeat_s):
                    beat = next(self._tags)
                    beats.add(beat)
                    try:
                        with self._write:
                            self._send(wire.format_command("POS", (), beat, self._version), command="POS")
                    except LinkError as exc:
                        # the beat is part of the wait: a device that vanishes during it fails the wait for the
                        # reply, whether the beat's write or the next read meets the dead port first
                        raise LinkError(
                            f"{self.link.port_name}: port failed while waiting for the reply to {verb!r} "
                            f"(expected {expected}): heartbeat 'POS' not sent: {exc.__cause__ or exc}"
                        ) from exc
                    next_beat_s, heard_since_beat = time.monotonic() + self.heartbeat_s, False
                due_s = next_beat_s if heard_since_beat else next_beat_s + self.heartbeat_s
                wait_s = min(wait_s, max(0.0, due_s - time.monotonic()))
            try:
                line = self.link.read_frame(wait_s, command=verb, expected=expected)
                heard_since_beat = True
            except LinkTimeout as exc:
                if heartbeat and not deadline.expired():
                    continue
                if dropped:
                    timeout = LinkTimeout(
                        f"{exc}; dropped {len(dropped)} invalid or stale lines, first "
                        f"{dropped[0]!r} (is this a {wire.DEVICE_NAME}?)"
                    )
                    timeout.dropped = dropped
                    raise timeout from None
                raise
            try:
                reply = wire.parse_reply(line, self._version)
            except WireProtocolError as exc:
                _log.warning("%s: dropped line while waiting for %s: %s", self.link.port_name, verb, exc)
                dropped.append(line)
                self._noisy = True
                continue
            if reply.tag in self._stops_sent:  # a STOP sent from another thread: its acknowledgement
                self._stop_acknowledged.set()
                if done_at is not None:  # the controller ends the move (ERR 8) before it answers STOP: that was lost
                    raise ControllerError(
                        f"{self.link.port_name}: MOVE #{tag} ended by STOP #{reply.tag} (its "
                        f"'ERR #{tag} 8 STOPPED' lost; STOP answered {' '.join(reply.fields)})",
                        wire.ErrorCode.STOPPED,
                    )
                continue
            if reply.tag in beats:
                if done_at is not None and reply.kind == "OK" and _idle_at(reply, done_at):
                    _log.warning(
                        "%s: %s #%d: DONE lost; POS shows the controller idle at the target",
                        self.link.port_name,
                        verb,
                        tag,
                    )
                    return wire.Reply("DONE", tag, tuple(str(s) for s in done_at))
                continue
            if reply.tag != tag:
                _log.info("%s: dropped stale reply %r while waiting for #%d", self.link.port_name, line, tag)
                dropped.append(line)
                continue
            if reply.kind == "ERR":
                code = reply.ints(0, 1)[0]
                if code == wire.ErrorCode.STOPPED:  # the move ended by a STOP: acknowledges a cross-thread stop()
                    self._stop_acknowledged.set()
                name = reply.fields[1] if len(reply.fields) > 1 else "?"
                raise ControllerError(
                    f"{self.link.port_name}: controller refused {verb!r} with error {code} "
                    f"{name} ({' '.join(reply.fields[2:])})".rstrip(" ()"),
                    code,
                )
            if reply.kind in kinds:
                return reply
            dropped.append(line)

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
                if exc.code not in _NOISE_REFUSALS or attempt > self.retries:
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

    @_holding_line
    def _move(self, targets: tuple[int, ...], speed_steps_s: int | None) -> tuple[int, ...]:
        speed = int(
            _checked_number("speed_steps_s", self.speed_steps_s if speed_steps_s is None else speed_steps_s, 1, 1000)
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
    @_holding_line
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


def _check_extension_verb(method: str, verb: str) -> None:
    if verb in ("MOVE", "STOP") or verb in _IDEMPOTENT:
        raise ConfigError(f"Pkm5Controller.{method}: verb = {verb!r}, expected a verb without a method of its own")


def _verifies(line: bytes, version: int) -> bool:
    try:
        wire.decode_line(line, version)
    except WireProtocolError:
        return False
    return True


def _idle_at(reply: wire.Reply, targets: tuple[int, ...]) -> bool:
    """Whether a ``POS`` reply (``POS s1 .. s6 STATE``) shows the controller idle at ``targets``."""
    fields = reply.fields
    if len(fields) != 2 + wire.AXES or fields[0] != "POS" or fields[-1] != "IDLE":
        return False
    try:
        return reply.ints(1, wire.AXES) == targets
    except WireProtocolError:
        return False


def _as_steps(steps: Any) -> tuple[int, ...]:
    array = np.asarray(steps)
    if array.shape != (wire.AXES,) or not np.issubdtype(array.dtype, np.integer):
        raise ConfigError(f"steps = {steps!r}, expected {wire.AXES} integers (absolute steps per actuator)")
    return tuple(int(s) for s in array)
