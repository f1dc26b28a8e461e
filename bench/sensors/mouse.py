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
        if not words or int(words[-1], 16) & 0b11 != 0b11:   # REL_X and REL_Y are bits 0 and 1 of the last word
            continue
        found.append(DeviceBinding(node.name, stable.get(node.name, str(Path(dev_root) / node.name)),
                                   _read_text(node / "device" / "name"), _read_text(node / "device" / "phys"), True))
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
    """

    def __init__(self, path: str, calibration: CountsCalibration, *, label: str = "mouse",
                 grab: bool = False) -> None:
        self.name = label
        self.calibration = calibration
        self._stream = EventStream(path, kind="mouse", label=label, grab=grab)
        self.binding = self._stream.binding
        self._assembler = FrameAssembler()
        self.counts = np.zeros(2, np.int64)
        self.segment_valid = True
        self._last_t_s: float | None = None

    @property
    def exhausted(self) -> bool:
        """True once a pipe or file has ended (a device never ends; it fails when unplugged)."""
        return self._stream.exhausted

    def fileno(self) -> int:
        return self._stream.fileno()

    def read_frames(self) -> MotionFrames:
        """Read every byte available now (non-blocking) and return the completed frames; counts are integrated."""
        chunks = [self._assembler.feed(data) for data in self._stream.read_available()]
        frames = MotionFrames.concatenate(chunks)
        if len(frames):
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
        return {"sensor": "evdev mouse", "label": self.name, "path": self.binding.path, "name": self.binding.name,
                "phys": self.binding.phys, "is_device": self.binding.is_device,
                "calibration": self.calibration.to_dict(), "calibration_hash": self.calibration.content_hash()}

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
        return Reading((float(x_mm), float(y_mm)), "mm", t_mono, t_wall, raw=tuple(int(c) for c in self.counts),
                       calibration_id=self.calibration.calibration_id, source=str(self.binding),
                       valid=self.segment_valid, note="" if self.segment_valid else "SYN_DROPPED: counts lost")

    def close(self) -> None:
        """Close the device; the kernel releases any grab with it."""
        self._stream.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"EvdevMouse(path={self.binding.path!r}, label={self.name!r}, "
                f"calibration={self.calibration.calibration_id!r}, device={self.binding.is_device})")


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
