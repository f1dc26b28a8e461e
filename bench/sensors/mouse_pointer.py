"""The dissertation's mouse method, kept only for parity: the OS pointer position sampled at a fixed rate
(MATLAB ``get(0,'PointerLocation')`` every 0.1 s, ``sensors.md`` §2) through pynput.

Pointer acceleration, OS speed gain, normalisation and clamping at the screen edges make this unfit for metrology
(``sensors.md`` §3): every use logs a loud warning and every reading says so; reports must list it as a method
deviation. pynput is imported only when a sampler without an injected position source is created, since it needs
a display.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable, Iterator

from bench.errors import ConfigError, LinkError
from bench.sensors.reading import Reading, now

__all__ = ["UNFIT_FOR_METROLOGY", "PointerMethodWarning", "PointerSampler"]

logger = logging.getLogger(__name__)

UNFIT_FOR_METROLOGY = (
    "OS-pointer mouse method (dissertation parity): pointer acceleration, speed gain and "
    "screen-edge clamping make it unfit for metrology; use raw counts (evdev or MCU)"
)


class PointerMethodWarning(UserWarning):
    """Raised as a warning whenever the OS-pointer method is used."""


def _pynput_position() -> Callable[[], tuple[float, float]]:
    from bench.extras import ensure_installed

    ensure_installed("pynput")
    try:
        from pynput import mouse  # needs a display at import time
    except ImportError as exc:  # pynput's backends refuse to import without a display
        raise LinkError(
            f"pointer sampler: cannot use pynput ({exc}); the OS-pointer method needs a desktop "
            "session. Read raw counts from /dev/input instead"
        ) from None
    controller = mouse.Controller()
    return lambda: tuple(controller.position)  # type: ignore[return-value]


class PointerSampler:
    """Pointer position in pixels converted with one mm/pixel factor, as the dissertation did.

    Parameters
    ----------
    mm_per_pixel : float
        The dissertation's 0.2 mm/pixel at pointer speed 4 (Table A.24).
    rate_hz : float
        Sampling rate of :meth:`samples` (10 Hz in App. B.1.9).
    position : callable or None
        Returns the pointer position ``(x_px, y_px)``; ``None`` uses pynput.
    """

    def __init__(
        self,
        *,
        mm_per_pixel: float = 0.2,
        rate_hz: float = 10.0,
        position: Callable[[], tuple[float, float]] | None = None,
        name: str = "pointer",
    ) -> None:
        if not mm_per_pixel > 0 or not rate_hz > 0:
            raise ConfigError(
                f"pointer sampler: mm_per_pixel = {mm_per_pixel!r}, rate_hz = {rate_hz!r}, expected positive numbers"
            )
        warnings.warn(UNFIT_FOR_METROLOGY, PointerMethodWarning, stacklevel=2)
        logger.warning("%s", UNFIT_FOR_METROLOGY)
        self.name = name
        self.mm_per_pixel = mm_per_pixel
        self.rate_hz = rate_hz
        self._position = position or _pynput_position()

    def settings(self) -> dict[str, object]:
        """What a run manifest stores: the method and its deviation from metrology practice."""
        return {
            "sensor": "OS pointer (dissertation parity)",
            "name": self.name,
            "mm_per_pixel": self.mm_per_pixel,
            "rate_hz": self.rate_hz,
            "deviation": UNFIT_FOR_METROLOGY,
        }

    def read(self) -> Reading:
        """Pointer position now, in mm (pixels times the factor); raw holds the pixels."""
        x_px, y_px = self._position()
        t_mono, t_wall = now()
        return Reading(
            (x_px * self.mm_per_pixel, y_px * self.mm_per_pixel),
            "mm",
            t_mono,
            t_wall,
            raw=(int(x_px), int(y_px)),
            calibration_id=f"pointer-{self.mm_per_pixel:g}mm-per-px",
            source=f"{self.name}:os-pointer",
            note=UNFIT_FOR_METROLOGY,
        )

    def samples(self, count: int, *, sleep: Callable[[float], None] = time.sleep) -> Iterator[Reading]:
        """``count`` readings at the fixed rate, on a monotonic schedule (no drift from slow reads)."""
        start = time.monotonic()
        for k in range(count):
            delay = start + k / self.rate_hz - time.monotonic()
            if delay > 0:
                sleep(delay)
            yield self.read()
