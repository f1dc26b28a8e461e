"""Timing helper shared by the benchmark scripts (run them as ``python benchmarks/bench_<robot>.py``)."""

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
