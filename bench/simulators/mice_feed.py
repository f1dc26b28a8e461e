"""Optical mice that watch the simulated pkm5 from inside its simulator process, written to FIFOs as a kernel
event device would be read (``bench sim pkm5 --mice DIR``).

This is the device-for-device stand-in of a station's ``[mice]``: the host opens ``DIR/mouse_xy.fifo`` and
``DIR/mouse_xz.fifo`` exactly as it opens ``/dev/input/by-id/...``, with no simulator verb on the controller link.
Each time the simulated robot comes to rest, the true motion since the last rest is fed to both mice (a straight
line over :data:`MOTION_S` of mouse time, quantised with carry, 500 Hz reports) and written *before* the controller
sends its ``DONE``, so the reports are in the FIFO when the host learns the move ended. A FIFO nobody drains fills up
and further reports are lost, as a kernel buffer overflows (``SYN_DROPPED``). The x-z mouse rides the platform (it
sees x and z) or, ``--mice-xz-mount guided``, runs on vertical guides pushed by the end effector (the dissertation's
Z mouse): it sees z only, its x counts stay 0 apart from noise (:func:`seen_by`).
"""

from __future__ import annotations

import dataclasses
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from bench.rigs.mice_liveness import XZ_GUIDED, XZ_PLATFORM
from bench.sensors.calibration import DEFAULT_CPI
from bench.simulators.mouse import MouseSimulator, MouseStream

__all__ = ["MOTION_S", "PLANES", "MiceFeed", "fifo_paths", "plane_seed", "seen_by", "stand_in"]

_log = logging.getLogger(__name__)

#: Mouse time the unobserved motion between two rests takes, s (only the end points are simulated).
MOTION_S = 0.05
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
    ) -> None:
        self._clock_s = 0.0
        self._writers: dict[str, int] = {}
        self._streams: dict[str, MouseStream] = {}
        start = np.asarray(start_pose, dtype=float)[:3]
        self._start, self._xz_mount = start, xz_mount
        for index, (plane, path) in enumerate(fifo_paths(folder).items()):
            if not os.path.exists(path):
                os.mkfifo(path)
            # read-write and non-blocking: the open returns before the host opens its end, and a full FIFO never
            # blocks the simulator (the reports are lost instead, as a kernel buffer overflows)
            self._writers[plane] = os.open(path, os.O_RDWR | os.O_NONBLOCK)
            simulator = MouseSimulator(
                cpi=cpi, noise_counts=noise_counts, report_rate_hz=report_rate_hz, seed=plane_seed(seed, index)
            )
            self._streams[plane] = MouseStream(simulator, origin_mm=seen_by(plane, start[None], start, xz_mount)[0])

    def rest(self, true_pose: np.ndarray) -> None:
        """The robot came to rest at ``true_pose``: report the motion there."""
        self._clock_s += MOTION_S
        xyz = np.asarray(true_pose, dtype=float)[:3]
        offset = _monotonic_now() - self._clock_s  # kernel-like timestamps on the host's CLOCK_MONOTONIC
        for plane in PLANES:
            data = self._streams[plane].input_events(
                np.array([self._clock_s]), seen_by(plane, xyz[None], self._start, self._xz_mount), clock_offset_s=offset
            )
            try:
                written = os.write(self._writers[plane], data)
            except BlockingIOError:
                written = 0
            if written < len(data):
                _log.warning(
                    "mouse_%s: FIFO full, %d of %d bytes of reports lost", plane, len(data) - written, len(data)
                )

    def close(self) -> None:
        for writer in self._writers.values():
            os.close(writer)
        self._writers.clear()


def _monotonic_now() -> float:
    import time

    return time.monotonic()
