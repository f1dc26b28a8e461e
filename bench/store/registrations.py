"""The registrations of a run's relative instruments, as the run stores them (its settings' ``registrations``, one
per segment: the start and every resume; made by :mod:`bench.rigs.registration`, filed by the runner).

A sample belongs to the last registration filed before it. "Before" is read on the run's own monotonic time,
never on a wall clock: a registration filed on a resume records ``after_t_s``, the largest ``t_s`` of the run's
samples stored until then (:meth:`bench.store.database.Store.add_registration`), and the resumed segment's samples
continue from there (the runner's ``t_s`` is ``time.monotonic`` seconds after the stored maximum), so a sample
belongs to the last registration whose ``after_t_s`` is below its ``t_s`` (the first registration, filed before any
sample, has none). A wall clock set 2 h back on resume, or stepped back mid-segment, relabels nothing. Runs stored
before ``after_t_s`` was recorded are read as before, by the registration's ``utc`` against the sample's
``wall_utc``.

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


def registration_of(wall_utc: str, entries: Sequence[Mapping[str, Any]], t_s: float | None = None) -> int | None:
    """The segment number of the registration in force when the sample at run time ``t_s`` (stored at ``wall_utc``)
    was taken (None: none). By ``t_s`` when every later registration records ``after_t_s``, else by wall clock."""
    if t_s is not None and entries and all("after_t_s" in e for e in entries[1:]):
        segments = [e["segment"] for e in entries if float(e.get("after_t_s", float("-inf"))) < t_s]
        return max(segments) if segments else None
    stored = datetime.fromisoformat(wall_utc)
    segments = [e["segment"] for e in entries if datetime.fromisoformat(e["utc"]) <= stored]
    return max(segments) if segments else None


def registration_u_mm(entries: Sequence[Mapping[str, Any]]) -> float:
    """The registration term of the AP budget per axis, mm: the largest ``u_mm`` of the run (0 without any)."""
    return max((float(e["u_mm"]) for e in entries), default=0.0)
