"""Camera laser-spot sensor: sub-pixel spot centroid with OpenCV, and pixel -> mm through a homography fitted to
a chessboard target lying in the measuring plane. Together an absolute 2-D position sensor.

The homography model assumes negligible lens distortion over the target; for wide-angle lenses undistort first
(``cv2.calibrateCamera``).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench.errors import ConfigError
from bench.extras import require
from bench.sensors.reading import MalformedSample, Reading, SensorStalled, now

cv2 = require("cv2")  # the camera extra: a station without a camera never imports this module

__all__ = ["LaserSpotCamera", "PlaneCalibration", "SpotDetection", "calibrate_from_chessboard", "detect_spot"]


@dataclass(frozen=True)
class SpotDetection:
    """A detected spot: centroid (px; u right, v down; pixel centres at integers), peak and contrast (grey
    levels above the background), and the number of pixels used."""

    u_px: float
    v_px: float
    peak: float
    contrast: float
    area_px: int


def _channel(image: np.ndarray, source: str) -> np.ndarray:
    """The image's laser channel as stored: the red channel of BGR (the 635 nm laser), or the grey image."""
    if image is None or image.size == 0:
        raise MalformedSample(f"{source}: empty image; check that the camera is connected and streaming")
    if image.ndim == 3:
        return image[:, :, 2]
    if image.ndim != 2:
        raise MalformedSample(f"{source}: image shape {image.shape}, expected (rows, cols) or (rows, cols, 3)")
    return image


def _median(channel: np.ndarray) -> float:
    """The median grey level, as ``np.median`` gives it. An 8-bit frame's median comes from its 256-bin histogram
    (OpenCV's, exact counts below 2^24 pixels): a sort of every pixel was a third of a detection's time."""
    if channel.dtype != np.uint8 or channel.size >= 1 << 24:
        return float(np.median(channel.astype(np.float64)))
    counts = cv2.calcHist([np.ascontiguousarray(channel)], [0], None, [256], [0, 256]).ravel()
    cumulative = np.cumsum(counts)
    middle = channel.size // 2
    upper = int(np.searchsorted(cumulative, middle, side="right"))  # the sorted pixel at index ``middle``
    if channel.size % 2:
        return float(upper)
    lower = int(np.searchsorted(cumulative, middle - 1, side="right"))
    return (lower + upper) / 2


def detect_spot(
    image: np.ndarray,
    *,
    min_contrast: float = 25.0,
    level: float = 0.2,
    saturation: float = 255.0,
    max_area_px: int = 5000,
    source: str = "camera",
) -> SpotDetection:
    """Find the laser spot and its intensity-weighted centroid.

    The background is the image median. Pixels of the connected blob around the brightest (smoothed) pixel that
    exceed ``background + level * contrast`` are weighted by their excess over that level; subtracting a
    symmetric level keeps the centroid of a symmetric spot unbiased.

    Raises ``MalformedSample`` for an empty image, no spot (contrast below ``min_contrast``), a saturated spot
    (its centroid would be biased by clipping) or a blob larger than ``max_area_px`` (stray light).
    """
    channel = _channel(image, source)
    grey = channel.astype(np.float64)
    background = _median(channel)
    smooth = cv2.GaussianBlur(grey, (5, 5), 0)
    v0, u0 = np.unravel_index(int(np.argmax(smooth)), smooth.shape)
    contrast = float(smooth[v0, u0] - background)
    if contrast < min_contrast:
        raise MalformedSample(
            f"{source}: no laser spot (peak {contrast:.1f} grey levels above background, "
            f"expected >= {min_contrast:g}); check the laser, the exposure and the aim"
        )
    threshold = background + level * contrast
    mask = (smooth > threshold).astype(np.uint8)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    label = labels[v0, u0]
    area = int(stats[label, cv2.CC_STAT_AREA])
    if area > max_area_px:
        raise MalformedSample(
            f"{source}: bright region of {area} px around ({u0}, {v0}), expected a spot of at "
            f"most {max_area_px} px; stray light or wrong exposure"
        )
    # the blob's bounding box holds every pixel it weighs: the centroid sums over it, not over the whole frame
    left, top, width, height = (
        int(stats[label, k]) for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT)
    )
    box = (slice(top, top + height), slice(left, left + width))
    blob = labels[box] == label
    pixels = grey[box]
    if np.any(pixels[blob] >= saturation):
        raise MalformedSample(
            f"{source}: spot saturated ({int(np.sum(pixels[blob] >= saturation))} px at "
            f"{saturation:g}); reduce the exposure or laser power"
        )
    weights = np.where(blob, np.clip(pixels - threshold, 0.0, None), 0.0)
    total = weights.sum()
    rows, cols = np.indices(pixels.shape)
    return SpotDetection(
        float((weights * (cols + left)).sum() / total),
        float((weights * (rows + top)).sum() / total),
        float(pixels[blob].max()),
        contrast,
        area,
    )


