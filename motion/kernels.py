"""Shared support of the compiled (numba) kernels of motion/: is numba there, and a thread pool to run them on.

numba is the optional extra ``bench[fast]``; nothing here imports it until :func:`available` is asked. The kernels
are compiled with ``nogil=True``, so chunks of poses run in parallel on plain threads, one per CPU this process may
use; each pose is computed on its own, so the results do not depend on the number of threads.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache

from motion.errors import MotionInputError

__all__ = ["ENGINES", "available", "use_compiled", "run_chunks"]

#: Values of the ``engine`` argument of the kinematics functions that have a compiled kernel.
ENGINES = ("auto", "numpy", "compiled")


@lru_cache(maxsize=1)
def available() -> bool:
    """True if numba imports (the optional ``fast`` extra is installed)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def use_compiled(engine: str, n: int, threshold: int) -> bool:
    """Whether a batch of ``n`` poses runs compiled: 'numpy' never, 'compiled' always (numba required), 'auto'
    from ``threshold`` poses on when numba is installed (the numpy path otherwise)."""
    if engine == "numpy":
        return False
    if engine == "compiled":
        if not available():
            raise MotionInputError(
                "engine = 'compiled' needs numba, which is not installed (pip install 'bench[fast]')"
            )
        return True
    if engine != "auto":
        raise MotionInputError(f"engine = {engine!r}, expected one of {list(ENGINES)}")
    return n >= threshold and available()


@lru_cache(maxsize=1)
def _pool() -> ThreadPoolExecutor | None:
    workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return ThreadPoolExecutor(workers, thread_name_prefix="motion-kernel") if workers > 1 else None


def run_chunks(work: Callable[[slice], object], n: int, chunk: int) -> None:
    """``work(rows)`` for consecutive slices of ``chunk`` rows of ``n``, on the thread pool when there is more than
    one slice (exceptions propagate)."""
    slices = [slice(start, min(start + chunk, n)) for start in range(0, n, chunk)]
    pool = _pool()
    if pool is None or len(slices) < 2:
        for rows in slices:
            work(rows)
    else:
        list(pool.map(work, slices))
