"""Small stored runs for the report tests, written with the store API (the configuration a pose protocol stores) or
run on the simulators, readers of the written HTML and PDF, and the JSON a ``bench`` command prints."""

from __future__ import annotations

import json
from html.parser import HTMLParser

import numpy as np

from bench.cli import main
from bench.store import Store

CUBE = {
    "P1": (110.0, 0.0, 320.0),
    "P2": (94.0, -16.0, 304.0),
    "P3": (94.0, 16.0, 304.0),
    "P4": (126.0, 16.0, 336.0),
    "P5": (126.0, -16.0, 336.0),
}
ORDER = ("P1", "P5", "P4", "P3", "P2")


def pose_config(**overrides):
    config = {
        "protocol": "iso9283_pose",
        "protocol_version": "1",
        "robot": "pkm5",
        "cycles": 10,
        "velocities_pct": [100.0],
        "loads_kg": [0.0],
        "cube_centre_mm": [110.0, 0.0, 320.0],
        "cube_side_mm": 40.0,
        "plane": "x=z",
        "poses": None,
        "settle_s": 1.0,
    }
    config.update(overrides)
    return config


SETTINGS = {
    "robot": {"driver": "Pkm5Controller", "port": "/dev/pts/7", "firmware": "sim-1.0", "rated_speed_steps_s": 200},
    "instrument": {
        "instrument": "two simulated optical mice (x-y, x-z)",
        "cpi": 800.0,
        "noise_counts": 0.3,
        "calibration_id": "sim-mouse-800cpi",
    },
    "speed_factor": 1000.0,
}


def write_pose_run(
    store: Store,
    *,
    seed: int = 1,
    bias_mm=(0.2, -0.1, 0.05),
    noise_mm: float = 0.05,
    config=None,
    settings=None,
    calibration: bool = True,
    load_sag_mm_per_kg: float = 0.0,
    calibration_ids=None,
) -> int:
    """A completed pose run: every pose, cycle, velocity and load of ``config``, attained = command + bias + noise
    (+ a sag in -z proportional to the load)."""
    config = config or pose_config()
    rng = np.random.default_rng(seed)
    ids = tuple(calibration_ids or ())
    if calibration and calibration_ids is None:
        ids = (
            store.add_calibration(
                "mouse_xy", {"cpi": 800.0, "matrix_mm_per_count": [[0.03175, 0], [0, 0.03175]]}, notes="nominal 800 cpi"
            ).id,
        )
    run_id = store.start_run(
        protocol_name=config["protocol"],
        protocol_version="1",
        robot=config["robot"],
        config=config,
        settings=settings or SETTINGS,
        calibration_ids=ids,
    )
    step, t_s = 0, 0.0
    for load in config["loads_kg"]:
        for velocity in config["velocities_pct"]:
            for cycle in range(1, config["cycles"] + 1):
                for label in ORDER:
                    command = np.array(CUBE[label])
                    attained = command + np.array(bias_mm) + rng.normal(0.0, noise_mm, 3)
                    attained[2] -= load_sag_mm_per_kg * load
                    values = {
                        "x_mm": attained[0],
                        "y_mm": attained[1],
                        "z_mm": attained[2],
                        "cmd_x_mm": command[0],
                        "cmd_y_mm": command[1],
                        "cmd_z_mm": command[2],
                        "cmd_a_deg": 0.0,
                        "cmd_b_deg": 0.0,
                        "velocity_pct": velocity,
                        "load_kg": load,
                    }
                    store.add_sample(
                        run_id,
                        step,
                        values={k: float(v) for k, v in values.items()},
                        pose=label,
                        cycle=cycle,
                        t_s=t_s,
                        raw={"counts_xy": [1, 2]},
                    )
                    step += 2
                    t_s += 1.5
    store.set_status(run_id, "completed")
    return run_id


# ---- runs of the documents' bench tests, stored as their protocols store them (same configuration, kinds, values) --

