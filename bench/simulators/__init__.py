"""bench.simulators: pretend hardware. Pseudo-terminal controllers that speak the real wire protocols, the plant and
its error model and dynamics, and simulated sensors.

Production packages (protocols, rigs, robots, sensors, store, metrology, reports, gui) never import this package
(an import-linter contract in ``.ci/run``); only the command line's ``--sim`` and the tests do.
"""
