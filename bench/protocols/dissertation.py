"""The dissertation's test protocols on the pkm5 (000_1cca5531533552b2.txt, ch. 8; reference pkm5.md §6.8-6.11).

- ``dissertation_pose``: 15 points (3 per y-region of Table 8-2) x 10 repeats, home -> point -> home; the
  ``translation`` variant measures position with the mice, the ``alpha`` and ``beta`` variants also ask for the
  calliper tilt reading at each visit (000 §8.6.3; Tables A.11-A.13): the tilt in degrees (``tilt_entry = "angle"``)
  or the two depths through the bracket holes ``hole_spacing_mm`` apart (``"depths"``, kind ``tilt_depth``), from
  which the analysis derives it (``bench.metrology.orientation_tables``).
- ``payload_ladder``: the load sequence of Table A.14, a pure vertical lift of 50.42 mm per load, six calliper leg
  readings per load, home between loads (000 §8.7).
- ``mouse_calibration``: steps of 5/10/15/20/40 mm along x then y, repeated, capturing the raw mouse counts at both
  ends; on completion a least-squares scale per axis is stored as a new version of calibration ``mouse``
  (000 App. A.7; sensors.md §5).
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.metrology.documents import LADDER_KG, LADDER_LIFT_MM, PAYLOAD_FAILURE_KG
from bench.metrology.formatting import format_measured
from bench.metrology.mouse_calibration import counts_per_inch, mouse_calibration_moves
from bench.protocols.base import Protocol, register
from bench.protocols.kinematics import robot_model
from bench.protocols.parameters import (
    ChoiceParameter,
    FloatListParameter,
    FloatParameter,
    IntegerParameter,
)
from bench.steps import (
    Capture,
    Checkpoint,
    Move,
    Plan,
    Prompt,
    Settle,
    commanded_values,
)

__all__ = [
    "DissertationPose",
    "MouseCalibration",
    "PayloadLadder",
    "mouse_calibration_moves",
    "mouse_calibration_text",
    "store_mouse_calibration",
]

_log = logging.getLogger(__name__)

#: 000 Table A.11 (translation), A.12 (alpha, deg) and A.13 (beta, deg): x, y, z in mm, angle in degrees.
POINTS = {
    "translation": [
        (170.67, -91.43, 268.83),
        (171.83, -98.75, 264.29),
        (163.49, -86.82, 275.46),
        (167.59, -36.14, 293.74),
        (174.87, -47.07, 293.64),
        (151.93, -71.93, 292.72),
        (110.52, -0.19, 305.5),
        (99.12, -18.53, 345.4),
        (177.3, 19.54, 294.36),
        (139.28, 33.52, 312.11),
        (142.83, 46.43, 302.21),
        (145.77, 67.62, 304.64),
        (160.7, 86.19, 281.34),
        (130.6, 91.48, 297.3),
        (130.06, 105.95, 292.9),
    ],
    "alpha": [
        (111.31, -80.44, 311.76, -7.39),
        (111.31, -89.17, 296.29, -5),
        (111.31, -83.08, 302.83, 5),
        (111.31, -45.29, 310.77, -15.82),
        (111.31, -33.65, 309.97, 12.26),
        (111.31, -68.9, 299.1, -7.09),
        (111.31, -4.66, 310.83, 15),
        (111.31, -26.81, 311.43, -20),
        (111.31, -0.26, 311.09, 5),
        (111.31, 31.15, 317.07, 16.7),
        (111.31, 77.88, 304.67, 20.25),
        (111.31, 46.86, 309.34, -9.78),
        (111.31, 89.04, 305.48, 10.41),
        (111.31, 103.97, 299.41, 8.78),
        (111.31, 84.59, 306.17, -2.3),
    ],
    "beta": [
        (124.47, -90.11, 287.16, 10.11),
        (101.57, -97.88, 314.82, -5.52),
        (105.16, -93.48, 322.4, -12.64),
        (105.45, -33.76, 317.56, 8.57),
        (113.84, -31.64, 308.17, 15.11),
        (97.84, -54.65, 322.13, -9.43),
        (164.34, -15, 305.66, -11.02),
        (164.48, 15.15, 296.16, -17.46),
        (138.51, 23.44, 304.56, 9.33),
        (111.03, 43.04, 308.45, 12.93),
        (135.94, 29.14, 319.64, -12.48),
        (137.56, 51.8, 315.32, -4),
        (123.69, 91.82, 287.49, 11.87),
        (151.61, 95.94, 273.93, 6.89),
        (142.28, 84.02, 301.35, -7.8),
    ],
}


def _label(index: int) -> str:
    return f"{index // 3 + 1}-{index % 3 + 1}"  # region-point, as in Tables A.11-A.13


def _target(variant: str, point: tuple[float, ...]) -> tuple[float, ...]:
    if variant == "translation":
        return point
    x, y, z, angle = point
    return (x, y, z, angle, 0.0) if variant == "alpha" else (x, y, z, 0.0, angle)


@register
class DissertationPose(Protocol):
    """000 §8.6: 15 points x 10 repeats from home, position by the mice, tilt by calliper (alpha/beta variants)."""

    name = "dissertation_pose"
    version = "1"
    title = "Dissertation pose test (000 §8.6.3), 15 points in 5 y-regions"
    robots = ("pkm5",)

    variant = ChoiceParameter("translation", choices=tuple(POINTS), description="Table A.11, A.12 or A.13")
    cycles = IntegerParameter(10, minimum=2, description="repeats per point (000: 10)")
    velocity_pct = FloatParameter(100.0, unit="%", minimum=0.1, maximum=100.0, description="velocity")
    settle_s = FloatParameter(1.0, unit="s", minimum=0.0, maximum=600.0, description="dwell before a reading")
    tilt_entry = ChoiceParameter(
        "angle",
        choices=("angle", "depths"),
        description="alpha/beta: the operator enters the tilt (deg), or the two calliper "
        "depths through the bracket holes (mm; the tilt is derived in the "
        "analysis, raw data first)",
    )
    hole_spacing_mm = FloatParameter(
        40.0,
        unit="mm",
        minimum=1.0,
        maximum=500.0,
        description="bracket hole spacing s: tilt = atan2(h2 - h1, s) (not stated in 000)",
    )
    design_keys = ("poses", "loads_kg")

    def config(self) -> dict:
        """The parameters plus what the report's deviations table reads: the labelled target poses (mm, degrees,
        the variant's table) and the load, none: 000 §8.6.2-8.6.3 mount no payload for this test."""
        poses = {_label(i): list(_target(self.variant, p)) for i, p in enumerate(POINTS[self.variant])}
        return {**super().config(), "poses": poses, "loads_kg": [0.0]}

    def steps(self) -> Plan:
        home = robot_model(self.robot).home
        angle = {"alpha": "a", "beta": "b"}.get(self.variant)
        for index, point in enumerate(POINTS[self.variant]):
            target = _target(self.variant, point)
            for cycle in range(1, self.cycles + 1):
                yield Move(home, self.velocity_pct, "home")
                yield Move(target, self.velocity_pct, _label(index))
                yield Settle(self.settle_s)
                yield Capture(
                    _label(index),
                    cycle,
                    commanded=commanded_values(target[:3]),
                    conditions={"velocity_pct": self.velocity_pct},
                )
                if angle is not None and self.tilt_entry == "depths":
                    for hole in (1, 2):  # 000 §8.6.3 step 5: "the depth at two different points"
                        yield Prompt(
                            f"Point {_label(index)}, repeat {cycle}: calliper depth at hole {hole} ({self.variant})",
                            field=f"depth{hole}_mm",
                            unit="mm",
                            minimum=0.0,
                            maximum=300.0,
                            pose=_label(index),
                            cycle=cycle,
                            kind="tilt_depth",
                            commanded={f"cmd_{angle}_deg": point[3]},
                            conditions={"hole_spacing_mm": self.hole_spacing_mm},
                        )
                elif angle is not None:
                    yield Prompt(
                        f"Point {_label(index)}, repeat {cycle}: calliper tilt {self.variant}",
                        field=f"{angle}_deg",
                        unit="deg",
                        minimum=-45.0,
                        maximum=45.0,
                        pose=_label(index),
                        cycle=cycle,
                        kind="tilt",
                        commanded={f"cmd_{angle}_deg": point[3]},
                    )
                yield Checkpoint(f"point {_label(index)}, repeat {cycle}")

    def final_steps(self) -> Plan:
        yield from self.return_home()


