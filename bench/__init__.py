"""bench: test-bench data acquisition and metrology for low-cost parallel robots.

Layers, with imports flowing one way only::

    bench.cli / bench.commands  ->  bench.protocols  ->  bench.robots, bench.sensors, bench.store  ->  motion
    bench.reports reads bench.store (never hardware)

Units at every public boundary are mm and degrees; every column name carries its unit (``x_mm``).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("bench")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
