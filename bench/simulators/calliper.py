"""Simulated digital calliper: true lengths or a true tilt (mm, deg) -> the text, serial lines or keystrokes a
real calliper would produce, with its resolution, a zero bias and reading noise (``iso9283.md`` §8.2(c)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["CalliperSimulator", "depths_for_tilt", "stand_in"]


def stand_in(station: Any, spec: Any, *, folder: str, truth_path: str) -> tuple[Any, list[str]]:
    """The ``[calliper]`` of a rehearsal: typed, as on hardware; a serial calliper is rehearsed as typed (its
    simulator needs the gauge's position, which only the person at the bench knows)."""
    if spec.kind != "serial":
        return spec, []
    return type(spec)(kind="typed", resolution_mm=spec.resolution_mm), []


@dataclass(frozen=True)
class CalliperSimulator:
    """A calliper reading true lengths.

    Parameters
    ----------
    resolution_mm : float
        Display step (0.01 mm).
    noise_mm : float
        Standard deviation of seating/operator scatter (mm).
    zero_bias_mm : float
        Error of the zero setting (mm), added to every reading.
    seed : int
        Seed of the noise generator.
    """

    resolution_mm: float = 0.01
    noise_mm: float = 0.0
    zero_bias_mm: float = 0.0
    seed: int = 0

    def values(self, true_mm: np.ndarray) -> np.ndarray:
        """Displayed values (mm), shape of ``true_mm``: bias and noise added, then rounded to the resolution."""
        true_mm = np.asarray(true_mm, float)
        noise = np.random.default_rng(self.seed).normal(0.0, self.noise_mm, true_mm.shape) if self.noise_mm else 0.0
        return np.round((true_mm + self.zero_bias_mm + noise) / self.resolution_mm) * self.resolution_mm

    def texts(self, true_mm: np.ndarray) -> list[str]:
        """Readings as the display shows them, e.g. ``"12.34"``."""
        decimals = max(0, round(-np.log10(self.resolution_mm)))
        return [f"{v:.{decimals}f}" for v in np.atleast_1d(self.values(true_mm))]

    def serial_lines(self, true_mm: np.ndarray, *, terminator: bytes = b"\r\n") -> bytes:
        """One line per reading, as a serial calliper interface sends them."""
        return b"".join(text.encode() + terminator for text in self.texts(true_mm))

    def keystrokes(self, true_mm: np.ndarray) -> list[str]:
        """Key symbols a keyboard wedge types: each character of a reading, then ``"enter"``."""
        return [key for text in self.texts(true_mm) for key in (*text, "enter")]

    def wedge_input_events(self, true_mm: np.ndarray, *, t0_s: float = 0.0) -> bytes:
        """The keystrokes as the wedge's keyboard event device delivers them (``input_event`` records)."""
        from bench.sensors.calliper_wedge import encode_keystrokes

        return encode_keystrokes(self.keystrokes(true_mm), t0_s=t0_s)


def depths_for_tilt(tilt_deg: np.ndarray, spacing_mm: float, centre_depth_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """True depths (h1, h2) in mm through two holes ``spacing_mm`` apart over a mirror tilted by ``tilt_deg``,
    centred on ``centre_depth_mm``; the inverse of :func:`bench.sensors.calliper.tilt_deg`."""
    half = 0.5 * spacing_mm * np.tan(np.radians(np.asarray(tilt_deg, float)))
    return centre_depth_mm - half, centre_depth_mm + half