@register
class PayloadLadder(Protocol):
    """000 §8.7: per load, confirm the payload, lift 50.42 mm straight up, read the six legs, return home."""

    name = "payload_ladder"
    version = "1"
    title = "Payload ladder (000 §8.7, Table A.14)"
    robots = ("pkm5",)

    loads_kg = FloatListParameter(
        LADDER_KG,
        unit="kg",
        minimum=0.0,
        maximum=25.23,
        description="load sequence (000 Table A.14); the structure failed on reload at 25 kg",
    )
    lift_mm = FloatParameter(
        LADDER_LIFT_MM, unit="mm", minimum=1.0, maximum=60.0, description="vertical lift (000 §8.7)"
    )
    start_mm = FloatListParameter(
        (95.0, 0.0, 301.0),
        length=3,
        unit="mm",
        description="pose before the lift (with the 60 mm leg windows only x ~ 70-120 mm, "
        "z ~ 297-305 mm allow a 50.42 mm lift)",
    )
    repeats = IntegerParameter(1, minimum=1, description="lifts per load (000: 1; reference §12.3: at least 3)")
    velocity_pct = FloatParameter(100.0, unit="%", minimum=0.1, maximum=100.0, description="velocity")
    settle_s = FloatParameter(1.0, unit="s", minimum=0.0, maximum=600.0, description="dwell before the readings")

    def limit_warnings(self) -> tuple[str, ...]:
        """A load at or above the documented failure load (000 §8.7.5: the structure failed on reloading at 25 kg)."""
        over = [load for load in self.loads_kg if load >= PAYLOAD_FAILURE_KG]
        if not over:
            return ()
        return (
            f"{self.source}: loads_kg {', '.join(f'{v:g}' for v in over)} kg reach the documented failure load "
            f"{PAYLOAD_FAILURE_KG:g} kg (000 §8.7.5: the mouse bracket and end effector failed on reloading at "
            f"25 kg); keep the top rung below your safe maximum",
        )

    def lifted(self) -> tuple[float, ...]:
        x, y, z = self.start_mm
        return (x, y, z + self.lift_mm)

    def expected_legs_mm(self) -> np.ndarray:
        """Leg lengths |BC| the IK predicts at the lifted pose (the L_cmd of reference §12.1)."""
        from motion import pkm5

        return pkm5.inverse_kinematics(list(self.lifted()) + [0.0, 0.0]).lengths_mm[0]

    def steps(self) -> Plan:
        legs = self.expected_legs_mm()
        for rung, load in enumerate(self.loads_kg, start=1):
            yield Prompt(f"Load {load:g} kg centred on the top platform, then confirm", conditions={"load_kg": load})
            for repeat in range(1, self.repeats + 1):
                yield Move(tuple(self.start_mm), self.velocity_pct, "start")
                yield Move(self.lifted(), self.velocity_pct, "lift")
                yield Settle(self.settle_s)
                for leg in range(6):
                    yield Prompt(
                        f"Load {load:g} kg: calliper length of leg {leg + 1}",
                        field="length_mm",
                        unit="mm",
                        minimum=150.0,
                        maximum=280.0,
                        pose=f"{load:g}kg",
                        cycle=repeat,
                        kind="leg_length",
                        commanded={"cmd_length_mm": float(legs[leg])},
                        conditions={"load_kg": load, "leg": leg + 1},
                    )
            yield Move(robot_model(self.robot).home, self.velocity_pct, "home")
            yield Checkpoint(f"rung {rung}: {load:g} kg")

    def final_steps(self) -> Plan:
        yield Prompt("Remove the payload, then confirm", conditions={"load_kg": 0.0})


