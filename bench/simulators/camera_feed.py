"""A camera that watches the simulated delta4's laser spot from inside its simulator process, streamed into a FIFO as
YUV4MPEG2 video (``bench sim delta4 --camera FIFO``).

This is the device-for-device stand-in of a station's ``[camera]``: the host opens the FIFO with OpenCV's
``VideoCapture`` exactly as it opens ``/dev/video0`` or a stream URL (:func:`bench.rigs.camera.video_grab`), with no
simulator verb on the controller link. Each frame is rendered by :class:`bench.simulators.camera.SpotCameraSimulator`
(:func:`delta4_camera`: 4 px/mm, a slight tilt and perspective, 2.5 px spot, 3 grey levels of read noise) from the
simulator's true x, y at the moment it is rendered (the pose last attained: the motion between two rests is not
rendered, as the laser grid reports it). Like a camera that exposes on demand, a new frame is rendered only
once the host has read everything written before (the FIFO is empty), so the host holds at most the one frame taken
when it read the previous one: :func:`bench.rigs.camera.video_grab` drops that frame before the first reading after
a move, as it drops a real camera's queued frames. A host that closes the stream is noticed at the next turn, and
the next one that opens it then gets a fresh stream header (a host that reopened within that turn would read the
end of the earlier stream: the simulator's turn is 2 ms, a rehearsal opens the camera once).
"""

from __future__ import annotations

import array
import dataclasses
import errno
import fcntl
import functools
import json
import logging
import os
import select
import termios
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.simulators.camera import SpotCameraSimulator

__all__ = ["CAMERA_SHAPE", "HOME_XY_MM", "CameraFeed", "delta4_camera", "stand_in", "write_plane_calibration"]

_log = logging.getLogger(__name__)

#: Frame rows, cols: +-85 mm of the plane at 4 px/mm.
CAMERA_SHAPE = (680, 680)
_PX_PER_MM = 4.0
#: The robot's home x, y (bench.robots.delta4.HOME_MM), where the lab zeroes the plane calibration.
HOME_XY_MM = (0.0, 0.0)
_F_SETPIPE_SZ = 1031
_PIPE_BYTES = 1 << 20  # a whole frame fits (the unprivileged maximum, /proc/sys/fs/pipe-max-size)


def delta4_camera(seed: int = 0) -> SpotCameraSimulator:
    """The simulated camera over the delta4's x-y plane: plane mm = the robot's x, y; centre of the frame at home;
    0.03 rad of roll and a slight perspective, as a hand-mounted camera has."""
    roll = 0.03
    tilt = np.array([[np.cos(roll), -np.sin(roll), 0.0], [np.sin(roll), np.cos(roll), 0.0], [1e-5, -1e-5, 1.0]])
    centre = np.array([[_PX_PER_MM, 0.0, CAMERA_SHAPE[1] / 2], [0.0, _PX_PER_MM, CAMERA_SHAPE[0] / 2], [0.0, 0.0, 1.0]])
    return SpotCameraSimulator(centre @ tilt, shape=CAMERA_SHAPE, sigma_px=2.5, noise_sigma=3.0, seed=seed)


def stand_in(station: Any, spec: Any, *, folder: str, truth_path: str) -> tuple[Any, list[str]]:
    """The ``[camera]`` of a rehearsal: the delta4 simulator's ``--camera`` video stream of the true laser spot (a
    FIFO in ``folder``), with a plane calibration made from the simulated camera's own chessboard image (the
    station's calibration file belongs to the real camera)."""
    if station.robot != "delta4":
        raise ConfigError(
            f"{station.source}: [camera] on the {station.robot} cannot be rehearsed yet (only the "
            "delta4 simulator streams a camera); check it with bench station check, or rehearse the "
            "protocol with [mice]"
        )
    if spec.plane != "xy":
        raise ConfigError(
            f"{station.source}: camera.plane = {spec.plane!r}: the simulated camera watches "
            "the x-y plane, expected 'xy' for a rehearsal"
        )
    device = os.path.join(folder, "camera.y4m")
    calibration = os.path.join(folder, "camera-plane.json")
    os.mkfifo(device)
    write_plane_calibration(calibration)
    return dataclasses.replace(spec, device=device, calibration=calibration), ["--camera", device]


