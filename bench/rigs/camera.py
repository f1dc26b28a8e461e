"""The camera laser-spot sensor as an Instrument: a camera looks at a laser spot on a plane fixed to the robot's
frame and reports the spot's plane position in mm through the plane calibration (``sensors.md`` §7).

The camera measures the two coordinates of its plane only (``[camera] plane``, default ``xy``): a capture stores
those two and never the third (absent, not 0: the analysis sees what was measured). The plane's origin is where the
spot is when the robot stands at its registration pose, so a reading is ``registration + plane position``.
"""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.errors import ConfigError
from bench.rigs.interfaces import Measurement
from bench.steps import Capture

if TYPE_CHECKING:
    from bench.rigs.check import DeviceCheck
    from bench.rigs.opening import SensorOpening
    from bench.rigs.station import Station, StationTable

__all__ = [
    "CameraSpec",
    "CameraSpotInstrument",
    "check_camera",
    "load_plane_calibration",
    "open_camera",
    "parse_camera",
    "video_grab",
]

_AXES = {"xy": ("x_mm", "y_mm"), "xz": ("x_mm", "z_mm"), "yz": ("y_mm", "z_mm")}
_INDEX = {"x_mm": 0, "y_mm": 1, "z_mm": 2}
_FRAMES_EXPECTED = "an integer 1-100 (frames averaged per reading)"


@dataclass(frozen=True)
class CameraSpec:
    """A camera looking at the laser spot on a plane: ``device`` is a video device, an index or a stream URL;
    ``calibration`` a JSON file with the plane calibration (:class:`bench.sensors.camera_spot.PlaneCalibration`)."""

    device: str
    calibration: str
    plane: str = "xy"  #: the two pose coordinates the camera's plane measures
    #: frames averaged into one reading: the spot centroid's noise falls as 1/sqrt(frames) (a reading that corrects
    #: a command copies its noise into it, so iterative correction to the camera's uncertainty needs a few)
    frames: int = 1


def parse_camera(table: StationTable) -> CameraSpec:
    """``[camera]`` of a station file; a relative calibration path is relative to the station file."""
    camera = CameraSpec(
        device=str(
            table.get("device", (str, int), required=True, expected="a video device, camera index or stream URL")
        ),
        calibration=table.get("calibration", str, required=True, expected="the plane calibration JSON file"),
        plane=table.choice("plane", tuple(_AXES), "xy"),
        frames=table.get("frames", int, 1, expected=_FRAMES_EXPECTED),
    )
    if not 1 <= camera.frames <= 100:
        raise table.fail("frames", camera.frames, _FRAMES_EXPECTED)
    if not Path(camera.calibration).is_absolute() and table.source != "station":
        camera = replace(camera, calibration=str(Path(table.source).parent / camera.calibration))
    return camera


def open_camera(opening: SensorOpening) -> CameraSpotInstrument:
    """The camera as the rig's instrument, its plane's origin at the robot's home pose."""
    from bench.sensors.camera_spot import LaserSpotCamera

    spec: CameraSpec = opening.spec
    calibration = load_plane_calibration(spec.calibration)
    grab, grab_next, release = video_grab(spec.device)
    opening.opened.callback(release)
    return CameraSpotInstrument(
        LaserSpotCamera(grab, calibration, grab_next=grab_next), opening.home(), plane=spec.plane, frames=spec.frames
    )


def check_camera(station: Station, spec: CameraSpec) -> list[DeviceCheck]:
    """One frame read from the camera, and its calibration file found."""
    from bench.rigs.check import guarded

    return [guarded("camera.device", spec.device, "video", lambda: _first_frame(spec.device, spec.calibration))]


def _first_frame(device: str, calibration: str) -> str:
    from bench.extras import require

    cv2 = require("cv2")

    if not os.path.exists(calibration):
        raise OSError(errno.ENOENT, f"calibration file {calibration} not found")
    capture = cv2.VideoCapture(int(device) if device.isdigit() else device)
    try:
        ok, image = capture.read()
    finally:
        capture.release()
    if not ok:
        raise OSError(errno.EIO, "no frame read")
    return f"frame {image.shape[1]} x {image.shape[0]} px"


