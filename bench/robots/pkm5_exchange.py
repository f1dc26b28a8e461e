"""The tagged line exchange with a pkm5 controller (:class:`bench.robots.pkm5.Pkm5Controller` is built on it).

One command line out, its reply back, matched by the command's tag: stale tags (late replies to an abandoned
command) and corrupted lines are dropped, and reported if nothing valid follows before the deadline. Idempotent
commands are retried a bounded number of times, also when the controller refuses one as ``SYNTAX`` or ``CHECKSUM``
(line noise corrupted the command; a refused command was not acted on); after noise on the line the next command is
preceded by a newline, which ends whatever noise the controller holds as an empty or refused line. While a move
runs, a ``POS`` heartbeat keeps the firmware's link watchdog fed, and a ``STOP`` another thread wrote past the
waiting command is recognised by its tag (docs/protocol-pkm5.md).
"""

from __future__ import annotations

import functools
import itertools
import logging
import threading
import time
from typing import Any

from bench.errors import ConfigError, LinkError, LinkTimeout
from bench.robots import pkm5_wire as wire
from bench.robots.link import Deadline, WireProtocolError

__all__ = [
    "HEARTBEAT_S",
    "IDEMPOTENT",
    "NOISE_REFUSALS",
    "RECEIVE_BUFFER_BYTES",
    "ControllerError",
    "TaggedExchange",
    "checked_number",
    "holding_line",
]

_log = logging.getLogger("bench.robots.pkm5")  # the driver's log: one logger for the controller's whole exchange

#: Interval of the heartbeat (a ``POS`` line) while waiting for ``DONE``: a third of the firmware's default link
#: watchdog (150 ms, docs/protocol-pkm5.md), so that one lost line never trips it.
HEARTBEAT_S = 0.05
#: Bytes the firmware's receive buffer holds (RX_SIZE, firmware/pkm5/pkm5.c): :meth:`Pkm5Controller.query_many` keeps
#: no more command bytes than that in flight.
RECEIVE_BUFFER_BYTES = 256
#: Commands whose repetition changes nothing: retried after a lost or corrupted reply.
IDEMPOTENT = frozenset({"ID", "POS", "STOP", "ENABLE", "DISABLE", "SETPOS"})
#: Refusals line noise causes (a corrupted command is refused, not acted on): an idempotent command is sent again.
NOISE_REFUSALS = frozenset({wire.ErrorCode.SYNTAX, wire.ErrorCode.CHECKSUM})


class ControllerError(LinkError):
    """The controller answered ``ERR``; ``code`` is a :class:`bench.robots.pkm5_wire.ErrorCode`."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


def checked_number(name: str, value: Any, low: float, high: float) -> float:
    """``value``, or ``ConfigError`` unless it is a number in [``low``, ``high``]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        raise ConfigError(f"Pkm5Controller: {name} = {value!r}, expected a number in [{low}, {high}]")
    return value


def holding_line(method: Any) -> Any:
    """Run a command holding the controller's line, so that one thread at a time reads the replies."""

    @functools.wraps(method)
    def holding(self: TaggedExchange, *args: Any, **kwargs: Any) -> Any:
        with self._line:
            return method(self, *args, **kwargs)

    return holding


class TaggedExchange:
    """The command/reply exchange with one controller on an open serial port (see the module); the parameters are
    :class:`bench.robots.pkm5.Pkm5Controller`'s."""

    def __init__(self, port: Any, *, reply_timeout_s: float, retries: int, heartbeat_s: float) -> None:
        self.link = wire.LineLink(port)
        self.reply_timeout_s = float(checked_number("reply_timeout_s", reply_timeout_s, 0.001, 600))
        self.retries = int(checked_number("retries", retries, 0, 10))
        self.heartbeat_s = float(checked_number("heartbeat_s", heartbeat_s, 0.001, 60))
        self._tags = itertools.count(1)
        self._line = threading.RLock()  # held by the command reading replies; stop() from elsewhere bypasses it
        # An emergency stop latches: no MOVE is written after it until enable(). The latch and the MOVE/STOP writes
        # share one lock, so a MOVE decided just before an e-stop either reaches the wire first (and STOP ends it) or
        # is refused; it can never follow the STOP.
        self._write = threading.Lock()
        self._noisy = False  # noise seen on the line since the last command: the next one starts with a newline
        self._version = 1  # link framing; identify() negotiates 2 (CRC-16) with a controller that offers it
        self._stops_sent: set[int] = set()  # tags of STOPs written past a waiting command (another thread's stop)
        self._stop_acknowledged = threading.Event()  # set by the waiting command when one of them is answered

    @holding_line
    def _exchange(
        self, verb: str, args: tuple[int, ...] = (), *, timeout_s: float | None = None, idempotent: bool | None = None
    ) -> wire.Reply:
        """Send one command and return its ``OK`` reply, retrying idempotent commands."""
        idempotent = verb in IDEMPOTENT if idempotent is None else idempotent
        attempts = 1 + (self.retries if idempotent else 0)
        for attempt in range(1, attempts + 1):
            tag = next(self._tags)
            self._send(wire.format_command(verb, args, tag, self._version), command=verb)
            try:
                return self._await(tag, verb, ("OK",), timeout_s or self.reply_timeout_s)
            except ControllerError as exc:
                if exc.code not in NOISE_REFUSALS or attempt == attempts:
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
        check_extension_verb("query", verb)
        return self._exchange(verb, tuple(args), idempotent=True)

    @holding_line
    def query_many(self, verb: str, args_list: Any) -> list[wire.Reply]:
        """:meth:`query` for each argument tuple of ``args_list`` in turn, pipelined: as many commands in flight as
        the controller's receive buffer holds (:data:`RECEIVE_BUFFER_BYTES`), so a long read-out (a simulator's
        sampled trace, hundreds of replies) waits for one round trip per batch instead of one per reply. The replies
        come in order; from the first that fails (noise, a timeout) on, the commands go one at a time with
        :meth:`query`'s retries, and the replies still in flight are dropped as stale."""
        check_extension_verb("query_many", verb)
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
                        if exc.code not in NOISE_REFUSALS:
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
                if done_at is not None and reply.kind == "OK" and idle_at(reply, done_at):
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


def check_extension_verb(method: str, verb: str) -> None:
    if verb in ("MOVE", "STOP") or verb in IDEMPOTENT:
        raise ConfigError(f"Pkm5Controller.{method}: verb = {verb!r}, expected a verb without a method of its own")


def idle_at(reply: wire.Reply, targets: tuple[int, ...]) -> bool:
    """Whether a ``POS`` reply (``POS s1 .. s6 STATE``) shows the controller idle at ``targets``."""
    fields = reply.fields
    if len(fields) != 2 + wire.AXES or fields[0] != "POS" or fields[-1] != "IDLE":
        return False
    try:
        return reply.ints(1, wire.AXES) == targets
    except WireProtocolError:
        return False
