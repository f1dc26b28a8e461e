"""Start guesses of the pkm5 FK solvers (numpy's ``motion.pkm5.fk`` and the compiled ``motion.pkm5.compiled``):
one home for both, so neither imports the other to share them."""

#: Mode name -> start poses (x, y, z mm[, angle rad]) tried in turn for solutions whose residual stays above
#: tolerance. The beta local minima sit at large positive beta and low x (pkm5.md §4.3); (80, 0, 320, 0.4 rad) solved
#: all 25 such cases among 12,567 random feasible beta poses.
RESTARTS: dict[str, list[tuple[float, ...]]] = {
    "translation": [(150.0, 0.0, 300.0), (120.0, 0.0, 320.0)],
    "alpha": [(111.31, 0.0, 300.0, 0.0), (111.31, 0.0, 300.0, 0.4), (111.31, 0.0, 300.0, -0.4)],
    "beta": [(80.0, 0.0, 320.0, 0.4), (150.0, 0.0, 300.0, 0.0), (120.0, 0.0, 320.0, 0.4), (150.0, 0.0, 300.0, -0.4)],
}
