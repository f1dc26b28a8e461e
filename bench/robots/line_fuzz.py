"""Random corruption of PKM5 wire lines, for the link-check fuzz test and benchmark (docs/protocol-pkm5.md, v2).

A corrupted frame is the line (terminator removed) with 1-3 random bit flips anywhere in it, or a burst of 1-16
consecutive bits overwritten with random values; the corruption always changes the line. CRC-16-CCITT detects every
pattern of up to 3 bit errors and every burst up to 16 bits in the bits it covers (Koopman & Chakravarty 2004); a flip in
the hex digits changes the claimed CRC or makes it unreadable, so no corrupted version-2 frame should be accepted.
"""

from __future__ import annotations

import numpy as np

from bench.robots import pkm5_wire as wire
from bench.robots.link import WireProtocolError

__all__ = ["accepted_count", "corrupt", "random_bodies"]


def corrupt(line: bytes, rng: np.random.Generator, *, max_flips: int = 3) -> bytes:
    """``line`` with random bit flips (1-``max_flips``) or one random burst of up to 16 bits; never unchanged."""
    bits = np.unpackbits(np.frombuffer(line, dtype=np.uint8))
    if rng.random() < 0.5:
        where = rng.choice(len(bits), size=int(rng.integers(1, max_flips + 1)), replace=False)
        bits[where] ^= 1
    else:
        length = int(rng.integers(1, 17))
        start = int(rng.integers(0, len(bits) - length + 1))
        original = bits[start : start + length].copy()
        while np.array_equal(bits[start : start + length], original):
            bits[start : start + length] = rng.integers(0, 2, length)
    return np.packbits(bits).tobytes()


def random_bodies(rng: np.random.Generator, count: int) -> list[str]:
    """Typical command and reply bodies with random numbers (MOVE, POS replies, DONE, ERR)."""
    bodies = []
    for _ in range(count):
        steps = " ".join(str(int(s)) for s in rng.integers(0, 21121, 6))
        tag = int(rng.integers(0, 10**9))
        kind = int(rng.integers(4))
        bodies.append(
            [
                f"MOVE {steps} {int(rng.integers(1, 1001))} #{tag}",
                f"OK #{tag} POS {steps} MOVING",
                f"DONE #{tag} {steps}",
                f"ERR #{tag} 8 STOPPED {steps}",
            ][kind]
        )
    return bodies


def accepted_count(count: int, version: int, seed: int = 0, *, max_flips: int = 3) -> int:
    """How many of ``count`` randomly corrupted frames of protocol ``version`` still decode."""
    rng = np.random.default_rng(seed)
    accepted = 0
    for body in random_bodies(rng, count):
        frame = wire.encode_line(body, version)[:-1]
        try:
            wire.decode_line(corrupt(frame, rng, max_flips=max_flips), version)
        except WireProtocolError:
            continue
        accepted += 1
    return accepted
