"""Keyboard-wedge callipers: interfaces that type the reading followed by Enter (``sensors.md`` §6.4).

:class:`WedgeDecoder` turns key symbols into readings and needs no display, so it is tested directly;
:class:`WedgeListener` feeds it from a pynput keyboard listener, imported only when a listener starts (there is no
display on a build machine). On Linux, prefer grabbing the wedge's own evdev keyboard device.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any, Self

from bench.errors import LinkError
from bench.sensors.calliper import parse_length
from bench.sensors.reading import MalformedSample, Reading, now

__all__ = ["WedgeDecoder", "WedgeListener", "key_symbol"]

logger = logging.getLogger(__name__)

_ACCEPTED = set("0123456789+-.,") | set("mMiInN\"")
_END_KEYS = {"enter", "tab"}


class WedgeDecoder:
    """Collect typed characters; on Enter (or Tab) turn them into a reading.

    Parameters
    ----------
    on_reading : callable
        Called with each :class:`Reading` (value in mm, raw = the typed text).
    on_reject : callable
        Called with a ``MalformedSample`` for text that is not a length; it is logged, never silently dropped.
    stale_after_s : float
        A wedge types a whole reading within milliseconds; characters older than this are discarded as stray
        keyboard input before the next one is added.
    clock : callable
        Monotonic clock (injected in tests).
    """

    def __init__(self, on_reading: Callable[[Reading], None], *, on_reject: Callable[[MalformedSample], None] | None = None,
                 name: str = "wedge", stale_after_s: float = 1.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self.on_reading = on_reading
        self.on_reject = on_reject or (lambda exc: logger.warning("%s", exc))
        self.stale_after_s = stale_after_s
        self._clock = clock
        self._typed: list[str] = []
        self._last_key_s = -float("inf")

    def feed(self, symbol: str) -> Reading | None:
        """Feed one key symbol (a character, ``"enter"``, ``"tab"`` or another key name)."""
        t = self._clock()
        if t - self._last_key_s > self.stale_after_s:
            self._typed.clear()
        self._last_key_s = t
        if symbol in _END_KEYS:
            return self._finish()
        if symbol == "space":
            symbol = " "
        if symbol == "backspace":
            if self._typed:
                self._typed.pop()
        elif len(symbol) == 1 and (symbol in _ACCEPTED or symbol == " "):
            self._typed.append(symbol)
        else:
            self._typed.append(f"<{symbol}>")   # keeps the bad key so the reading is rejected, not mangled
        return None

    def _finish(self) -> Reading | None:
        text, self._typed = "".join(self._typed), []
        if not text.strip():
            return None
        try:
            value = parse_length(text, source=self.name)
        except MalformedSample as exc:
            self.on_reject(exc)
            return None
        t_mono, t_wall = now()
        reading = Reading(value, "mm", t_mono, t_wall, raw=text, source=self.name)
        self.on_reading(reading)
        return reading


def key_symbol(key: Any) -> str:
    """Name of a pynput key: its character for ``KeyCode`` objects, the key's name (``"enter"``) otherwise."""
    char = getattr(key, "char", None)
    if char:
        return char
    name = getattr(key, "name", None)
    return name or str(key)


class WedgeListener:
    """A pynput keyboard listener feeding a :class:`WedgeDecoder`; start with a visible "armed" state.

    Readings arrive in the listener's thread through the decoder's ``on_reading``.
    """

    def __init__(self, decoder: WedgeDecoder) -> None:
        self.decoder = decoder
        self._listener: Any = None

    def start(self) -> None:
        try:
            from pynput import (
                keyboard,  # imported here: pynput needs a display or uinput at import time
            )
        except ImportError as exc:  # pynput's backends refuse to import without a display
            raise LinkError(f"{self.decoder.name}: cannot start a keyboard listener ({exc}); run on a desktop "
                            "session, or read the wedge's evdev keyboard device instead") from None
        self._listener = keyboard.Listener(on_press=lambda key: self.decoder.feed(key_symbol(key)))
        self._listener.start()
        logger.warning("%s armed: keystrokes typed now are taken as calliper readings", self.decoder.name)

    def stop(self) -> None:
        if self._listener is not None:
            self._listener.stop()
            self._listener = None

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