ACTUATOR_SETTINGS = {
    "robot": {"driver": "Pkm5Controller", "fixture": "actuator-bench", "rated_speed_steps_s": 200},
    "instrument": {"instrument": "depth gauge / calliper entries (actuator bench, 000 §8.4)"},
}
LADDER_SETTINGS = {
    "robot": {"driver": "Pkm5Controller", "fixture": "assembled", "rated_speed_steps_s": 200},
    "instrument": {"instrument": "two simulated optical mice (x-y, x-z)", "cpi": 800.0},
}
GRID_SETTINGS = {
    "robot": {"driver": "Delta4Controller", "velocity": "servo maximum (not settable)"},
    "instrument": {"instrument": "laser grid (controller reports)", "calibration_id": "lasergrid-gui-default"},
}
#: Delta thesis Appendix D2 (delta4-lasergrid.md §7.3): hits out of 25 of sensors 1-16 at 140, 170 and 200 mm.
APPENDIX_D2 = {
    140.0: (25, 24, 25, 25, 25, 25, 25, 25, 25, 24, 25, 24, 25, 25, 25, 25),
    170.0: (25, 25, 24, 25, 25, 24, 25, 25, 25, 24, 25, 24, 25, 24, 25, 25),
    200.0: (25, 25, 24, 25, 25, 23, 25, 25, 25, 25, 23, 25, 24, 25, 24, 24),
}


def _start(store: Store, name: str, parameters, settings) -> tuple[int, dict]:
    from bench.protocols import PROTOCOLS

    config = PROTOCOLS[name](**parameters).config()
    run_id = store.start_run(
        protocol_name=name,
        protocol_version=config["protocol_version"],
        robot=config["robot"],
        config=config,
        settings=settings,
    )
    return run_id, config


def write_actuator_run(
    store: Store,
    *,
    seed: int = 1,
    actuators=(1, 5),
    distances_mm=(10.0, 30.0, 50.0),
    repeats: int = 4,
    scale=(0.004, -0.003),
    noise_mm: float = 0.03,
    settings=ACTUATOR_SETTINGS,
) -> int:
    """A completed actuator_accuracy run: gauge reading = travel x (1 + scale of the actuator) + noise, to 0.01 mm."""
    run_id, _ = _start(
        store,
        "actuator_accuracy",
        {"actuators": list(actuators), "distances_mm": list(distances_mm), "repeats": repeats, "settle_s": 0.0},
        settings,
    )
    rng, step = np.random.default_rng(seed), 0
    for axis, error in zip(actuators, scale):
        for distance in distances_mm:
            for repeat in range(1, repeats + 1):
                reading = round(distance * (1 + error) + rng.normal(0.0, noise_mm), 2)
                store.add_sample(
                    run_id,
                    step,
                    kind="actuator_travel",
                    pose=f"A{axis}/{distance:g}mm",
                    cycle=repeat,
                    t_s=float(step),
                    values={
                        "travel_mm": reading,
                        "cmd_travel_mm": float(distance),
                        "actuator": float(axis),
                        "velocity_pct": 100.0,
                    },
                )
                step += 4
    store.set_status(run_id, "completed")
    return run_id


def write_ladder_run(
    store: Store,
    *,
    seed: int = 1,
    loads_kg=(0.0, 2.0, 5.0, 10.0),
    repeats: int = 3,
    sag_mm_per_kg: float = 0.02,
    noise_mm: float = 0.004,
) -> int:
    """A completed payload_ladder run whose legs read the IK lengths of the lifted pose sagging by
    ``sag_mm_per_kg`` x load in -z, plus reading noise, to 0.01 mm."""
    from motion import pkm5

    run_id, config = _start(
        store, "payload_ladder", {"loads_kg": list(loads_kg), "repeats": repeats, "settle_s": 0.0}, LADDER_SETTINGS
    )
    x, y, z = config["start_mm"]
    lifted = [x, y, z + config["lift_mm"], 0.0, 0.0]
    commanded = pkm5.inverse_kinematics(lifted).lengths_mm[0]
    rng, step = np.random.default_rng(seed), 0
    for load in loads_kg:
        sagging = pkm5.inverse_kinematics([x, y, lifted[2] - sag_mm_per_kg * load, 0.0, 0.0]).lengths_mm[0]
        for repeat in range(1, repeats + 1):
            step += 3
            for leg in range(6):
                length = round(float(sagging[leg] + rng.normal(0.0, noise_mm)), 2)
                store.add_sample(
                    run_id,
                    step,
                    kind="leg_length",
                    pose=f"{load:g}kg",
                    cycle=repeat,
                    t_s=float(step),
                    values={
                        "length_mm": length,
                        "cmd_length_mm": float(commanded[leg]),
                        "load_kg": float(load),
                        "leg": float(leg + 1),
                    },
                )
                step += 1
    store.set_status(run_id, "completed")
    return run_id


