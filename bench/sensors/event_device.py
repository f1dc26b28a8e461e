"""Opening a Linux input event device, or a pipe or file in the same ``input_event`` layout: identification
(name, phys), ``CLOCK_MONOTONIC`` timestamps, optional exclusive grab, and non-blocking reads whose failures
name the device and what to do (``sensors.md`` §4.1-§4.7). Shared by mice and keyboard-wedge callipers.
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import selectors
import stat
import struct
from dataclasses import dataclass
from typing import Self

from bench.errors import LinkError

__all__ = ["EVIOCGRAB", "EVIOCSCLOCKID", "DeviceBinding", "EventStream", "eviocg"]

logger = logging.getLogger(__name__)

#: ``_IOW('E', 0x90, int)``: exclusive grab (argument 1) / release (0) (§4.6).
EVIOCGRAB = 0x40044590
#: ``_IOW('E', 0xa0, int)``: select the clock of the event timestamps (§4.5).
EVIOCSCLOCKID = 0x400445A0
_CLOCK_MONOTONIC = 1
_READ_SIZE = 1 << 16


def eviocg(nr: int, length: int) -> int:
    """``_IOC(_IOC_READ, 'E', nr, length)``: the string queries EVIOCGNAME (0x06), EVIOCGPHYS (0x07)."""
    return (2 << 30) | (length << 16) | (ord("E") << 8) | nr


@dataclass(frozen=True)
class DeviceBinding:
    """Which physical device a stream comes from; stored in the run manifest (``sensors.md`` §4.1).

    ``label`` is the bench's own name ("XY", "Z"); ``name``/``phys`` come from the kernel when the path is a real
    event device and are empty for pipes and files.
    """

    label: str
    path: str
    name: str = ""
    phys: str = ""
    is_device: bool = False
    kind: str = "mouse"

    def __str__(self) -> str:
        return f"{self.kind} {self.label!r} ({self.path}{', ' + self.name if self.name else ''})"


def _query_string(fd: int, nr: int) -> str:
    buf = bytearray(256)
    try:
        fcntl.ioctl(fd, eviocg(nr, len(buf)), buf)
    except OSError:
        return ""
    return bytes(buf).split(b"\0", 1)[0].decode(errors="replace")


def _open(kind: str, label: str, path: str) -> int:
    """Open non-blocking; a FIFO is opened blocking first, so that it waits for its writer instead of at EOF."""
    try:
        if stat.S_ISFIFO(os.stat(path).st_mode):
            fd = os.open(path, os.O_RDONLY)
            os.set_blocking(fd, False)
            return fd
        return os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise LinkError(
            f"{kind} {label!r}: {path} does not exist; is the {kind} plugged in? "
            "List /dev/input/by-path/ and bind the device again"
        ) from None
    except PermissionError:
        raise LinkError(
            f"{kind} {label!r}: permission denied on {path}; add a udev rule giving your group "
            "access to the device (sensors.md §4.7), then re-plug it"
        ) from None


class EventStream:
    """A non-blocking byte stream of ``input_event`` records.

    Parameters
    ----------
    path : str
        An event device (prefer a ``/dev/input/by-path/...`` link), a FIFO or a regular file.
    kind, label : str
        What the device is (``"mouse"``) and the bench's name for it, used in every message.
    grab : bool
        Take exclusive access with ``EVIOCGRAB``. Only applied to character devices; refused loudly (``LinkError``)
        if another client holds the device.
    """

    def __init__(self, path: str, *, kind: str, label: str, grab: bool = False) -> None:
        self._fd = _open(kind, label, path)
        is_device = stat.S_ISCHR(os.fstat(self._fd).st_mode)
        self.binding = DeviceBinding(
            label,
            path,
            _query_string(self._fd, 0x06) if is_device else "",
            _query_string(self._fd, 0x07) if is_device else "",
            is_device,
            kind,
        )
        self.exhausted = False
        if is_device:
            self._setup_device(grab)
        elif grab:
            logger.info("%s is not an event device; grab skipped", self.binding)

    def _setup_device(self, grab: bool) -> None:
        try:
            fcntl.ioctl(self._fd, EVIOCSCLOCKID, struct.pack("i", _CLOCK_MONOTONIC))
        except OSError as exc:
            logger.warning("%s: cannot switch timestamps to CLOCK_MONOTONIC (%s)", self.binding, exc)
        if grab:
            try:
                fcntl.ioctl(self._fd, EVIOCGRAB, 1)
            except OSError as exc:
                self.close()
                hint = "another program holds it" if exc.errno == errno.EBUSY else exc.strerror
                raise LinkError(
                    f"{self.binding}: exclusive grab failed ({hint}); close that program or run without grab"
                ) from None

    def fileno(self) -> int:
        return self._fd

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` until data (or the end of a pipe or file) can be read."""
        with selectors.PollSelector() as selector:  # epoll refuses regular files
            selector.register(self._fd, selectors.EVENT_READ)
            return bool(selector.select(timeout_s))

    def read_available(self) -> list[bytes]:
        """Every chunk readable now, without blocking; sets ``exhausted`` at the end of a pipe or file."""
        chunks = []
        while True:
            try:
                data = os.read(self._fd, _READ_SIZE)
            except BlockingIOError:
                return chunks
            except OSError as exc:
                raise LinkError(
                    f"{self.binding}: read failed ({exc.strerror}); the device was probably "
                    "unplugged: the run segment is invalid, re-bind and restart the cycle"
                ) from None
            if not data:
                self.exhausted = True
                return chunks
            chunks.append(data)

    def close(self) -> None:
        """Close the descriptor; the kernel releases any grab with it."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
