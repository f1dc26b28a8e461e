"""Optical mice that watch the simulated pkm5 from inside its simulator process, written to FIFOs as a kernel
event device would be read (``bench sim pkm5 --mice DIR``).

This is the device-for-device stand-in of a station's ``[mice]``: the host opens ``DIR/mouse_xy.fifo`` and
``DIR/mouse_xz.fifo`` exactly as it opens ``/dev/input/by-id/...``, with no simulator verb on the controller link.
Each time the simulated robot comes to rest, its motion since the last rest is fed to both mice as a real mouse
reports it during the move: a straight line from the last rest to the new one over the move's simulated duration,
quantised with carry, at the mice's report rate (500 Hz), stamped on the mice's clock, and written *before* the
controller sends its ``DONE``, so the reports are in the FIFO when the host learns the move ended. The mice's clock
counts the rig's seconds (``CLOCK_MONOTONIC`` x the simulator's ``--speed-factor``, as the host's
:class:`bench.rigs.mice.MiceInstrument` reads it with ``time_scale``): a move of D simulated seconds took D / factor
of wall time, so its reports end now and start after the previous move's last report, and the report times of a
mouse never run backwards (a move the clock cannot fit is compressed into the time since the last report).
A FIFO nobody drains fills up
and further reports are lost, as a kernel buffer overflows (whole events only: the FIFO is written in atomic,
event-aligned pieces, so the host never reads a torn event). A rest waits up to :data:`_DRAIN_WAIT_S` for a host
that has not read yet (before it opens its mice) and up to :data:`_DRAIN_WAIT_READING_S` for one seen reading
(a host starved of CPU catches up rather than losing counts the cross-check would then refuse). The x-z mouse rides the platform (it
sees x and z) or, ``--mice-xz-mount guided``, runs on vertical guides pushed by the end effector (the dissertation's
Z mouse): it sees z only, its x counts stay 0 apart from noise (:func:`seen_by`).
"""

from __future__ import annotations

import dataclasses
import fcntl
import logging
import os
import select
import struct
import termios
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.rigs.mice_liveness import XZ_GUIDED, XZ_PLATFORM
from bench.sensors.calibration import DEFAULT_CPI
from bench.simulators.mouse import MouseSimulator, MouseStream

__all__ = ["MOTION_S", "PLANES", "MiceFeed", "fifo_paths", "plane_seed", "seen_by", "stand_in"]

_log = logging.getLogger(__name__)

