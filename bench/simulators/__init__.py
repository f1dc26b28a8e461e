"""bench.simulators: pretend hardware. Pseudo-terminal controllers that speak the real wire protocols, the plant and
its error model and dynamics, and simulated sensors.

Production packages (protocols, rigs, robots, sensors, store, metrology, reports, gui) never import this package
(an import-linter contract in ``.ci/run``); only the command line's ``--sim`` and the tests do.
"""

#: Simulated time runs this much faster than real moves in simulated runs unless told otherwise.
DEFAULT_SPEED_FACTOR = 10000.0
#: How long a simulator started for a timed campaign (``bench demo``, ``benchmarks/bench_demo_floor.py``) waits for
#: its compiled kernel before it serves its port (``--kernel-wait-s``): 1-2 s from numba's cache, which its first
#: moves would otherwise wait for one by one; bounded, since a fresh install compiles for 10-20 s.
CAMPAIGN_KERNEL_WAIT_S = 6.0
