"""The registrations of a run's relative instruments, as the run stores them (its settings' ``registrations``, one
per segment: the start and every resume; made by :mod:`bench.rigs.registration`, filed by the runner).

A sample belongs to the last registration stored before it (the registration's ``utc`` against the sample's
``wall_utc``): a segment's samples are stored after its registration and before the next one, since one process
owns a run at a time.

What it means for a result: a relative instrument's frame is the robot's home as reached at the registration,
known to the registration's standard uncertainty ``u_mm`` per axis. Every attained position of a segment shares
that frame error, so a pose's mean (AP) carries it fully: :func:`registration_u_mm` is the largest ``u_mm`` of the
run (the conservative bound of a mean over samples of several segments, sum w_k^2 u_k^2 <= max u_k^2 for
weights w_k summing to 1), added to the instrument's term of the AP budget. Within a segment the frame error is
common and cancels from the spread (RP); across segments it adds to it, which the report states rather than models.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime
from typing import Any

__all__ = ["registration_of", "registration_u_mm", "registrations"]


def registrations(settings: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The stored registrations of a run (empty for a run whose instruments need none, or stored before them)."""
    return list(settings.get("registrations") or ())


def registration_of(wall_utc: str, entries: Sequence[Mapping[str, Any]]) -> int | None:
    """The segment number of the registration in force when a sample was stored at ``wall_utc`` (None: none)."""
    stored = datetime.fromisoformat(wall_utc)
    segments = [e["segment"] for e in entries if datetime.fromisoformat(e["utc"]) <= stored]
    return max(segments) if segments else None


def registration_u_mm(entries: Sequence[Mapping[str, Any]]) -> float:
    """The registration term of the AP budget per axis, mm: the largest ``u_mm`` of the run (0 without any)."""
    return max((float(e["u_mm"]) for e in entries), default=0.0)