@dataclass(frozen=True, eq=False)
class PlaneCalibration:
    """Pixel -> mm map of the measuring plane, ``[x, y, 1] ~ H [u, v, 1]``.

    Attributes
    ----------
    homography_px_to_mm : ndarray, shape (3, 3)
    rms_mm : float
        RMS residual of the target's corners after the fit (mm).
    calibration_id, date : str
    """

    homography_px_to_mm: np.ndarray
    rms_mm: float
    calibration_id: str
    date: str

    def pixel_to_mm(self, uv_px: np.ndarray) -> np.ndarray:
        """Map pixel coordinates (N, 2) or (2,) to plane coordinates in mm, same shape."""
        uv = np.asarray(uv_px, float)
        points = cv2.perspectiveTransform(uv.reshape(-1, 1, 2), self.homography_px_to_mm).reshape(-1, 2)
        return points.reshape(uv.shape)

    def to_dict(self) -> dict[str, object]:
        return {
            "calibration_id": self.calibration_id,
            "date": self.date,
            "rms_mm": self.rms_mm,
            "homography_px_to_mm": self.homography_px_to_mm.tolist(),
        }


def calibrate_from_chessboard(
    image: np.ndarray, pattern_size: tuple[int, int], square_mm: float, *, calibration_id: str, date: str | None = None
) -> PlaneCalibration:
    """Fit the pixel -> mm homography from a chessboard target in the measuring plane.

    ``findChessboardCorners`` + ``cornerSubPix`` locate the ``pattern_size`` inner corners; the target frame has
    its origin at the inner corner nearest the image's top-left, x along ``pattern_size[0]``. ``findHomography``
    (least squares over all corners) gives the map.
    """
    if not square_mm > 0:
        raise ConfigError(f"camera calibration: square_mm = {square_mm!r}, expected the square size in mm")
    grey = _channel(image, "camera calibration").astype(np.uint8)
    found, corners = cv2.findChessboardCorners(
        grey, pattern_size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if not found:
        raise MalformedSample(
            f"camera calibration: chessboard with {pattern_size} inner corners not found; "
            "check pattern_size, focus, lighting and that the whole target is in view"
        )
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    corners = cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), criteria).reshape(-1, 2)
    if np.linalg.norm(corners[0]) > np.linalg.norm(corners[-1]):
        corners = corners[::-1]  # the detector may start from either end of the grid
    nx, ny = pattern_size
    target_mm = np.array([(i * square_mm, j * square_mm) for j in range(ny) for i in range(nx)], float)
    homography, _ = cv2.findHomography(corners, target_mm, 0)
    residual = cv2.perspectiveTransform(corners.reshape(-1, 1, 2), homography).reshape(-1, 2) - target_mm
    rms = float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))
    return PlaneCalibration(homography, rms, calibration_id, date or _dt.date.today().isoformat())


class LaserSpotCamera:
    """A camera looking at a target plane, reporting the laser spot position in mm.

    Parameters
    ----------
    grab : callable
        Returns one frame (ndarray) taken after the robot came to rest; wrap ``cv2.VideoCapture`` as
        ``lambda: cap.read()[1]``, or use :func:`bench.rigs.camera.video_grab`, which drops a queued stale frame.
    calibration : PlaneCalibration
        Pixel -> mm map of the plane; its id travels with every reading.
    grab_next : callable, optional
        Returns the frame after the one just read (a series of frames at one rest); default ``grab``.
    """

    def __init__(
        self,
        grab: Callable[[], np.ndarray],
        calibration: PlaneCalibration,
        *,
        name: str = "camera",
        grab_next: Callable[[], np.ndarray] | None = None,
        **detect_options: float,
    ) -> None:
        self.name = name
        self._grab = grab
        self._grab_next = grab_next or grab
        self.calibration = calibration
        self.detect_options = detect_options
        self._last_frame_digest: bytes | None = None

    def settings(self) -> dict[str, object]:
        """What a run manifest stores about this camera: detection options and the plane calibration."""
        return {
            "sensor": "camera laser spot",
            "name": self.name,
            "detect_options": dict(self.detect_options),
            "calibration": self.calibration.to_dict(),
        }

    def read(self, *, next_frame: bool = False) -> Reading:
        """Grab a frame, detect the spot, and return its plane position (mm); raw holds the pixels. ``next_frame``:
        the frame after the one just read (``grab_next``), for a series at one rest."""
        frame = self._grab_next() if next_frame else self._grab()
        t_mono, t_wall = now()
        # a camera's read noise makes every frame differ somewhere; the same bytes again are a frozen camera or
        # driver handing back its last buffer, and the spot in it is stale
        digest = hashlib.blake2b(np.ascontiguousarray(frame).tobytes(), digest_size=16).digest()
        if digest == self._last_frame_digest:
            raise SensorStalled(
                f"{self.name}: this frame is identical to the previous one, bit for bit (a frozen "
                "camera or driver); the reading is refused; check the camera, then resume the run"
            )
        self._last_frame_digest = digest
        spot = detect_spot(frame, source=self.name, **self.detect_options)
        x_mm, y_mm = self.calibration.pixel_to_mm(np.array([spot.u_px, spot.v_px]))
        return Reading(
            (float(x_mm), float(y_mm)),
            "mm",
            t_mono,
            t_wall,
            raw=(spot.u_px, spot.v_px),
            calibration_id=self.calibration.calibration_id,
            source=self.name,
            note=f"contrast={spot.contrast:.0f} area_px={spot.area_px}",
        )