#: Mouse time the unobserved motion between two rests takes, s (the simulated rig's mice, :mod:`bench.simulators.rig`).
MOTION_S = 0.05
#: How long a rest waits in all for the host to drain full FIFOs before the rest of its reports are lost, wall s:
#: the host's reader empties a pipe's buffer in well under a millisecond; nobody reads before the host opens its
#: mice (the homing move), and the controller must answer within its link's timeout meanwhile.
_DRAIN_WAIT_S = 0.05
#: The same once the host has been seen draining the FIFO: a reader starved of CPU for this long (a loaded test
#: machine) still gets every report; the controller's DONE waits meanwhile, well within its move's margin.
_DRAIN_WAIT_READING_S = 1.0
#: The largest piece written at once: whole ``input_event`` records (24 bytes) within ``PIPE_BUF`` (4096 bytes), which
#: a pipe writes atomically, all or nothing: a full FIFO never leaves half an event for the host to read.
_PIECE_BYTES = 24 * (select.PIPE_BUF // 24)
#: The pose coordinates each mouse sees: x-y mouse (x, y), x-z mouse (x, z).
PLANES = {"xy": (0, 1), "xz": (0, 2)}


def plane_seed(seed: int, plane_index: int) -> int:
    """An independent noise seed per mouse (seed + index would give seed s's x-z mouse seed s+1's x-y noise)."""
    return int(np.random.SeedSequence([seed, plane_index]).generate_state(1)[0])


def seen_by(plane: str, xyz: np.ndarray, start_xyz: np.ndarray, xz_mount: str = XZ_PLATFORM) -> np.ndarray:
    """The plane coordinates mouse ``plane`` sees of true positions ``xyz`` ((n, 3) mm): its :data:`PLANES` columns,
    except that an x-z mouse on vertical guides (``xz_mount`` :data:`XZ_GUIDED`) stays at the start's x."""
    seen = np.array(np.asarray(xyz, dtype=float)[:, list(PLANES[plane])])
    if plane == "xz" and xz_mount == XZ_GUIDED:
        seen[:, 0] = float(np.asarray(start_xyz, dtype=float)[0])
    return seen


def fifo_paths(folder: str | Path) -> dict[str, str]:
    """Where ``--mice DIR`` puts each plane's FIFO."""
    return {plane: str(Path(folder) / f"mouse_{plane}.fifo") for plane in PLANES}


def stand_in(station: Any, spec: Any, *, folder: str, truth_path: str) -> tuple[Any, list[str]]:
    """The ``[mice]`` of a rehearsal: the pkm5 simulator's ``--mice`` FIFOs in ``folder``, read as event devices
    (not grabbed; the count noise 0.05 unless the station states its own), the x-z mouse mounted as the station's."""
    paths = fifo_paths(folder)
    for path in paths.values():
        os.mkfifo(path)
    noise = spec.noise_counts if spec.noise_counts is not None else 0.05
    options = ["--mice", folder, "--mice-xz-mount", spec.xz_mount]
    return dataclasses.replace(spec, xy=paths["xy"], xz=paths["xz"], grab=False, noise_counts=noise), options


class MiceFeed:
    """Two simulated mice fed from the simulator's true pose, writing ``input_event`` records into FIFOs; the x-z
    mouse mounted by ``xz_mount`` (:func:`seen_by`)."""

    def __init__(
        self,
        folder: str | Path,
        start_pose: np.ndarray,
        *,
        seed: int,
        cpi: float = DEFAULT_CPI,
        noise_counts: float = 0.05,
        report_rate_hz: float = 500.0,
        xz_mount: str = XZ_PLATFORM,
        speed_factor: float = 1.0,
    ) -> None:
        self._speed_factor = float(speed_factor)
        self._clock_s = self._now()
        self._writers: dict[str, int] = {}
        self._unread: dict[str, int] = {}  # per FIFO, the bytes it held after the last write
        self._host_reads: dict[str, bool] = {}  # per FIFO, whether the host has been seen draining it
        self._streams: dict[str, MouseStream] = {}
        start = np.asarray(start_pose, dtype=float)[:3]
        self._start, self._xz_mount = start, xz_mount
        for index, (plane, path) in enumerate(fifo_paths(folder).items()):
            if not os.path.exists(path):
                os.mkfifo(path)
            # read-write and non-blocking: the open returns before the host opens its end, and a full FIFO never
            # blocks the simulator for long (the reports are lost instead, as a kernel buffer overflows)
            self._writers[plane] = os.open(path, os.O_RDWR | os.O_NONBLOCK)
            self._unread[plane], self._host_reads[plane] = _unread_bytes(self._writers[plane]), False
            simulator = MouseSimulator(
                cpi=cpi, noise_counts=noise_counts, report_rate_hz=report_rate_hz, seed=plane_seed(seed, index)
            )
            origin = seen_by(plane, start[None], start, xz_mount)[0]
            self._streams[plane] = MouseStream(simulator, origin_mm=origin, t0_s=self._clock_s)

    def _now(self) -> float:
        """The mice's clock: the rig's seconds, ``CLOCK_MONOTONIC`` x the speed factor."""
        return time.monotonic() * self._speed_factor

    def rest(self, true_pose: np.ndarray, motion_s: float = 0.0) -> None:
        """The robot came to rest at ``true_pose`` after moving for ``motion_s`` simulated seconds: report that
        motion, a straight line from the last rest ending now, at the mice's report rate."""
        xyz = np.asarray(true_pose, dtype=float)[:3]
        end_s = max(self._now(), self._clock_s + 1e-6)
        # at rest until the move started; a move the clock has no time for is compressed into the time since the
        # last report
        start_s = min(max(end_s - float(motion_s), self._clock_s), end_s - 1e-6)
        now = time.monotonic()
        for plane in PLANES:
            self._streams[plane].idle_until(start_s)
            seen = seen_by(plane, xyz[None], self._start, self._xz_mount)
            data = self._streams[plane].input_events(np.array([end_s]), seen)
            fd = self._writers[plane]
            before = _unread_bytes(fd)
            # bytes gone from the FIFO since the last write, or during this one: the host reads it
            self._host_reads[plane] = self._host_reads[plane] or before < self._unread[plane]
            wait_s = _DRAIN_WAIT_READING_S if self._host_reads[plane] else _DRAIN_WAIT_S
            written = _write_draining(fd, data, now + wait_s)
            self._unread[plane] = _unread_bytes(fd)
            self._host_reads[plane] = self._host_reads[plane] or self._unread[plane] < before + written
            if written < len(data):
                _log.warning(
                    "mouse_%s: FIFO full, %d of %d bytes of reports lost", plane, len(data) - written, len(data)
                )
        self._clock_s = end_s

    def close(self) -> None:
        for writer in self._writers.values():
            os.close(writer)
        self._writers.clear()


def _unread_bytes(fd: int) -> int:
    """The bytes a FIFO holds that nobody has read yet (``FIONREAD``)."""
    return int(struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0])


def _write_draining(fd: int, data: bytes, deadline: float) -> int:
    """Write ``data`` (whole ``input_event`` records) to a non-blocking FIFO in atomic pieces of whole records,
    waiting until ``deadline`` (monotonic) while it is full for the host's reader to drain it (a long move's reports
    exceed a pipe's buffer); the bytes written, always whole records."""
    written = 0
    while written < len(data):
        try:
            written += os.write(fd, data[written : written + _PIECE_BYTES])
        except BlockingIOError:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([], [fd], [], remaining)[1]:
                break
    return written