def write_plane_calibration(path: str | os.PathLike[str], camera: SpotCameraSimulator | None = None) -> dict:
    """Calibrate the simulated camera as a lab does, and write the JSON the station's ``camera.calibration`` names.

    A 9 x 6 chessboard of 12 mm squares lies in the plane with its first inner corner at (-60, -40) mm; the fit
    (:func:`bench.sensors.camera_spot.calibrate_from_chessboard`) maps pixels to board mm; the plane is then zeroed
    at home (the spot's reading at home is subtracted), because :class:`bench.rigs.camera.CameraSpotInstrument` adds
    the home position to every reading. Returns the JSON's dict (``rms_mm``: the fit's RMS, the instrument's u_mm).
    """
    text = _default_calibration_json() if camera is None else json.dumps(_plane_calibration(camera))
    Path(path).write_text(text, encoding="utf-8")
    return json.loads(text)


@functools.cache
def _default_calibration_json() -> str:
    """The calibration of :func:`delta4_camera`, made once per process: it is the same every time (a rendered
    chessboard, no noise), and rendering the board is most of a rehearsal's start (0.6 s of CPU)."""
    return json.dumps(_plane_calibration(delta4_camera()))


def _plane_calibration(camera: SpotCameraSimulator) -> dict:
    from bench.sensors.camera_spot import PlaneCalibration, calibrate_from_chessboard, detect_spot

    square_mm, corner_mm = 12.0, np.array([-60.0, -40.0])
    to_corner = np.array([[1.0, 0.0, corner_mm[0]], [0.0, 1.0, corner_mm[1]], [0.0, 0.0, 1.0]])
    board_view = SpotCameraSimulator(camera.homography_mm_to_px @ to_corner, shape=camera.shape)
    fitted = calibrate_from_chessboard(
        board_view.chessboard((9, 6), square_mm),
        (9, 6),
        square_mm,
        calibration_id="sim-delta4-camera",
        date="2026-12-02",
    )
    spot = detect_spot(camera.frame(np.asarray(HOME_XY_MM), np.random.default_rng(0)))
    home_reading = fitted.pixel_to_mm(np.array([spot.u_px, spot.v_px]))
    zero_at_home = np.array([[1.0, 0.0, -home_reading[0]], [0.0, 1.0, -home_reading[1]], [0.0, 0.0, 1.0]])
    calibration = PlaneCalibration(
        zero_at_home @ fitted.homography_px_to_mm, fitted.rms_mm, fitted.calibration_id, fitted.date
    )
    return calibration.to_dict()


class CameraFeed:
    """Renders frames of the true x, y on demand into ``path`` (a FIFO, made if missing) as YUV4MPEG2 mono."""

    def __init__(
        self, path: str | os.PathLike[str], *, seed: int = 0, camera: SpotCameraSimulator | None = None
    ) -> None:
        self.path = str(path)
        if not os.path.exists(self.path):
            os.mkfifo(self.path)
        self.camera = camera or delta4_camera(seed)
        self._rng = np.random.default_rng([seed, 0x43414D])
        self._fd: int | None = None
        self._pending = b""
        self.frames = 0  #: frames rendered so far

    def _open(self) -> bool:
        try:  # write-only and non-blocking: refused (ENXIO) until a host has opened its end
            self._fd = os.open(self.path, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno == errno.ENXIO:
                return False
            raise
        try:
            fcntl.fcntl(self._fd, _F_SETPIPE_SZ, _PIPE_BYTES)
        except OSError:  # a smaller pipe only means a frame goes in several writes
            pass
        rows, cols = self.camera.shape
        self._pending = f"YUV4MPEG2 W{cols} H{rows} F30:1 Ip A1:1 Cmono\n".encode("ascii")
        return True

    def _close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
        self._fd, self._pending = None, b""

    @property
    def connected(self) -> bool:
        """Whether a host has the stream open (as far as the last turn saw)."""
        return self._fd is not None

    def _unread_bytes(self) -> int:
        count = array.array("i", [0])
        fcntl.ioctl(self._fd, termios.FIONREAD, count)
        return count[0]

    def stream(self, true_pose: np.ndarray) -> None:
        """One turn: open for a new host, notice a host that left, write what is pending, render the next frame
        (from ``true_pose``'s x, y) once the host has read everything."""
        if self._fd is None and not self._open():
            return
        poller = select.poll()
        poller.register(self._fd, select.POLLOUT)
        if any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0)):
            self._close()  # the host closed the stream
            return
        if not self._pending and self._unread_bytes() == 0:
            frame = self.camera.frame(np.asarray(true_pose, dtype=float)[:2], self._rng)
            self._pending = b"FRAME\n" + frame.tobytes()
            self.frames += 1
        try:
            written = os.write(self._fd, self._pending) if self._pending else 0
        except BlockingIOError:
            written = 0
        except BrokenPipeError:
            self._close()
            return
        self._pending = self._pending[written:]

    def close(self) -> None:
        self._close()