@register
class MouseCalibration(Protocol):
    """000 App. A.7: known steps along x then y, raw counts at both ends, against a reference the person states;
    fitted (an intercept per move direction) and stored as a new calibration version, put in force by none.

    ``reference`` says what the travel is known from: ``calliper`` (the operator reads the end effector's position
    along the step axis against a fixed stop after every capture: the robot under test is not the reference) or
    ``calibrated-axis`` (the commanded travel of an axis the person states is calibrated, e.g. a certified stage
    carrying the mouse). ``reference_u_pct`` is the reference's stated relative standard uncertainty of scale; it
    is combined with the fit's own into the stored u.
    """

    name = "mouse_calibration"
    version = "2"  # 2: a stated reference (calliper readings or a calibrated axis), every move between readings
    title = "Optical-mouse resolution calibration (000 App. A.7)"
    robots = ("pkm5",)

    distances_mm = FloatListParameter(
        (5.0, 10.0, 15.0, 20.0, 40.0),
        unit="mm",
        minimum=0.5,
        maximum=60.0,
        description="step lengths (000: 5, 10, 15, 20, 40 mm)",
    )
    repeats = IntegerParameter(5, minimum=2, description="repeats per step length")
    start_mm = FloatListParameter((90.0, -20.0, 310.0), length=3, unit="mm", description="start of every step")
    velocity_pct = FloatParameter(100.0, unit="%", minimum=0.1, maximum=100.0, description="velocity")
    settle_s = FloatParameter(0.5, unit="s", minimum=0.0, maximum=600.0, description="dwell before a reading")
    reference = ChoiceParameter(
        None,
        choices=("calliper", "calibrated-axis"),
        description="what the travel is known from (required): calliper readings, or the "
        "commanded travel of an axis stated to be calibrated",
    )
    reference_u_pct = FloatParameter(
        None,
        unit="%",
        minimum=0.0,
        maximum=10.0,
        description="the reference's relative standard uncertainty of scale (required)",
    )

    def validate(self) -> None:
        super().validate()
        for key, expected in (
            (
                "reference",
                (
                    "'calliper' or 'calibrated-axis' (what the travel is known from; "
                    "the robot under test is no reference)"
                ),
            ),
            ("reference_u_pct", "the reference's relative standard uncertainty of scale, %"),
        ):
            if getattr(self, key) is None:
                raise ConfigError(f"{self.source}: {key} missing, expected {expected}")

    def steps(self) -> Plan:
        start = tuple(self.start_mm)
        for axis, name in ((0, "x"), (1, "y")):
            for distance in self.distances_mm:
                end = list(start)
                end[axis] += distance
                for repeat in range(1, self.repeats + 1):
                    for where, target in (("start", start), ("end", tuple(end))):
                        label = f"{name}{distance:g}/{where}"
                        yield Move(target, self.velocity_pct, label)
                        yield Settle(self.settle_s)
                        commanded = {**commanded_values(target), "step_mm": distance}
                        yield Capture(label, repeat, kind="mouse", commanded=commanded)
                        if self.reference == "calliper":
                            yield Prompt(
                                f"Calliper: the end effector's {name} position against the fixed stop",
                                field="reference_mm",
                                unit="mm",
                                minimum=-1000.0,
                                maximum=1000.0,
                                pose=label,
                                cycle=repeat,
                                kind="mouse_reference",
                                commanded=commanded,
                            )
                    yield Checkpoint(f"{name} {distance:g} mm, repeat {repeat}")

    def on_completed(self, store: Any, run_id: int) -> None:
        record = store_mouse_calibration(store, run_id)
        _log.warning(
            "stored mouse calibration mouse-v%d: %s; not in force until a station names it ([mice] calibration = %d)",
            record.version,
            mouse_calibration_text(record.params),
            record.version,
        )


