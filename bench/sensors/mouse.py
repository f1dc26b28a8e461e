"""Optical mouse read as raw counts from a Linux event device (``/dev/input/event*``) or any byte stream in the
same ``input_event`` layout (a pipe or file written by :mod:`bench.simulators.mouse`).

Replaces the dissertation's two-PC cursor method (``sensors.md`` §2-§4): per-device counts below pointer
acceleration, kernel timestamps on ``CLOCK_MONOTONIC``, several mice told apart by name/phys, optional grab.
"""

from __future__ import annotations

import logging
import os
import selectors
import time
from pathlib import Path
from typing import Self

import numpy as np

from bench.errors import LinkError
from bench.sensors.calibration import CountsCalibration
from bench.sensors.event_device import (
    EVIOCGRAB,
    EVIOCSCLOCKID,
    DeviceBinding,
    EventStream,
)
from bench.sensors.input_event import FrameAssembler, MotionFrames
from bench.sensors.reader_process import ReaderProcess
from bench.sensors.reading import Reading, now

__all__ = ["EVIOCGRAB", "EVIOCSCLOCKID", "EvdevMouse", "MouseBinding", "MouseGroup", "list_mice"]

logger = logging.getLogger(__name__)

#: Kept under the historical name: a mouse's binding is a :class:`DeviceBinding`.
MouseBinding = DeviceBinding


def _read_text(path: Path) -> str:
    try:
        return path.read_text().strip()
    except OSError:
        return ""


def list_mice(*, dev_root: str = "/dev/input", sysfs_root: str = "/sys/class/input") -> list[MouseBinding]:
    """Event devices that report REL_X and REL_Y, named by their stable link where one exists.

    Reads ``/sys/class/input/eventN/device/{name,phys,capabilities/rel}`` (no permission needed) and prefers a
    ``by-path`` link (stable per USB port, works for identical mice) over ``by-id`` (``sensors.md`` §4.1). Use
    it for the daily wiggle test: move one sensor and see which binding produces counts.
    """
    stable: dict[str, str] = {}
    for folder in ("by-path", "by-id"):
        links = Path(dev_root) / folder
        if links.is_dir():
            for link in sorted(links.iterdir()):
                stable.setdefault(os.path.basename(os.path.realpath(link)), str(link))
    found = []
    nodes = sorted(Path(sysfs_root).glob("event*"), key=lambda p: int(p.name[5:]) if p.name[5:].isdigit() else -1)
    for node in nodes:
        words = _read_text(node / "device" / "capabilities" / "rel").split()
        if not words or int(words[-1], 16) & 0b11 != 0b11:  # REL_X and REL_Y are bits 0 and 1 of the last word
            continue
        found.append(
            DeviceBinding(
                node.name,
                stable.get(node.name, str(Path(dev_root) / node.name)),
                _read_text(node / "device" / "name"),
                _read_text(node / "device" / "phys"),
                True,
            )
        )
    return found


