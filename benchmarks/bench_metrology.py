"""Timing of the metrology core on a full ISO 9283 campaign and on a 10^6-sample stream (one run, one machine).

The ISO pose analysis covers 5 poses x 30 cycles x 3 velocities x 2 loads (900 rows) through the tidy-table
interface, uncertainties included; AD/RD pairs 10^6 cycles; drift cuts a 10^6-sample stream into 60 windows.
Target: the whole set under 1 s on a 2-core machine. Prints each stage's best-of-3 time and its share of the
target.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from _timing import timed

from bench.metrology import distance_characteristics, pose_drift
from bench.metrology.tables import analyze_poses, pose_table

TARGET_S = 1.0


def campaign_table(rng: np.random.Generator) -> pd.DataFrame:
    centre, half = np.array([150.0, 0.0, 300.0]), 40.0
    signs = {"P1": (0, 0, 0), "P2": (-1, -1, -1), "P3": (-1, 1, -1), "P4": (1, 1, 1), "P5": (1, -1, 1)}
    rows = []
    for velocity in (100, 50, 10):
        for load in (1.0, 0.1):
            for cycle in range(1, 31):
                for pose, sign in signs.items():
                    command = centre + half * np.array(sign)
                    attained = command + rng.normal(0.05, 0.03, 3)
                    rows.append((pose, cycle, *command, *attained, velocity, load))
    columns = ["pose", "cycle", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "x_mm", "y_mm", "z_mm", "velocity_pct", "load_kg"]
    return pd.DataFrame(rows, columns=columns)


def report(label: str, function) -> float:
    elapsed, _ = timed(function)
    print(f"{label:<55} {elapsed * 1000:8.1f} ms  ({elapsed / TARGET_S:5.1%} of the 1 s target)")
    return elapsed


def main() -> None:
    rng = np.random.default_rng(0)
    table = campaign_table(rng)
    n = 1_000_000
    first = rng.normal(0, 0.02, (n, 3))
    second = first + [100.0, 0, 0] + rng.normal(0, 0.02, (n, 3))
    t = np.sort(rng.uniform(0, 8 * 3600, n))
    stream = rng.normal(0, 0.02, (n, 3)) + (t / 28800)[:, None] * [0.1, 0, 0]
    total = 0.0
    total += report(
        "ISO pose analysis, 30 groups x 30 cycles (+U, bootstrap)", lambda: analyze_poses(pose_table(table))
    )
    total += report(
        "AD/RD over 10^6 paired cycles", lambda: distance_characteristics(first, second, [0, 0, 0], [100, 0, 0])
    )
    total += report(
        "drift over a 10^6-sample stream, 60 windows", lambda: pose_drift(t, stream, [0, 0, 0], window_s=480)
    )
    print(f"{'total':<55} {total * 1000:8.1f} ms  ratio to target {total / TARGET_S:.2f}")


if __name__ == "__main__":
    main()
