"""Synthetic camera images with known geometry: a laser spot at a known sub-pixel position, and a chessboard
target seen through a known plane-to-image homography. Used by tests and by simulated campaigns, where the spot
position comes from the true end-effector position.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["SpotCameraSimulator", "apply_homography", "render_chessboard", "render_spot"]


def apply_homography(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map points (N, 2) through a 3x3 homography, returning (N, 2)."""
    points = np.atleast_2d(np.asarray(points, float))
    mapped = np.column_stack([points, np.ones(len(points))]) @ np.asarray(homography, float).T
    return mapped[:, :2] / mapped[:, 2:3]


def _erf(x: np.ndarray) -> np.ndarray:
    """The error function of each of ``x``, by ``math.erf``: a frame needs a few thousand, and importing
    ``scipy.special`` for them cost every camera simulator 0.3 s of CPU at its start (the two agree to 1 ulp; 400
    random frames rendered with either were the same)."""
    return np.fromiter(map(math.erf, x.ravel()), dtype=float, count=x.size).reshape(x.shape)


def _pixel_integral(edges_lo: np.ndarray, centre: float, sigma: float) -> np.ndarray:
    scale = 1.0 / (math.sqrt(2.0) * sigma)
    return 0.5 * (_erf((edges_lo + 1.0 - centre) * scale) - _erf((edges_lo - centre) * scale))


