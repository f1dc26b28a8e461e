"""bench.simulators: pretend hardware. Pseudo-terminal controllers that speak the real wire protocols, the plant and
its error model and dynamics, and simulated sensors.

Production packages (protocols, rigs, robots, sensors, store, metrology, reports, gui) never import this package
(an import-linter contract in ``.ci/run``); only the command line's ``--sim`` and the tests do.
"""

#: Simulated time runs this much faster than real moves in simulated runs unless told otherwise.
DEFAULT_SPEED_FACTOR = 10000.0