def write_grid_hit_run(store: Store, *, hits=APPENDIX_D2, attempts: int = 25) -> int:
    """A completed lasergrid_hits run at the heights of ``hits``, sensor n of the 4 x 4 spread hitting ``hits[h][n]``
    of ``attempts`` (the misses last); a miss still lights some other sensor every second time."""
    from bench.protocols.delta import grid_targets

    heights = sorted(hits)
    run_id, _ = _start(
        store, "lasergrid_hits", {"attempts": attempts, "heights_mm": [-h for h in heights]}, GRID_SETTINGS
    )
    step = 0
    for height in heights:
        for (i, j, x, y), count in zip(grid_targets(4), hits[height]):
            for attempt in range(1, attempts + 1):
                hit = attempt <= count
                other = not hit and attempt % 2 == 0
                store.add_sample(
                    run_id,
                    step,
                    kind="grid_hit",
                    pose=f"H{i},{j}@{height:g}",
                    cycle=attempt,
                    t_s=float(step),
                    values={
                        "cmd_x_mm": float(x),
                        "cmd_y_mm": float(y),
                        "cmd_z_mm": -height,
                        "expected_i": float(i),
                        "expected_j": float(j),
                        "expected_index": float(i + 16 * j),
                        "hit_expected": float(hit),
                        "hit_any": float(hit or other),
                        "hits": float(hit or other),
                    },
                )
                step += 3
    store.set_status(run_id, "completed")
    return run_id


# ---- runs with partial or streamed readings: delta_positioning (laser grid) and iso9283_stabilisation (arrivals) ----


def simulated_run(
    store: Store, protocol, robot: str, *, seed: int, speed_factor: float, options=(), ideal: bool = False
) -> int:
    """Run ``protocol`` on a freshly started simulated rig into ``store``; returns the completed run's id."""
    from bench.protocols import Runner
    from bench.simulators.rig import simulated_rig

    rig = simulated_rig(robot, seed=seed, speed_factor=speed_factor, options=tuple(options), ideal=ideal)
    try:
        result = Runner(rig, store).run(protocol)
    finally:
        rig.close()
    assert result.exit_status == "completed", result
    return result.run_id


def simulated_path_run(folder, *, shape: str, cycles: int, seed: int) -> int:
    """A simulated ``iso9283_path`` run of ``shape`` at 100 % into ``folder/p.db``; returns its id."""
    from bench.protocols.path import PathAccuracy

    protocol = PathAccuracy(shape=shape, cycles=cycles, velocities_pct=[100.0], final_hold_s=0.2)
    with Store(folder / "p.db") as store:
        return simulated_run(store, protocol, "pkm5", seed=seed, speed_factor=10000)


GRID_POSITIONING_SETTINGS = {
    "robot": {"driver": "Delta4Controller", "velocity": "servo maximum (not settable)"},
    "instrument": {
        "instrument": "laser grid (controller reports)",
        "calibration_id": "grid-measured-2024-05",
        "decoder": {"spot_half_width_mm": 1.0, "gate_mm": 3.75, "prior_uncertainty_mm": 0.0},
    },
}
#: Readings per pose of :func:`write_grid_positioning_run` as (x, y, z) with None where no screen measured the axis:
#: P1 three complete readings and one of the horizontal screen only; P2 the vertical screen only (x never measured);
#: P3 nothing at all.
GRID_READINGS = {
    "P1": [(0.0, 2.5, -200.0), (2.5, 0.0, -197.5), (0.0, 0.0, -200.0), (2.5, 2.5, None)],
    "P2": [(None, -70.0, -180.0), (None, -67.5, -180.0), (None, None, None), (None, -70.0, -182.5)],
    "P3": [(None, None, None)] * 4,
}


