"""Keyboard-wedge callipers: interfaces that type the reading followed by Enter (``sensors.md`` §6.4).

:class:`WedgeDecoder` turns key symbols into readings and needs no display, so it is tested directly. Two ways to
feed it: :class:`EvdevWedge` reads and grabs the wedge's own evdev keyboard device (preferred on Linux: readings
never leak into a window, and the operator's typing never pollutes them), and :class:`WedgeListener` uses a
pynput keyboard listener, imported only when it starts (there is no display on a build machine).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any, Self

import numpy as np

from bench.errors import LinkError
from bench.sensors.calliper import parse_length
from bench.sensors.event_device import EventStream
from bench.sensors.input_event import EV_KEY, EV_SYN, EVENT, EVENT_DTYPE, SYN_REPORT
from bench.sensors.reading import MalformedSample, Reading, now

__all__ = ["US_KEYS", "EvdevWedge", "WedgeDecoder", "WedgeListener", "encode_keystrokes", "key_symbol"]

logger = logging.getLogger(__name__)

_ACCEPTED = set("0123456789+-.,") | set('mMiInN"')
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

    def __init__(
        self,
        on_reading: Callable[[Reading], None],
        *,
        on_reject: Callable[[MalformedSample], None] | None = None,
        name: str = "wedge",
        stale_after_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
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
            self._typed.append(f"<{symbol}>")  # keeps the bad key so the reading is rejected, not mangled
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
        from bench.extras import ensure_installed

        ensure_installed("pynput")
        try:
            from pynput import (
                keyboard,  # imported here: pynput needs a display or uinput at import time
            )
        except ImportError as exc:  # pynput's backends refuse to import without a display
            raise LinkError(
                f"{self.decoder.name}: cannot start a keyboard listener ({exc}); run on a desktop "
                "session, or read the wedge's evdev keyboard device instead"
            ) from None
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


#: Linux key codes (``input-event-codes.h``) -> (symbol, shifted symbol) on the US layout wedges assume.
US_KEYS: dict[int, tuple[str, str]] = {
    **{code: (str(code - 1), "!@#$%^&*("[code - 2]) for code in range(2, 11)},
    11: ("0", ")"),
    12: ("-", "_"),
    13: ("=", "+"),
    14: ("backspace", "backspace"),
    15: ("tab", "tab"),
    23: ("i", "I"),
    28: ("enter", "enter"),
    40: ("'", '"'),
    49: ("n", "N"),
    50: ("m", "M"),
    51: (",", "<"),
    52: (".", ">"),
    57: ("space", "space"),
    71: ("7", "7"),
    72: ("8", "8"),
    73: ("9", "9"),
    74: ("-", "-"),
    75: ("4", "4"),
    76: ("5", "5"),
    77: ("6", "6"),
    78: ("+", "+"),
    79: ("1", "1"),
    80: ("2", "2"),
    81: ("3", "3"),
    82: ("0", "0"),
    83: (".", "."),
    96: ("enter", "enter"),
}
_SHIFT_KEYS = {42, 54}  # KEY_LEFTSHIFT, KEY_RIGHTSHIFT
_KEY_OF_SYMBOL = {
    symbol: (code, shifted)
    for code, pair in sorted(US_KEYS.items(), reverse=True)
    for shifted, symbol in ((True, pair[1]), (False, pair[0]))
}


def encode_keystrokes(symbols: list[str], *, t0_s: float = 0.0, key_interval_s: float = 0.002) -> bytes:
    """Key symbols as a wedge's keyboard device sends them: press and release events (with Shift where the US
    layout needs it), each followed by ``SYN_REPORT``. The inverse of :class:`EvdevWedge` (used by simulators)."""
    records = []
    for k, symbol in enumerate(symbols):
        code, shifted = _KEY_OF_SYMBOL[symbol]
        t = t0_s + k * key_interval_s
        sec, usec = int(t), round((t - int(t)) * 1e6)
        presses = [(42, 1), (code, 1), (code, 0), (42, 0)] if shifted else [(code, 1), (code, 0)]
        for key, value in presses:
            records.append(EVENT.pack(sec, usec, EV_KEY, key, value))
            records.append(EVENT.pack(sec, usec, EV_SYN, SYN_REPORT, 0))
    return b"".join(records)


class EvdevWedge:
    """A keyboard-wedge calliper read from its own event device, grabbed by default.

    Parameters
    ----------
    path : str
        The wedge's keyboard event device (``/dev/input/by-id/usb-<vendor>_<product>-event-kbd``), a FIFO or a file.
    decoder : WedgeDecoder
        Receives the key symbols and emits the readings.
    grab : bool
        Exclusive access (only on real devices): its keystrokes then reach no window.
    layout : dict
        Key code -> (symbol, shifted symbol); the US layout by default, as wedges usually assume.
    """

    def __init__(
        self, path: str, decoder: WedgeDecoder, *, grab: bool = True, layout: dict[int, tuple[str, str]] | None = None
    ) -> None:
        self.name = decoder.name
        self.decoder = decoder
        self.layout = layout or US_KEYS
        self._stream = EventStream(path, kind="calliper wedge", label=decoder.name, grab=grab)
        self._pending = b""
        self._shift = False

    def poll(self, timeout_s: float = 0.0) -> list[Reading]:
        """Wait up to ``timeout_s`` for keystrokes and return the readings completed by them."""
        if timeout_s > 0:
            self._stream.wait(timeout_s)
        buffer = self._pending + b"".join(self._stream.read_available())
        whole = len(buffer) - len(buffer) % EVENT.size
        self._pending = buffer[whole:]
        readings = []
        for event in np.frombuffer(buffer[:whole], EVENT_DTYPE):
            if event["type"] != EV_KEY:
                continue
            code, value = int(event["code"]), int(event["value"])
            if code in _SHIFT_KEYS:
                self._shift = value != 0
            elif value == 1:  # a press; releases (0) and auto-repeats (2) carry no new character
                pair = self.layout.get(code, (f"key{code}", f"key{code}"))
                reading = self.decoder.feed(pair[1] if self._shift else pair[0])
                if reading is not None:
                    readings.append(reading)
        return readings

    def settings(self) -> dict[str, object]:
        """What a run manifest stores about the wedge: its device binding."""
        binding = self._stream.binding
        return {
            "sensor": "keyboard-wedge calliper (evdev)",
            "name": self.name,
            "path": binding.path,
            "device_name": binding.name,
            "is_device": binding.is_device,
        }

    @property
    def exhausted(self) -> bool:
        return self._stream.exhausted

    def close(self) -> None:
        self._stream.close()
