"""Timing helper shared by the benchmark scripts (run them as ``python benchmarks/bench_<robot>.py``)."""

import os
import time

import numpy as np


def timed(function, *args, repeat: int = 3, **kwargs):
    """Best wall time of ``repeat`` calls and the last result."""
    best, result = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function(*args, **kwargs)
        best = min(best, time.perf_counter() - start)
    return best, result


def spread(function, *args, repeat: int = 5, **kwargs):
    """Wall times of ``repeat`` calls (a list, in call order) and the last result."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function(*args, **kwargs)
        times.append(time.perf_counter() - start)
    return times, result


def min_median_max(times) -> str:
    """``min / median / max`` of a list of seconds, for one printed line."""
    return f"min {min(times):.3f} s, median {float(np.median(times)):.3f} s, max {max(times):.3f} s"


def copy_bandwidths_bytes_s(megabytes: int = 256, repeat: int = 5) -> list[float]:
    """Memory bandwidth of this machine as numpy sees it, once per ``repeat``: bytes read + written per second by
    ``np.copyto`` of a ``megabytes`` array, the floor any streaming array computation is measured against."""
    source = np.ones(megabytes * 2**20 // 8)
    target = np.empty_like(source)
    return [2 * source.nbytes / seconds for seconds in spread(np.copyto, target, source, repeat=repeat)[0]]


def nbytes_of(result) -> int:
    """Bytes of the arrays a result holds (its dataclass fields), i.e. what a solver must at least write."""
    fields = getattr(result, "__dataclass_fields__", {})
    return sum(getattr(result, name).nbytes for name in fields if isinstance(getattr(result, name), np.ndarray))


def load_line(started: tuple[float, float, float]) -> str:
    """The machine's load during a run: the 1-minute load average at its start (``os.getloadavg()`` taken then)
    and now, on this many CPUs (the figures of a shared machine mean little without it)."""
    return f"load average {started[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, on {os.cpu_count()} CPUs"
