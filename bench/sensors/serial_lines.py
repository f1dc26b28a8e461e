"""Line framing on a serial port for sensors that send one ASCII line per sample (MCU mice, serial callipers).

The port is any pySerial port (``serial.serial_for_url`` gives ptys, ``loop://`` and real ports alike); the transport
is the robots' own (:class:`bench.serial_link.FramedLink`: pySerial's read timeout sliced under a monotonic deadline),
a frame here being one line; parsing lives in each sensor module.
"""

from __future__ import annotations

import time
from typing import Any, Protocol

from bench.errors import LinkError, LinkTimeout
from bench.sensors.reading import MalformedSample
from bench.serial_link import FramedLink

__all__ = ["LineReader", "Port"]


class Port(Protocol):
    """The part of ``serial.Serial`` a :class:`LineReader` uses."""

    timeout: float | None

    @property
    def in_waiting(self) -> int: ...

    def read(self, size: int = 1) -> bytes: ...


class LineReader(FramedLink):
    """Split a port's byte stream into lines.

    Parameters
    ----------
    port : Port
        An open port; its ``timeout`` is set to short poll slices while a line is awaited.
    name : str
        The device's name in messages (e.g. ``"calliper /dev/ttyUSB0"``).
    terminator : bytes
        End of a line; a trailing ``\\r`` is stripped as well.
    max_line_bytes : int
        Longer lines are refused as malformed (a wrong baud rate produces endless garbage).
    """

    def __init__(self, port: Any, name: str, *, terminator: bytes = b"\n", max_line_bytes: int = 256) -> None:
        super().__init__(port, max_pending=max(4096, 2 * max_line_bytes))
        self.name = name
        self.terminator = terminator
        self.max_line_bytes = max_line_bytes

    @property
    def port_name(self) -> str:
        return self.name

    def _take_frame(self) -> bytes | None:
        end = self._pending.find(self.terminator)
        if end < 0:
            if len(self._pending) > self.max_line_bytes:
                garbage = bytes(self._pending)
                self._pending.clear()
                raise MalformedSample(
                    f"{self.name}: {len(garbage)} bytes without a line end "
                    f"({garbage[:32]!r}...); check the baud rate and framing"
                )
            return None
        line = bytes(self._pending[:end])
        del self._pending[: end + len(self.terminator)]
        return line.rstrip(b"\r")

    def read_line(self, timeout_s: float) -> bytes:
        """Return the next complete line without its terminator; ``LinkTimeout`` after ``timeout_s``;
        :class:`MalformedSample` for a line longer than ``max_line_bytes``; ``LinkError`` when the port fails."""
        start = time.monotonic()
        try:
            return self.read_frame(timeout_s, command="a line", expected="a complete line")
        except MalformedSample:
            raise
        except LinkTimeout:
            raise LinkTimeout(
                f"{self.name}: no complete line after {time.monotonic() - start:.2f} s (received so far: "
                f"{bytes(self._pending)!r}); is the device connected and sending?"
            ) from None
        except LinkError as exc:
            cause = exc.__cause__ or exc
            raise LinkError(f"{self.name}: read failed ({cause}); the device was probably unplugged") from None