def mouse_calibration_text(params: dict[str, Any]) -> str:
    """One line of what a stored mouse calibration says: each scale with its U, and significant intercepts."""
    k = params.get("k", 2.0)
    scales = ", ".join(
        f"{a} {format_measured(params[f'{a}_mm_per_count'], k * params[f'u_{a}_mm_per_count'])} mm/count "
        f"({format_measured(*counts_per_inch(params[f'{a}_mm_per_count'], k * params[f'u_{a}_mm_per_count']))} cpi)"
        for a in "xy"
    )
    flagged = [f"{label} {value:+.2f} counts" for label, value in params.get("significant_intercepts", {}).items()]
    return f"{scales} (U, k = {k:.2f}); reference {params.get('reference', '?')}" + (
        f"; significant start/stop intercepts: {', '.join(flagged)}" if flagged else ""
    )


def store_mouse_calibration(store: Any, run_id: int, name: str = "mouse") -> Any:
    """Fit the x-y mouse's 2x2 matrix with an intercept per move direction against the run's stated reference
    (:func:`bench.metrology.fit_matrix`) and store it as a new version of calibration ``name``: the matrix, each
    axis's scale in mm/count with its u (the fit's and the reference's ``reference_u_pct`` combined), k, the
    intercepts with their u and which are significant."""
    from bench.metrology import fit_matrix

    run = store.run(run_id)
    config = run.config
    samples = sorted(store.samples(run_id, kind="mouse"), key=lambda s: s.step_index)
    references = store.samples(run_id, kind="mouse_reference") if config.get("reference") == "calliper" else None
    reference, counts, readings = mouse_calibration_moves(samples, references)
    if len(reference) < 6:
        raise ConfigError(f"run {run_id}: {len(reference)} moves with both readings stored, expected >= 6")
    fit = fit_matrix(reference, counts, per_direction=True, readings=readings)
    reference_u = float(config.get("reference_u_pct") or 0.0) / 100.0
    params: dict[str, Any] = {
        "source": f"run {run_id}",
        "reference": config.get("reference", "commanded travel"),
        "reference_u_pct": 100.0 * reference_u,
        "k": fit.coverage_factor,
        "dof": fit.dof,
        "matrix_mm_per_count": fit.a_mm_per_count.tolist(),
        "u_matrix_mm_per_count": fit.u_a_mm_per_count.tolist(),
    }
    u_scales = fit.u_scale_mm_per_count(reference_u)
    for column, axis in enumerate("xy"):
        params[f"{axis}_mm_per_count"] = float(fit.scale_mm_per_count[column])
        params[f"u_{axis}_mm_per_count"] = float(u_scales[column])
        params[f"{axis}_residual_sd_counts"] = float(fit.sigma_counts[column])
    params["mm_per_count"] = (params["x_mm_per_count"] + params["y_mm_per_count"]) / 2
    params["intercepts_counts"] = {label: fit.offsets_counts[i].tolist() for i, label in enumerate(fit.offset_labels)}
    params["u_intercepts_counts"] = {
        label: fit.u_offsets_counts[i].tolist() for i, label in enumerate(fit.offset_labels)
    }
    params["significant_intercepts"] = {
        f"{label} sensor {'xy'[j]}": float(fit.offsets_counts[i, j])
        for i, label in enumerate(fit.offset_labels)
        for j in range(2)
        if fit.offsets_significant[i, j]
    }
    return store.add_calibration(
        name, params, source_run_id=run_id, notes="2x2 least squares, an intercept per move direction (sensors.md §5.2)"
    )