def load_plane_calibration(path: str) -> Any:
    """A :class:`bench.sensors.camera_spot.PlaneCalibration` from its JSON (``PlaneCalibration.to_dict``)."""
    from bench.sensors.camera_spot import PlaneCalibration

    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        return PlaneCalibration(
            np.asarray(data["homography_px_to_mm"], dtype=float),
            float(data["rms_mm"]),
            str(data["calibration_id"]),
            str(data["date"]),
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(
            f"camera.calibration = {path!r}: cannot read it ({exc}), expected the JSON of a plane "
            "calibration (homography_px_to_mm, rms_mm, calibration_id, date)"
        ) from None


def video_grab(device: str) -> tuple[Callable[[], np.ndarray], Callable[[], np.ndarray], Callable[[], None]]:
    """Frame grabbers on a video device, camera index or stream URL (OpenCV), and its release: ``grab`` for the
    first frame after a move, ``grab_next`` for the frames that follow it while the robot rests.

    A camera keeps delivering (or queueing) frames while nobody reads: the frame at the head of its queue after a move
    was taken before the move. The driver's queue is asked for one buffer (``CAP_PROP_BUFFERSIZE``, where the backend
    honours it), one frame is read at open (a device that gives none is refused at once), and ``grab`` drops the
    frame queued since the previous reading before it reads the one it returns. ``grab_next`` reads the next frame
    as it comes: right after a reading, the queued frame was taken after it, so nothing is stale to drop (a
    reading of several frames costs one frame period each, not two). A backend that ignores the one-buffer request
    keeps a deeper queue: ``grab`` then drops one stale frame of several, and ``camera.frames`` > 1 averages the
    rest in with the new frames; such a camera needs its driver's buffer set to one (or its frames read as they
    come, between readings)."""
    from bench.extras import require

    cv2 = require("cv2")

    from bench.errors import LinkError

    capture = cv2.VideoCapture(int(device) if device.isdigit() else device)
    if not capture.isOpened():
        raise LinkError(f"camera.device = {device!r}: cannot open it (is the camera plugged in, the name right?)")
    capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)

    def read() -> np.ndarray:
        ok, frame = capture.read()
        if not ok:
            raise LinkError(f"camera.device = {device!r}: no frame")
        return frame

    try:
        read()
    except LinkError:
        capture.release()
        raise

    def grab() -> np.ndarray:
        capture.grab()  # the frame queued since the last reading: taken before the robot moved
        return read()

    return grab, read, capture.release


class CameraSpotInstrument:
    """Plane position of the laser spot, mm, on the two axes of ``plane`` (``xy``, ``xz`` or ``yz``): the mean of
    ``frames`` consecutive frames' spot positions (each frame's pixels kept in the raw data)."""

    def __init__(self, camera: Any, origin_mm: Any, *, plane: str = "xy", frames: int = 1) -> None:
        if plane not in _AXES:
            raise ConfigError(f"camera.plane = {plane!r}, expected one of {', '.join(_AXES)}")
        if not (isinstance(frames, int) and 1 <= frames <= 100):
            raise ConfigError(f"camera.frames = {frames!r}, expected {_FRAMES_EXPECTED}")
        self.camera, self.plane, self.frames = camera, plane, frames
        self.origin = np.asarray(origin_mm, dtype=float)[:3].copy()

    def measure(self, capture: Capture) -> Measurement:
        if capture.kind != "pose":
            raise ConfigError(f"camera: capture kind {capture.kind!r}, expected 'pose' (the camera measures a plane)")
        # the first frame after the move, then the frames that follow it (none of them queued before the move)
        readings = [self.camera.read()] + [self.camera.read(next_frame=True) for _ in range(self.frames - 1)]
        mean = np.mean([reading.value for reading in readings], axis=0)
        axes = _AXES[self.plane]
        values = {axis: float(self.origin[_INDEX[axis]] + v) for axis, v in zip(axes, mean)}
        raw = {"spot_px": list(readings[0].raw), "calibration": readings[0].calibration_id, "note": readings[0].note}
        if self.frames > 1:  # every frame's spot, so the mean can be recomputed and its spread judged
            raw["frames_spot_px"] = [list(reading.raw) for reading in readings]
            raw["frames_note"] = [reading.note for reading in readings]
        return Measurement(values, raw=raw)

    def settings(self) -> dict[str, Any]:
        calibration = self.camera.calibration
        return {
            "instrument": f"camera laser spot ({self.plane} plane)",
            **self.camera.settings(),
            "calibration_id": calibration.calibration_id,
            "u_mm": float(calibration.rms_mm),
            "frames_per_reading": self.frames,
            "registration_mm": [float(v) for v in self.origin],
        }
