"""bench: test-bench data acquisition and metrology for low-cost parallel robots.

Layers, with imports flowing one way only::

    bench.cli / bench.commands  ->  bench.protocols  ->  bench.robots, bench.sensors, bench.store  ->  motion
    bench.reports reads bench.store (never hardware)

Units at every public boundary are mm and degrees; every column name carries its unit (``x_mm``).
"""


def __getattr__(name: str) -> str:
    """``bench.__version__``, read from the installed metadata on first use (importlib.metadata costs ~40 ms, and
    ``bench --help`` should not pay it)."""
    if name != "__version__":
        raise AttributeError(f"module 'bench' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        value = version("bench")
    except PackageNotFoundError:  # running from a source tree that was never installed
        value = "0.0.0+unknown"
    globals()["__version__"] = value
    return value