class EvdevMouse:
    """One mouse read as raw counts, with the calibration applied on :meth:`read`.

    Parameters
    ----------
    path : str
        An event device (prefer ``/dev/input/by-path/...-event-mouse``), a FIFO or a regular file.
    calibration : CountsCalibration
        Counts -> mm; its id travels with every reading.
    label : str
        The bench's name for this sensor.
    grab : bool
        Take exclusive access with ``EVIOCGRAB`` so the sensor does not move the desktop pointer. Only applied to
        real character devices; refused loudly if another client holds the device.
    reader_process : bool
        Read through a child process (:meth:`start_reader_process`) from the start.
    """

    def __init__(
        self,
        path: str,
        calibration: CountsCalibration,
        *,
        label: str = "mouse",
        grab: bool = False,
        reader_process: bool = False,
    ) -> None:
        self.name = label
        self.calibration = calibration
        self._stream = EventStream(path, kind="mouse", label=label, grab=grab)
        self.binding = self._stream.binding
        self._assembler = FrameAssembler()
        self.counts = np.zeros(2, np.int64)
        self.segment_valid = True
        self._last_t_s: float | None = None
        #: ``SYN_DROPPED`` gaps seen since the mouse was opened (each one lost counts; its segment is invalid).
        self.dropped_gaps = 0
        self._reader: ReaderProcess | None = None
        if reader_process:
            self.start_reader_process()

    def start_reader_process(self, *, realtime: bool = True) -> None:
        """From now on a child process drains the device (:mod:`bench.sensors.reader_process`), so that no Python
        work of this process can starve it; :meth:`read_frames`, :meth:`fileno` and :attr:`exhausted` read its
        frames. Bytes read before stay with the in-process assembler (an unfinished frame is completed by neither).
        ``realtime`` asks for real-time priority for it (see :class:`ReaderProcess`)."""
        if self._reader is None:
            self._reader = ReaderProcess(self._stream.fileno(), name=str(self.binding), realtime=realtime)

    @property
    def exhausted(self) -> bool:
        """True once a pipe or file has ended (a device never ends; it fails when unplugged)."""
        return self._reader.exhausted if self._reader is not None else self._stream.exhausted

    def fileno(self) -> int:
        return self._reader.fileno() if self._reader is not None else self._stream.fileno()

    def read_frames(self, *, up_to_now: bool = False) -> MotionFrames:
        """Read every frame available now (non-blocking) and return the completed frames; counts are integrated.
        With a reader process, ``up_to_now`` waits for the frames still on their way from it (a capture's read).
        """
        if self._reader is not None:
            frames = self._reader.read_frames(up_to_now=up_to_now)
        else:
            frames = MotionFrames.concatenate([self._assembler.feed(data) for data in self._stream.read_available()])
        if len(frames):
            self.dropped_gaps += int(len(frames) - frames.valid.sum())
            self.counts += (int(frames.dx.sum()), int(frames.dy.sum()))
            self.segment_valid &= bool(frames.valid.all())
            self._last_t_s = float(frames.t_s[-1])
        return frames

    def rezero(self) -> None:
        """Start a new measurement segment at the current position (e.g. at home, every cycle)."""
        self.counts[:] = 0
        self.segment_valid = True

    def settings(self) -> dict[str, object]:
        """What a run manifest stores about this sensor: binding and calibration (id, hash, matrix)."""
        return {
            "sensor": "evdev mouse",
            "label": self.name,
            "path": self.binding.path,
            "name": self.binding.name,
            "phys": self.binding.phys,
            "is_device": self.binding.is_device,
            "calibration": self.calibration.to_dict(),
            "calibration_hash": self.calibration.content_hash(),
            "reader": self._reader_kind(),
        }

    def _reader_kind(self) -> str:
        """How the device is read: by this process, or by a reader process (at real-time priority or not)."""
        if self._reader is None:
            return "in process"
        return "reader process, real-time priority" if self._reader.realtime else "reader process, normal priority"

    def read(self, timeout_s: float = 0.0) -> Reading:
        """Integrated displacement since the last :meth:`rezero`, in mm, after waiting up to ``timeout_s``."""
        if timeout_s > 0:
            self._stream.wait(timeout_s)
        self.read_frames()
        return self.reading()

    def reading(self) -> Reading:
        """The integrated displacement of the frames read so far (no read), in mm."""
        t_mono, t_wall = now()
        if self._last_t_s is not None and self.binding.is_device:
            t_wall -= t_mono - self._last_t_s
            t_mono = self._last_t_s
        x_mm, y_mm = self.calibration.counts_to_mm(self.counts)
        return Reading(
            (float(x_mm), float(y_mm)),
            "mm",
            t_mono,
            t_wall,
            raw=tuple(int(c) for c in self.counts),
            calibration_id=self.calibration.calibration_id,
            source=str(self.binding),
            valid=self.segment_valid,
            note="" if self.segment_valid else "SYN_DROPPED: counts lost",
        )

    def close(self) -> None:
        """Stop the reader process if any, close the device; the kernel releases any grab with it."""
        if self._reader is not None:
            self._reader.close()
        self._stream.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"EvdevMouse(path={self.binding.path!r}, label={self.name!r}, "
            f"calibration={self.calibration.calibration_id!r}, device={self.binding.is_device})"
        )


class MouseGroup:
    """Several mice read in one thread with ``selectors``; frames come back keyed by each mouse's label."""

    def __init__(self, mice: list[EvdevMouse]) -> None:
        labels = [m.name for m in mice]
        if len(set(labels)) != len(labels):
            raise LinkError(f"mouse group: labels {labels} repeat; each sensor needs its own label")
        self.mice = {m.name: m for m in mice}
        self._selector = selectors.PollSelector()  # epoll refuses regular files
        for mouse in mice:
            self._selector.register(mouse.fileno(), selectors.EVENT_READ, mouse)

    def poll(self, timeout_s: float) -> dict[str, MotionFrames]:
        """Wait up to ``timeout_s`` for data and return the new frames of every mouse that had some."""
        out: dict[str, MotionFrames] = {}
        for key, _ in self._selector.select(timeout_s):
            mouse: EvdevMouse = key.data
            frames = mouse.read_frames()
            if mouse.exhausted:
                self._selector.unregister(key.fd)
            if len(frames):
                out[mouse.name] = frames
        return out

    def collect(self, duration_s: float) -> dict[str, MotionFrames]:
        """Read all mice for ``duration_s`` (or until every stream ends) and return all frames per label."""
        parts: dict[str, list[MotionFrames]] = {label: [] for label in self.mice}
        deadline = time.monotonic() + duration_s
        while self._selector.get_map() and (remaining := deadline - time.monotonic()) > 0:
            for label, frames in self.poll(min(remaining, 0.1)).items():
                parts[label].append(frames)
        return {label: MotionFrames.concatenate(p) for label, p in parts.items()}

    def close(self) -> None:
        self._selector.close()
        for mouse in self.mice.values():
            mouse.close()
