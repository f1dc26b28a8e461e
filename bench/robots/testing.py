"""Byte-exact driver tests: a scripted port that checks every write and serves the scripted replies.

Modelled on PyMeasure's ``expected_protocol``: the port, never the driver, is scripted. Each pair is
``(command, reply)`` with terminators (and, for the PKM5 protocol, checksums) left out; ``frame`` adds them. A reply
may be ``None`` (the device stays silent) or a list of replies sent one after another. Writes that differ from the
script fail at once; pairs left unused fail when the block ends.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

__all__ = ["ScriptedPort", "expected_exchange"]

Reply = bytes | str | None | Sequence[bytes | str]


def _as_bytes(value: bytes | str) -> bytes:
    return value.encode("ascii") if isinstance(value, str) else value


class ScriptedPort:
    """A stand-in for an open pyserial port that follows a script of (command, reply) pairs."""

    def __init__(
        self,
        pairs: Sequence[tuple[bytes | str, Reply]],
        frame: Callable[[str], bytes] | None = None,
        *,
        name: str = "scripted://",
    ) -> None:
        self._frame = frame or (lambda body: body.encode("ascii"))
        self._script = [(self._framed(cmd), reply) for cmd, reply in pairs]
        self._written = b""
        self._readable = bytearray()
        self.port = name
        self.baudrate = 115200
        self.timeout: float | None = None
        self.is_open = True

    def _framed(self, value: bytes | str) -> bytes:
        return value if isinstance(value, bytes) else self._frame(value)

    @property
    def unused(self) -> list[tuple[bytes, Reply]]:
        return list(self._script)

    def write(self, data: bytes) -> int:
        self._written += bytes(data)
        while self._written:
            if not self._script:
                raise AssertionError(f"unexpected write {self._written!r}: the script is exhausted")
            command, reply = self._script[0]
            if not command.startswith(self._written[: len(command)]):
                raise AssertionError(f"wrote {self._written!r}, expected {command!r}")
            if len(self._written) < len(command):
                break
            self._written = self._written[len(command) :]
            self._script.pop(0)
            replies = [] if reply is None else [reply] if isinstance(reply, (bytes, str)) else list(reply)
            for item in replies:
                self._readable += self._framed(item)
        return len(data)

    def flush(self) -> None:
        pass

    @property
    def in_waiting(self) -> int:
        return len(self._readable)

    def read(self, size: int = 1) -> bytes:
        if not self._readable:
            time.sleep(min(self.timeout or 0.0, 0.005))
            return b""
        chunk = bytes(self._readable[:size])
        del self._readable[:size]
        return chunk

    def reset_input_buffer(self) -> None:
        self._readable.clear()

    def close(self) -> None:
        self.is_open = False


@contextlib.contextmanager
def expected_exchange(
    driver_cls: Callable[..., Any],
    pairs: Sequence[tuple[bytes | str, Reply]],
    *,
    frame: Callable[[str], bytes] | None = None,
    **driver_kwargs: Any,
) -> Iterator[Any]:
    """Yield ``driver_cls(port, **driver_kwargs)`` on a :class:`ScriptedPort`; fail if pairs remain unused."""
    port = ScriptedPort(pairs, frame)
    yield driver_cls(port, **driver_kwargs)
    if port.unused:
        raise AssertionError(f"script pairs never used: {port.unused!r}")