def render_spot(
    shape: tuple[int, int],
    centre_px: tuple[float, float],
    *,
    sigma_px: float = 2.0,
    peak: float = 180.0,
    background: float = 20.0,
    noise_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """An 8-bit grey image of a Gaussian laser spot.

    Each pixel holds the integral of the Gaussian over its area (so the true centroid is exact, not sampled),
    plus a uniform background and Gaussian read noise, rounded and clipped to 0..255.

    Parameters
    ----------
    shape : (rows, cols)
        Image size in pixels.
    centre_px : (u, v)
        Spot centre in pixel coordinates, u to the right (column), v down (row); pixel (0, 0) covers
        [-0.5, 0.5] x [-0.5, 0.5].
    sigma_px : float
        Spot radius (standard deviation), px; includes defocus blur.
    peak, background, noise_sigma : float
        Grey levels.
    """
    rows, cols = shape
    u, v = centre_px
    # 2*pi*sigma^2 turns the per-pixel integrals back into a spot whose centre pixel reads about ``peak``
    gain = peak * 2.0 * math.pi * sigma_px**2
    profile_u = _pixel_integral(np.arange(cols) - 0.5, u, sigma_px)
    profile_v = _pixel_integral(np.arange(rows) - 0.5, v, sigma_px)
    # the noise array is the image: rng.normal(0, s) draws s x the same standard normals, so the frame is the same
    # to the bit while no temporary frames are allocated (the noise of a 680 x 680 frame is most of its time)
    if noise_sigma > 0:
        image = (rng or np.random.default_rng(0)).standard_normal((rows, cols))
        image *= noise_sigma
    else:
        image = np.zeros((rows, cols))
    image += background + gain * np.outer(profile_v, profile_u)
    np.rint(image, out=image)
    np.clip(image, 0, 255, out=image)
    return image.astype(np.uint8)


def render_chessboard(
    shape: tuple[int, int],
    pattern_size: tuple[int, int],
    square_mm: float,
    homography_mm_to_px: np.ndarray,
    *,
    supersample: int = 4,
) -> np.ndarray:
    """An 8-bit image of a chessboard target lying in a plane, seen through ``homography_mm_to_px``.

    The target frame has its origin at the first inner corner, x along the ``pattern_size[0]`` inner corners and y
    along the ``pattern_size[1]`` ones; squares extend one square beyond the inner corners, and the surround is
    white. Pixels are anti-aliased by averaging ``supersample``^2 sub-samples.
    """
    rows, cols = shape
    image = np.full((rows, cols), 225, dtype=np.uint8)
    # only the pixels of the board's bounding box are sampled: the surround is white (a projective image of the
    # board's outline is the quadrilateral of its mapped corners, inside their bounding box)
    outline = (
        np.array(
            [[-1, -1], [pattern_size[0], -1], [pattern_size[0], pattern_size[1]], [-1, pattern_size[1]]], dtype=float
        )
        * square_mm
    )
    corners_px = apply_homography(homography_mm_to_px, outline)
    u0, v0 = np.maximum(np.floor(corners_px.min(axis=0)).astype(int) - 2, 0)
    u1, v1 = np.minimum(np.ceil(corners_px.max(axis=0)).astype(int) + 3, (cols, rows))
    if u0 >= u1 or v0 >= v1:
        return image
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    sub_u = (np.arange(u0, u1)[:, None] + offsets).ravel()[None, :]
    sub_v = (np.arange(v0, v1)[:, None] + offsets).ravel()[:, None]
    # every sub-sample's plane position: the pixel -> mm homography broadcast over the sub-sample rows and columns
    # (a matrix product of 10^7 rows of [u, v, 1] took 1-2 s of CPU; the same board, classified sample by sample)
    to_mm = np.linalg.inv(homography_mm_to_px)
    w = to_mm[2, 0] * sub_u + to_mm[2, 1] * sub_v + to_mm[2, 2]
    ix = np.floor((to_mm[0, 0] * sub_u + to_mm[0, 1] * sub_v + to_mm[0, 2]) / w / square_mm)
    iy = np.floor((to_mm[1, 0] * sub_u + to_mm[1, 1] * sub_v + to_mm[1, 2]) / w / square_mm)
    inside = (ix >= -1) & (ix < pattern_size[0]) & (iy >= -1) & (iy < pattern_size[1])
    black = inside & ((ix + iy) % 2 == 0)
    values = np.where(black, 30.0, 225.0).reshape(v1 - v0, supersample, u1 - u0, supersample)
    image[v0:v1, u0:u1] = np.rint(values.mean(axis=(1, 3))).astype(np.uint8)
    return image


@dataclass(frozen=True, eq=False)
class SpotCameraSimulator:
    """A camera watching a laser spot on a plane: true plane position (mm) -> 8-bit frame.

    Parameters
    ----------
    homography_mm_to_px : ndarray, shape (3, 3)
        Plane-to-image map of the simulated camera (the truth a chessboard calibration should recover).
    shape : (rows, cols)
        Frame size in pixels.
    sigma_px, peak, background, noise_sigma : float
        Spot and sensor model of :func:`render_spot`.
    seed : int
        Seed of the read noise; successive frames draw fresh noise.
    """

    homography_mm_to_px: np.ndarray
    shape: tuple[int, int] = (480, 640)
    sigma_px: float = 2.5
    peak: float = 170.0
    background: float = 20.0
    noise_sigma: float = 3.0
    seed: int = 0

    def frame(self, xy_mm: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        """The frame showing the spot at plane position ``xy_mm`` (2,)."""
        u, v = apply_homography(self.homography_mm_to_px, np.asarray(xy_mm, float))[0]
        return render_spot(
            self.shape,
            (u, v),
            sigma_px=self.sigma_px,
            peak=self.peak,
            background=self.background,
            noise_sigma=self.noise_sigma,
            rng=rng or np.random.default_rng(self.seed),
        )

    def frame_source(self, true_xy_mm: Callable[[], np.ndarray]) -> Callable[[], np.ndarray]:
        """A ``grab`` callable for :class:`~bench.sensors.camera_spot.LaserSpotCamera` observing a true position."""
        rng = np.random.default_rng(self.seed)
        return lambda: self.frame(true_xy_mm(), rng)

    def chessboard(self, pattern_size: tuple[int, int] = (9, 6), square_mm: float = 10.0) -> np.ndarray:
        """The calibration target as this camera sees it (target frame = plane frame)."""
        return render_chessboard(self.shape, pattern_size, square_mm, self.homography_mm_to_px)
