"""The kernel's ``input_event`` record: encoding, decoding, and assembling relative-motion frames.

A frame is the events of one hardware report up to ``EV_SYN/SYN_REPORT``; REL_X and REL_Y are summed within it
(``sensors.md`` §4.2-§4.4). ``SYN_DROPPED`` means the kernel discarded events: everything up to and including the
next ``SYN_REPORT`` is ignored and an *invalid* frame marks the lost counts, which are never repaired.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

__all__ = [
    "EVENT",
    "EVENT_DTYPE",
    "EV_KEY",
    "EV_REL",
    "EV_SYN",
    "REL_X",
    "REL_Y",
    "SYN_DROPPED",
    "SYN_REPORT",
    "FrameAssembler",
    "MotionFrames",
    "encode_frames",
]

EV_SYN, EV_KEY, EV_REL = 0x00, 0x01, 0x02
SYN_REPORT, SYN_DROPPED = 0, 3
REL_X, REL_Y = 0x00, 0x01

#: ``struct input_event`` with native sizes: 24 bytes on 64-bit Linux, 16 on 32-bit user space (§4.2).
EVENT = struct.Struct("llHHi")
_LONG = struct.calcsize("l")
#: The same layout as a numpy dtype, for bulk decoding.
EVENT_DTYPE = np.dtype(
    {
        "names": ["sec", "usec", "type", "code", "value"],
        "formats": [f"i{_LONG}", f"i{_LONG}", "u2", "u2", "i4"],
        "offsets": [0, _LONG, 2 * _LONG, 2 * _LONG + 2, 2 * _LONG + 4],
        "itemsize": EVENT.size,
    }
)


@dataclass(frozen=True)
class MotionFrames:
    """Frames of relative motion, one entry per ``SYN_REPORT``.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
        Kernel timestamp of each frame (s; the clock the device was set to, monotonic by default).
    dx, dy : ndarray of int64, shape (n,)
        Counts summed over the frame.
    valid : ndarray of bool, shape (n,)
        False for the marker frame that closes a ``SYN_DROPPED`` gap (its counts are zero and counts were lost).
    """

    t_s: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    valid: np.ndarray

    def __len__(self) -> int:
        return len(self.t_s)

    @classmethod
    def empty(cls) -> MotionFrames:
        return cls(np.empty(0), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, bool))

    @classmethod
    def concatenate(cls, parts: list[MotionFrames]) -> MotionFrames:
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("t_s", "dx", "dy", "valid")))


def encode_frames(t_s: np.ndarray, dx: np.ndarray, dy: np.ndarray, *, skip_zero: bool = True) -> bytes:
    """Encode frames as the kernel would: REL_X (if non-zero), REL_Y (if non-zero), then SYN_REPORT.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Frame timestamps (s), written as ``tv_sec`` / ``tv_usec``.
    dx, dy : array_like of int, shape (n,)
        Counts of each frame.
    skip_zero : bool
        Omit a zero axis, as evdev does; with False both axes are always written.
    """
    t_s, dx, dy = np.asarray(t_s, float), np.asarray(dx, np.int64), np.asarray(dy, np.int64)
    usec_total = np.round(t_s * 1e6).astype(np.int64)
    sec, usec = np.divmod(usec_total, 1_000_000)
    has_x = dx != 0 if skip_zero else np.ones(len(dx), bool)
    has_y = dy != 0 if skip_zero else np.ones(len(dy), bool)
    per_frame = has_x.astype(int) + has_y + 1
    events = np.zeros(int(per_frame.sum()), EVENT_DTYPE)
    end = np.cumsum(per_frame)
    start = end - per_frame
    frame_of_event = np.repeat(np.arange(len(t_s)), per_frame)
    events["sec"], events["usec"] = sec[frame_of_event], usec[frame_of_event]
    x_at = start[has_x]
    y_at = start[has_y] + has_x[has_y]
    events["type"][x_at], events["code"][x_at], events["value"][x_at] = EV_REL, REL_X, dx[has_x]
    events["type"][y_at], events["code"][y_at], events["value"][y_at] = EV_REL, REL_Y, dy[has_y]
    events["type"][end - 1], events["code"][end - 1] = EV_SYN, SYN_REPORT
    return events.tobytes()


class FrameAssembler:
    """Turn a byte stream of ``input_event`` records into :class:`MotionFrames`, chunk by chunk.

    Partial records and the events after the last ``SYN_REPORT`` are carried to the next :meth:`feed`. Chunks
    without ``SYN_DROPPED`` take a vectorised path; the rest go through :meth:`_feed_events_loop`, the plain
    reference implementation of §4.10.
    """

    def __init__(self) -> None:
        self._pending = b""
        self._dropping = False

    def feed(self, data: bytes) -> MotionFrames:
        """Decode ``data`` (any length) and return the frames it completes."""
        buffer = self._pending + data
        whole = len(buffer) - len(buffer) % EVENT.size
        events = np.frombuffer(buffer, EVENT_DTYPE, count=whole // EVENT.size)
        is_syn = events["type"] == EV_SYN
        report = is_syn & (events["code"] == SYN_REPORT)
        if not report.any() and not self._dropping:
            self._pending = buffer
            return MotionFrames.empty()
        dropped = is_syn & (events["code"] == SYN_DROPPED)
        if self._dropping or dropped.any():
            frames, used = self._feed_events_loop(events)
        else:
            frames, used = self._feed_events_vectorised(events, report)
        self._pending = buffer[used * EVENT.size :]
        return frames

    @staticmethod
    def _feed_events_vectorised(events: np.ndarray, report: np.ndarray) -> tuple[MotionFrames, int]:
        last = int(np.flatnonzero(report)[-1])
        events, report = events[: last + 1], report[: last + 1]
        frame_of_event = np.cumsum(report) - report
        n_frames = int(report.sum())
        rel = events["type"] == EV_REL
        sums = []
        for code in (REL_X, REL_Y):
            sel = rel & (events["code"] == code)
            sums.append(
                np.bincount(frame_of_event[sel], weights=events["value"][sel], minlength=n_frames).astype(np.int64)
            )
        ends = events[report]
        t_s = ends["sec"] + ends["usec"] * 1e-6
        return MotionFrames(t_s, sums[0], sums[1], np.ones(n_frames, bool)), last + 1

    def _feed_events_loop(self, events: np.ndarray) -> tuple[MotionFrames, int]:
        t_out, dx_out, dy_out, valid_out = [], [], [], []
        fx = fy = 0
        used = 0
        for k, (sec, usec, etype, code, value) in enumerate(events.tolist()):
            if etype == EV_REL and code == REL_X:
                fx += value
            elif etype == EV_REL and code == REL_Y:
                fy += value
            elif etype == EV_SYN and code == SYN_DROPPED:
                self._dropping = True
            elif etype == EV_SYN and code == SYN_REPORT:
                t_out.append(sec + usec * 1e-6)
                dx_out.append(0 if self._dropping else fx)
                dy_out.append(0 if self._dropping else fy)
                valid_out.append(not self._dropping)
                self._dropping = False
                fx = fy = 0
                used = k + 1
        return MotionFrames(
            np.array(t_out, float), np.array(dx_out, np.int64), np.array(dy_out, np.int64), np.array(valid_out, bool)
        ), used
