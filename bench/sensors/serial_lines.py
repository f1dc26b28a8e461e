"""Line framing on a serial port for sensors that send one ASCII line per sample (MCU mice, serial callipers).

The port is any pySerial-like object (``serial.serial_for_url`` gives ptys, ``loop://`` and real ports alike);
framing lives here, parsing in each sensor module. Every read has a monotonic deadline.
"""

from __future__ import annotations

import time
from typing import Protocol

from bench.errors import LinkError, LinkTimeout
from bench.sensors.reading import MalformedSample

__all__ = ["LineReader", "Port"]


class Port(Protocol):
    """The part of ``serial.Serial`` a :class:`LineReader` uses."""

    timeout: float | None

    def read(self, size: int = 1) -> bytes: ...


class LineReader:
    """Split a port's byte stream into lines.

    Parameters
    ----------
    port : Port
        An open port; its ``timeout`` is set to a short poll interval.
    name : str
        The device's name in messages (e.g. ``"calliper /dev/ttyUSB0"``).
    terminator : bytes
        End of a line; a trailing ``\\r`` is stripped as well.
    max_line_bytes : int
        Longer lines are refused as malformed (a wrong baud rate produces endless garbage).
    """

    def __init__(self, port: Port, name: str, *, terminator: bytes = b"\n", max_line_bytes: int = 256) -> None:
        self.port = port
        self.name = name
        self.terminator = terminator
        self.max_line_bytes = max_line_bytes
        self._buffer = b""
        port.timeout = 0.02

    def read_line(self, timeout_s: float) -> bytes:
        """Return the next complete line without its terminator; ``LinkTimeout`` after ``timeout_s``."""
        start = time.monotonic()
        while self.terminator not in self._buffer:
            if len(self._buffer) > self.max_line_bytes:
                garbage, self._buffer = self._buffer, b""
                raise MalformedSample(
                    f"{self.name}: {len(garbage)} bytes without a line end "
                    f"({garbage[:32]!r}...); check the baud rate and framing"
                )
            waited = time.monotonic() - start
            if waited >= timeout_s:
                raise LinkTimeout(
                    f"{self.name}: no complete line after {waited:.2f} s "
                    f"(received so far: {self._buffer!r}); is the device connected and sending?"
                )
            try:
                self._buffer += self.port.read(256)
            except OSError as exc:
                raise LinkError(f"{self.name}: read failed ({exc}); the device was probably unplugged") from None
        line, self._buffer = self._buffer.split(self.terminator, 1)
        return line.rstrip(b"\r")
