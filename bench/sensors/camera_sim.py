"""Synthetic camera images with known geometry: a laser spot at a known sub-pixel position, and a chessboard
target seen through a known plane-to-image homography. Used by tests and by simulated campaigns, where the spot
position comes from the true end-effector position.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erf

__all__ = ["render_spot", "render_chessboard", "apply_homography"]


def apply_homography(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map points (N, 2) through a 3x3 homography, returning (N, 2)."""
    points = np.atleast_2d(np.asarray(points, float))
    mapped = np.column_stack([points, np.ones(len(points))]) @ np.asarray(homography, float).T
    return mapped[:, :2] / mapped[:, 2:3]


def _pixel_integral(edges_lo: np.ndarray, centre: float, sigma: float) -> np.ndarray:
    scale = 1.0 / (math.sqrt(2.0) * sigma)
    return 0.5 * (erf((edges_lo + 1.0 - centre) * scale) - erf((edges_lo - centre) * scale))


def render_spot(shape: tuple[int, int], centre_px: tuple[float, float], *, sigma_px: float = 2.0,
                peak: float = 180.0, background: float = 20.0, noise_sigma: float = 0.0,
                rng: np.random.Generator | None = None) -> np.ndarray:
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
    gain = peak * 2.0 * math.pi * sigma_px ** 2
    profile_u = _pixel_integral(np.arange(cols) - 0.5, u, sigma_px)
    profile_v = _pixel_integral(np.arange(rows) - 0.5, v, sigma_px)
    image = background + gain * np.outer(profile_v, profile_u)
    if noise_sigma > 0:
        image = image + (rng or np.random.default_rng(0)).normal(0.0, noise_sigma, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def render_chessboard(shape: tuple[int, int], pattern_size: tuple[int, int], square_mm: float,
                      homography_mm_to_px: np.ndarray, *, supersample: int = 4) -> np.ndarray:
    """An 8-bit image of a chessboard target lying in a plane, seen through ``homography_mm_to_px``.

    The target frame has its origin at the first inner corner, x along the ``pattern_size[0]`` inner corners and y
    along the ``pattern_size[1]`` ones; squares extend one square beyond the inner corners, and the surround is
    white. Pixels are anti-aliased by averaging ``supersample``^2 sub-samples.
    """
    rows, cols = shape
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    sub_u = (np.arange(cols)[:, None] + offsets).ravel()
    sub_v = (np.arange(rows)[:, None] + offsets).ravel()
    grid_v, grid_u = np.meshgrid(sub_v, sub_u, indexing="ij")
    mm = apply_homography(np.linalg.inv(homography_mm_to_px), np.column_stack([grid_u.ravel(), grid_v.ravel()]))
    ix, iy = np.floor(mm[:, 0] / square_mm), np.floor(mm[:, 1] / square_mm)
    inside = (ix >= -1) & (ix < pattern_size[0]) & (iy >= -1) & (iy < pattern_size[1])
    black = inside & ((ix + iy) % 2 == 0)
    values = np.where(black, 30.0, 225.0).reshape(rows, supersample, cols, supersample)
    return np.rint(values.mean(axis=(1, 3))).astype(np.uint8)
