"""bench.rigs: what a run does its steps with. The interfaces (Mover, Instrument, Operator, Rig), the movers for
each robot, the instruments (mice, laser grid, gauges, camera), the operators, and the builder that makes a rig from
a station file."""
