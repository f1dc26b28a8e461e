"""The position series of a streamed capture of the two mice (:mod:`bench.rigs.mice`): from the reports in a window,
the zero-order-hold position of the measuring point at every report time, with the raw data it came from."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["MM_DECIMALS", "S_DECIMALS", "arrival_series", "moved"]

#: Decimals kept in the stored series (0.1 um, 1 us): far below a count (32 um at 800 cpi).
MM_DECIMALS, S_DECIMALS = 4, 6


def moved(frames: Any, since_s: float = -math.inf) -> bool:
    """Whether ``frames`` hold any counts at or after ``since_s``."""
    later = frames.t_s >= since_s
    return bool(np.any(frames.dx[later]) or np.any(frames.dy[later]))


def arrival_series(
    frames: Mapping[str, Any],
    counts_before: Mapping[str, np.ndarray],
    calibration: Any,
    origin_mm: np.ndarray,
    *,
    t_request: float,
    lead_s: float,
    hold_s: float,
) -> tuple[dict[str, list[float]], dict[str, Any]]:
    """Position series of an x-y and an x-z mouse in the window [t_request - lead_s, t_request + hold_s].

    ``frames`` are the mice's reports from the window's start on and ``counts_before`` their counts there. A mouse
    reports only when it moves, so its position holds between reports (zero-order hold). The series is sampled at
    every report time in the window plus the window's two ends; x comes from the x-y mouse, z from the x-z mouse.
    Returns the series (``t_s`` relative to ``t_request``, ``x_mm``, ``y_mm``, ``z_mm``) and the raw data it was
    computed from (the counts at the window start and every report in the window).
    """
    start, end = t_request - lead_s, t_request + hold_s
    times = [np.array([start, end])]
    counts_at_start, reports, count_paths = {}, {}, {}
    for plane, f in frames.items():
        counts_at_start[plane] = np.asarray(counts_before[plane], np.int64)
        cumulative = counts_at_start[plane] + np.cumsum(np.column_stack([f.dx, f.dy]), axis=0)
        inside = f.t_s <= end
        reports[plane] = {
            "t_s": np.round(f.t_s[inside] - t_request, S_DECIMALS).tolist(),
            "dx_counts": f.dx[inside].tolist(),
            "dy_counts": f.dy[inside].tolist(),
        }
        count_paths[plane] = (f.t_s[inside], cumulative[inside], counts_at_start[plane])
        times.append(f.t_s[inside])
    grid = np.unique(np.concatenate(times))
    position = {}
    for plane, (t_reports, cumulative, at_start) in count_paths.items():
        latest = np.searchsorted(t_reports, grid, side="right") - 1
        counts = np.where(
            latest[:, None] >= 0, cumulative[np.maximum(latest, 0)] if len(cumulative) else at_start, at_start
        )
        position[plane] = calibration.counts_to_mm(counts)
    origin = np.asarray(origin_mm, dtype=float)
    relative = np.round(grid - t_request, S_DECIMALS)
    distinct = np.r_[relative[1:] != relative[:-1], True]  # times equal once rounded: the later position holds
    series = {
        "t_s": relative[distinct].tolist(),
        "x_mm": np.round(origin[0] + position["xy"][distinct, 0], MM_DECIMALS).tolist(),
        "y_mm": np.round(origin[1] + position["xy"][distinct, 1], MM_DECIMALS).tolist(),
        "z_mm": np.round(origin[2] + position["xz"][distinct, 1], MM_DECIMALS).tolist(),
    }
    raw = {
        "lead_s": lead_s,
        "hold_s": hold_s,
        "reports": reports,
        "counts_at_start": {plane: [int(c) for c in counts] for plane, counts in counts_at_start.items()},
    }
    return series, raw
