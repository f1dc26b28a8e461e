"""Small stored runs for the report tests, written with the store API (the configuration a pose protocol stores)."""

from __future__ import annotations

import numpy as np

from bench.store import Store

CUBE = {"P1": (110.0, 0.0, 320.0), "P2": (94.0, -16.0, 304.0), "P3": (94.0, 16.0, 304.0),
        "P4": (126.0, 16.0, 336.0), "P5": (126.0, -16.0, 336.0)}
ORDER = ("P1", "P5", "P4", "P3", "P2")


def pose_config(**overrides):
    config = {"protocol": "iso9283_pose", "protocol_version": "1", "robot": "pkm5", "cycles": 10,
              "velocities_pct": [100.0], "loads_kg": [0.0], "cube_centre_mm": [110.0, 0.0, 320.0],
              "cube_side_mm": 40.0, "plane": "x=z", "poses": None, "settle_s": 1.0}
    config.update(overrides)
    return config


SETTINGS = {"robot": {"driver": "Pkm5Controller", "port": "/dev/pts/7", "firmware": "sim-1.0",
                      "rated_speed_steps_s": 200},
            "instrument": {"instrument": "two simulated optical mice (x-y, x-z)", "cpi": 800.0,
                           "noise_counts": 0.3, "calibration_id": "sim-mouse-800cpi"},
            "speed_factor": 1000.0}


def write_pose_run(store: Store, *, seed: int = 1, bias_mm=(0.2, -0.1, 0.05), noise_mm: float = 0.05,
                   config=None, settings=None, calibration: bool = True, load_sag_mm_per_kg: float = 0.0,
                   calibration_ids=None) -> int:
    """A completed pose run: every pose, cycle, velocity and load of ``config``, attained = command + bias + noise
    (+ a sag in -z proportional to the load)."""
    config = config or pose_config()
    rng = np.random.default_rng(seed)
    ids = tuple(calibration_ids or ())
    if calibration and calibration_ids is None:
        ids = (store.add_calibration("mouse_xy", {"cpi": 800.0, "matrix_mm_per_count": [[0.03175, 0], [0, 0.03175]]},
                                     notes="nominal 800 cpi").id,)
    run_id = store.start_run(protocol_name=config["protocol"], protocol_version="1", robot=config["robot"],
                             config=config, settings=settings or SETTINGS, calibration_ids=ids)
    step, t_s = 0, 0.0
    for load in config["loads_kg"]:
        for velocity in config["velocities_pct"]:
            for cycle in range(1, config["cycles"] + 1):
                for label in ORDER:
                    command = np.array(CUBE[label])
                    attained = command + np.array(bias_mm) + rng.normal(0.0, noise_mm, 3)
                    attained[2] -= load_sag_mm_per_kg * load
                    values = {"x_mm": attained[0], "y_mm": attained[1], "z_mm": attained[2],
                              "cmd_x_mm": command[0], "cmd_y_mm": command[1], "cmd_z_mm": command[2],
                              "cmd_a_deg": 0.0, "cmd_b_deg": 0.0, "velocity_pct": velocity, "load_kg": load}
                    store.add_sample(run_id, step, values={k: float(v) for k, v in values.items()}, pose=label,
                                     cycle=cycle, t_s=t_s, raw={"counts_xy": [1, 2]})
                    step += 2
                    t_s += 1.5
    store.set_status(run_id, "completed")
    return run_id
