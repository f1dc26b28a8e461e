"""Write examples/kinematic_calibration.toml and examples/kinematic_validation.toml (the pkm5), and
examples/kinematic_calibration_delta4.toml and examples/kinematic_validation_delta4.toml (docs/calibration.md).

Calibration poses: 30 chosen by greedy D-optimal selection (:func:`bench.metrology.kinematic_calibration.select_poses`,
every parameter and the registration free, the mice's 0.05 mm per axis) from 300 reachable candidates of the three
motion modes (``motion.pkm5.sample_reachable(seed=1)``), rounded as a protocol file states them (0.01 mm, 0.01 deg)
and pre-flighted, leaving out the candidates near a fold of the forward kinematics (``fold_ratio`` below 1/100 of
the median, :func:`bench.metrology.kinematic_calibration.away_from_folds`). Validation poses: 12 held-out
translation poses (a different seed) in the central workspace (95 < x < 170 mm, |y| < 60 mm), so that a
calibrated geometry's pre-flight passes them too; translation only, since a calibrated geometry moves the alpha
plane (docs/calibration.md, limits).

delta4 (the camera spot sensor, x-y plane, 0.02 mm per axis): 30 positions chosen the same way from 300 reachable
ones within the camera's field (|x|, |y| < 75 mm; ``motion.delta4.workspace.workspace_samples(seed=1)``), the
candidates being the x-y registration and ``motion.delta4.calibration.BASE_PARAMETERS`` at the servo angles the
driver's default mapping sends (its bytes); 12 held-out positions (seed 7) within |x|, |y| < 60 mm.

    python examples/make_kinematic_protocols.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.metrology.kinematic_calibration import select_poses
from bench.protocols.kinematics import robot_model
from bench.robots.delta4_wire import LegacyVbMapping
from motion import delta4, pkm5
from motion.delta4 import calibration as delta4_calibration
from motion.delta4.workspace import workspace_samples
from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, modes_of_poses

HERE = Path(__file__).resolve().parent
MICE_UNCERTAINTY_MM = 0.05
CAMERA_UNCERTAINTY_MM = 0.02


def candidates(count: int, kinds: tuple[str, ...], seed: int) -> np.ndarray:
    """Reachable poses (mm, deg) rounded as a protocol file states them, that pass the pre-flight."""
    poses = pkm5.sample_reachable(count, kinds=kinds, seed=seed)
    deg = np.array(poses)
    deg[:, :3] = np.round(deg[:, :3], 2)
    deg[:, 3:] = np.round(np.degrees(deg[:, 3:]), 2)
    return deg[robot_model("pkm5").check(deg).reachable]


#: Cycles per pose of the pkm5's protocols. The documented pkm5's passive joints play 0.6 mm per axis per move
#: (sigma): with 2 cycles the pose means are too uncertain to inform the fit (``bench calibrate`` refuses and plans
#: the cycles; half the parameters were informed from 3-5 on the simulated robots). The calibration's own error at
#: the held-out poses falls as 1 / sqrt(cycles): 0.15 mm with 10 on true-geometry seed 65 (3.3x), 0.043 mm with 40
#: (6.1x). A validation run reads each pose's mean to the play's ~1.1 mm / sqrt(cycles): 50 cycles put that floor at
#: ~0.15 mm of AP, 150 at ~0.08 mm, so a robot erring by 0.57 mm before (seed 65) can show 5x (docs/calibration.md,
#: "A robot with play").
PKM5_CALIBRATION_CYCLES = 40
PKM5_VALIDATION_CYCLES = 150
#: Every pose of the pkm5's protocols is approached from 1 mm below it: every leg extends into it (0.57-1.0 mm of
#: leg per mm of z), so the backlash (0.1 mm) is taken up on one side at every arrival and the calibration identifies
#: it as a constant (docs/calibration.md, "Backlash").
PKM5_APPROACH_FROM_BELOW_MM = 1.0


def protocol_text(
    title: str, prefix: str, poses: np.ndarray, robot: str = "pkm5", cycles: int = 2, below_mm: float = 0.0
) -> str:
    lines = [f"# {line}" for line in title.splitlines()]
    lines += [
        'protocol = "iso9283_pose"',
        f'robot = "{robot}"',
        f"cycles = {cycles}",
        "velocities_pct = [100]",
        "settle_s = 0.2",
        *([f"approach_from_below_mm = {below_mm:g}"] if below_mm else []),
        "",
        "[poses]",
    ]
    lines += [f"{prefix}{i:02d} = [{', '.join(f'{v:g}' for v in pose)}]" for i, pose in enumerate(poses, 1)]
    return "\n".join(lines) + "\n"


def delta4_field(count: int, seed: int, half_width_mm: float) -> np.ndarray:
    """Reachable delta4 positions (mm, rounded to 0.01) within |x|, |y| < ``half_width_mm``, that pass the
    pre-flight."""
    points, reachable = workspace_samples(20000, seed=seed)
    points = np.round(points[reachable], 2)
    points = points[np.all(np.abs(points[:, :2]) < half_width_mm, axis=1)]
    return points[robot_model("delta4").check(points).reachable][:count]


def write_delta4() -> None:
    pool = delta4_field(300, 1, 75.0)
    mapping = LegacyVbMapping()  # the driver's default: the servos are sent bytes
    servo = mapping.to_deg(mapping.to_bytes(delta4.inverse_kinematics(pool).servo_deg))
    names = delta4_calibration.REGISTRATION[:2] + delta4_calibration.BASE_PARAMETERS
    jac = delta4_calibration.ForwardModel(servo, names).jacobian(np.zeros(len(names)))
    chosen = pool[select_poses(jac, CAMERA_UNCERTAINTY_MM, 30)]
    (HERE / "kinematic_calibration_delta4.toml").write_text(
        protocol_text(
            "Kinematic calibration of the delta4 with the camera spot sensor (x-y plane): 30 positions chosen for\n"
            "observability (greedy D-optimal from 300 candidates in the camera's field; written by\n"
            "examples/make_kinematic_protocols.py). Run it without a calibration in force, then: bench calibrate RUN_ID\n"
            "(docs/calibration.md).",
            "C",
            chosen,
            "delta4",
        )
    )
    (HERE / "kinematic_validation_delta4.toml").write_text(
        protocol_text(
            "Validation of a delta4 kinematic calibration: the ISO 9283 pose test on 12 held-out positions. Run it\n"
            "twice, with the calibration in force (the default) and with --no-kinematic-calibration, and compare AP\n"
            "(written by examples/make_kinematic_protocols.py; docs/calibration.md).",
            "V",
            delta4_field(12, 7, 60.0),
            "delta4",
        )
    )


def main() -> None:
    pool = candidates(300, ("constant-orientation", "alpha", "beta"), seed=1)
    rad = pool.copy()
    rad[:, 3:] = np.radians(rad[:, 3:])
    steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(rad).lengths_mm)
    names = REGISTRATION + PARAMETERS
    model = ForwardModel(steps, modes_of_poses(pool), names)
    fold_ratio = model.fold_ratio(np.zeros(len(names)))  # candidates near an FK fold are never chosen
    chosen = pool[select_poses(model.jacobian(np.zeros(len(names))), MICE_UNCERTAINTY_MM, 30, fold_ratio=fold_ratio)]
    (HERE / "kinematic_calibration.toml").write_text(
        protocol_text(
            "Kinematic calibration of the pkm5: 30 poses chosen for observability (greedy D-optimal from 300\n"
            "candidates; written by examples/make_kinematic_protocols.py). Run it without a calibration in force,\n"
            "then: bench calibrate RUN_ID (docs/calibration.md).",
            "C",
            chosen,
            cycles=PKM5_CALIBRATION_CYCLES,
            below_mm=PKM5_APPROACH_FROM_BELOW_MM,
        )
    )
    held = candidates(60, ("constant-orientation",), seed=7)
    held = held[(held[:, 0] > 95) & (held[:, 0] < 170) & (np.abs(held[:, 1]) < 60)][:12]
    (HERE / "kinematic_validation.toml").write_text(
        protocol_text(
            "Validation of a kinematic calibration: the ISO 9283 pose test on 12 held-out translation poses. Run it\n"
            "twice, with the calibration in force (the default) and with --no-kinematic-calibration, and compare AP\n"
            "(written by examples/make_kinematic_protocols.py; docs/calibration.md).",
            "V",
            held,
            cycles=PKM5_VALIDATION_CYCLES,
            below_mm=PKM5_APPROACH_FROM_BELOW_MM,
        )
    )


if __name__ == "__main__":
    main()
    write_delta4()