def write_grid_positioning_run(store: Store, readings=GRID_READINGS, settings=GRID_POSITIONING_SETTINGS) -> int:
    """A completed delta_positioning run whose samples store ``readings`` as the laser-grid instrument stores them:
    only the measured axes, the horizontal screen valid when x is stored, the vertical one when z is."""
    cycles = len(next(iter(readings.values())))
    run_id, config = _start(store, "delta_positioning", {"cycles": cycles, "settle_s": 0.1}, settings)
    step = 0
    for cycle in range(cycles):
        for label, rows in readings.items():
            command = config["poses"][label]
            x, y, z = rows[cycle]
            values = {f"cmd_{a}_mm": float(v) for a, v in zip("xyz", command)}
            values |= {f"{a}_mm": v for a, v in zip("xyz", (x, y, z)) if v is not None}
            values |= {
                "horizontal_valid": float(x is not None),
                "vertical_valid": float(z is not None),
                "horizontal_hits": float(x is not None),
                "vertical_hits": float(z is not None or y is not None),
                "velocity_pct": 100.0,
            }
            store.add_sample(run_id, step, values=values, pose=label, cycle=cycle + 1, t_s=float(step))
            step += 3
    store.set_status(run_id, "completed")
    return run_id


# ---- reading a written report back ----


class _Tables(HTMLParser):
    """Every ``<table id=...>`` of an HTML page as a list of rows of cell texts (header row first)."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self._table = self._row = self._cell = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self._table = self.tables.setdefault(dict(attrs).get("id", ""), [])
        elif tag == "tr" and self._table is not None:
            self._row = []
            self._table.append(self._row)
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def html_tables(path) -> dict[str, list[list[str]]]:
    """The tables of an HTML report by id, each a list of rows of cell texts (header first)."""
    parser = _Tables()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser.tables


def pdf_text(path) -> str:
    """The text of a PDF report, whitespace collapsed to single spaces (pypdf)."""
    from pypdf import PdfReader

    return " ".join(" ".join(page.extract_text().split()) for page in PdfReader(path).pages)


def cli_json(capsys, *argv) -> dict:
    """The JSON that ``bench *argv`` prints (``capsys``: pytest's fixture), after checking that it exits with 0."""
    capsys.readouterr()
    assert main(list(argv)) == 0
    return json.loads(capsys.readouterr().out)


def rounded_by_u(value: float, u: float) -> str:
    """``value ± U`` as a report must print it, computed independently of bench's formatter: U to two significant
    digits (the exponent of the leading digit, from the decimal string), the value to the same decimal place."""
    leading = f"{u:.1e}"  # e.g. '2.3e-01': two significant digits, and their exponent
    mantissa, exponent = leading.split("e")
    places = max(0, 1 - int(exponent))
    return f"{value:.{places}f} ± {float(leading):.{places}f}"


def copy_path_cycles(db_path, run_id: int, copies: int) -> None:
    """Append ``copies`` copies of path run ``run_id``'s ``path`` samples to its store at ``db_path``, each with new
    step indices and cycle numbers and its own checksums: a long run from a short simulated one (one SQL statement
    per copy; the store commits sample by sample, minutes for thousands of samples)."""
    import sqlite3

    from bench.store.sample_checksum import CHECKED_COLUMNS, sample_checksum

    with sqlite3.connect(db_path) as db:
        ((steps, cycles),) = db.execute(
            "SELECT MAX(step_index) + 1, MAX(cycle) FROM samples WHERE run_id = ?", (run_id,)
        )
        for copy in range(1, copies + 1):
            db.execute(
                "INSERT INTO samples (run_id, step_index, kind, pose, cycle, t_s, wall_utc, values_json, "
                "raw_json) SELECT run_id, step_index + ?, kind, pose, cycle + ?, t_s, wall_utc, values_json, "
                "raw_json FROM samples WHERE run_id = ? AND kind = 'path' AND step_index < ?",
                (copy * steps, copy * cycles, run_id, steps),
            )
        columns = ", ".join(CHECKED_COLUMNS)  # each copy's checksum: its step and cycle are new
        rows = db.execute(f"SELECT rowid, {columns} FROM samples WHERE run_id = ? AND step_index >= ?", (run_id, steps))
        db.executemany(
            "UPDATE samples SET checksum = ? WHERE rowid = ?", [(sample_checksum(*row[1:]), row[0]) for row in rows]
        )
