"""Byte-stream framing on a serial port with monotonic deadlines: the one transport of every robot driver and every
line-sending sensor (issue 35: one serial line transport).

A device module receives an open pyserial port (built with ``serial.serial_for_url``, so a pty path, ``loop://`` and
``spy://`` all work) and wraps it in one :class:`FramedLink` subclass that knows what a frame is: the robots' framed
replies (:mod:`bench.robots.pkm5_wire`, :mod:`bench.robots.delta4_wire`), a sensor's text lines
(:class:`bench.sensors.serial_lines.LineReader`). Every wait is pySerial's own read timeout, sliced so that a read
never blocks past its :class:`Deadline` on ``time.monotonic`` (it survives wall-clock jumps) by more than
:data:`_POLL_S`; on expiry :class:`bench.errors.LinkTimeout` names the port, the command, the time waited, what was
expected and the bytes received so far. A failing port (``serial.SerialException``, ``OSError``: the device vanished)
becomes a :class:`bench.errors.LinkError` naming the same things. It sits below the robots and the sensors, which
may not import each other.
"""

from __future__ import annotations

import errno
import logging
import time
from typing import Any

import serial

try:  # pyserial's POSIX flush() is termios.tcdrain, whose errors are termios.error, not OSError
    from termios import error as _TermiosError
except ImportError:  # no termios (Windows): nothing extra to catch
    _TermiosError = OSError

from bench.errors import LinkError, LinkTimeout

#: Flush attempts when a signal interrupts tcdrain (EINTR: the bytes are still queued, draining simply resumes).
_FLUSH_ATTEMPTS = 3


__all__ = ["Deadline", "FramedLink", "open_port"]

_log = logging.getLogger(__name__)

#: Longest single blocking read; a read never blocks past its deadline by more than this.
_POLL_S = 0.05


class Deadline:
    """A point in monotonic time ``timeout_s`` seconds after creation."""

    def __init__(self, timeout_s: float) -> None:
        if not timeout_s >= 0:
            raise ValueError(f"timeout_s = {timeout_s!r}, expected a number >= 0")
        self.timeout_s = float(timeout_s)
        self._start = time.monotonic()

    def elapsed_s(self) -> float:
        return time.monotonic() - self._start

    def remaining_s(self) -> float:
        return max(0.0, self.timeout_s - self.elapsed_s())

    def expired(self) -> bool:
        return self.remaining_s() <= 0.0


class FramedLink:
    """Splits the byte stream of an open port into frames; subclasses define a frame in :meth:`_take_frame`.

    Parameters
    ----------
    port : serial.SerialBase
        An open port, e.g. ``serial.serial_for_url("/dev/pts/3", baudrate=115200)``. Its ``timeout`` is changed to
        poll in short slices; nothing else is touched.
    max_pending : int
        Bytes kept without a complete frame before the oldest are dropped (noise protection).
    """

    def __init__(self, port: Any, *, max_pending: int = 4096) -> None:
        self.port = port
        self.max_pending = max_pending
        self._pending = bytearray()

    @property
    def port_name(self) -> str:
        return str(getattr(self.port, "port", None) or getattr(self.port, "name", "?"))

    def _take_frame(self) -> bytes | None:
        """Remove and return the first complete frame of ``self._pending``, or ``None``."""
        raise NotImplementedError

    def write(self, data: bytes, *, command: str) -> None:
        try:
            self.port.write(data)
            self._flush()
        except (serial.SerialException, OSError, _TermiosError) as exc:
            raise LinkError(f"{self.port_name}: cannot send {command!r}: {exc}") from exc
        _log.debug("%s <- %r", self.port_name, data)

    def _flush(self) -> None:
        """Wait until the bytes are sent; a signal interrupting the wait (EINTR, e.g. a profiler's timer) retries."""
        for attempt in range(1, _FLUSH_ATTEMPTS + 1):
            try:
                self.port.flush()
                return
            except _TermiosError as exc:
                if attempt == _FLUSH_ATTEMPTS or not exc.args or exc.args[0] != errno.EINTR:
                    raise

    def read_frame(self, timeout_s: float, *, command: str, expected: str) -> bytes:
        """The next frame, waiting at most ``timeout_s`` seconds (monotonic).

        Raises
        ------
        LinkTimeout
            No complete frame before the deadline; the message names the port, ``command``, the time waited,
            ``expected`` and the bytes received so far.
        LinkError
            The port failed (e.g. the device vanished).
        """
        deadline = Deadline(timeout_s)
        polled = False  # a zero timeout still takes what the port already holds
        while True:
            frame = self._take_frame()
            if frame is not None:
                _log.debug("%s -> %r", self.port_name, frame)
                return frame
            remaining = deadline.remaining_s()
            if remaining <= 0.0 and polled:
                raise LinkTimeout(
                    f"{self.port_name}: no reply to {command!r} after {deadline.elapsed_s():.3f} s, "
                    f"expected {expected}; received {len(self._pending)} bytes so far: {bytes(self._pending)!r}"
                )
            self._receive(min(remaining, _POLL_S), command=command, expected=expected)
            polled = True

    def _receive(self, wait_s: float, *, command: str, expected: str) -> None:
        try:
            if self.port.timeout != wait_s:
                self.port.timeout = wait_s
            chunk = self.port.read(max(1, self.port.in_waiting))
        except (serial.SerialException, OSError) as exc:
            raise LinkError(
                f"{self.port_name}: port failed while waiting for the reply to {command!r} (expected {expected}): {exc}"
            ) from exc
        self._pending += chunk
        overflow = len(self._pending) - self.max_pending
        if overflow > 0:
            _log.warning("%s: dropping %d bytes of unframed input", self.port_name, overflow)
            del self._pending[:overflow]

    def discard_input(self) -> bytes:
        """Drop what is buffered (ours and the port's) and return it, e.g. stale replies before a new session."""
        try:
            waiting = self.port.in_waiting
            stale = bytes(self._pending) + (self.port.read(waiting) if waiting else b"")
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"{self.port_name}: cannot read: {exc}") from exc
        self._pending.clear()
        return stale

    def close(self) -> None:
        try:
            self.port.close()
        except (serial.SerialException, OSError) as exc:  # closing a vanished device must not mask the cause
            _log.warning("%s: close failed: %s", self.port_name, exc)


def open_port(url: str, *, baudrate: int, **settings: Any) -> Any:
    """Open ``url`` with ``serial.serial_for_url``; a failure becomes a :class:`LinkError` naming the port."""
    try:
        return serial.serial_for_url(url, baudrate=baudrate, **settings)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise LinkError(f"{url}: cannot open serial port at {baudrate} baud: {exc}") from exc
