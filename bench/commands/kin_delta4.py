"""``bench kin ik|fk|workspace delta4``: the 4-RSS delta's kinematics on the command line (mm, degrees)."""

from __future__ import annotations

import argparse

from bench.commands.kin import add_sampling_options, emit, new_robot_parser
from bench.errors import BenchError, ConfigError, UnreachableTarget

_ROBOT = "delta4"
_HELP = "3-DOF 4-RSS delta with laser-grid sensor (four RC servos)"
#: ``--geometry`` name -> the geometry's name in motion.delta4 (imported when a command runs).
_GEOMETRIES = {"nominal": "NOMINAL", "thesis": "THESIS"}


def _geometry(name: str):
    from motion import delta4

    return getattr(delta4, _GEOMETRIES[name])


def _add_geometry(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--geometry",
        choices=sorted(_GEOMETRIES),
        default="nominal",
        help="nominal: Table 3 (R0 = 179 mm); thesis: the code's R0^2 - n^2 = 300.607 cm^2",
    )


def add_ik(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    parser.add_argument("x_mm", type=float, metavar="X", help="end-effector centre x [mm]")
    parser.add_argument("y_mm", type=float, metavar="Y", help="y [mm]")
    parser.add_argument("z_mm", type=float, metavar="Z", help="z [mm] (negative: below the base)")
    _add_geometry(parser)
    parser.set_defaults(handler=_ik)


def add_fk(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    parser.add_argument("servo_deg", type=float, nargs=4, metavar="S", help="servo angles theta_R1..theta_R4 [deg]")
    parser.add_argument(
        "--method",
        choices=["least_squares", "joint_space", "closed_form"],
        default="least_squares",
        help="least squares over the four leg spheres or over the four angles, or the thesis closed form",
    )
    _add_geometry(parser)
    parser.set_defaults(handler=_fk)


def add_workspace(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    add_sampling_options(parser, 200_000)
    parser.add_argument(
        "--z-mm",
        type=float,
        nargs="*",
        default=[-250.0, -200.0, -150.0, -100.0],
        metavar="Z",
        help="heights at which to report the largest reachable centred square",
    )
    _add_geometry(parser)
    parser.set_defaults(handler=_workspace)


def _ik(args: argparse.Namespace) -> int:
    from motion import delta4

    result = delta4.inverse_kinematics([args.x_mm, args.y_mm, args.z_mm], _geometry(args.geometry))
    reason = result.reason[0]
    servo, coord = result.servo_deg[0].tolist(), result.coord_deg[0].tolist()
    emit(
        {
            "servo_deg": servo,
            "coord_deg": coord,
            "knees_mm": result.knees_mm[0].tolist(),
            "reachable": reason is None,
            "reason": reason,
        },
        args.json,
        [
            f"leg {i + 1}: servo {s:9.4f} deg   coordinate {c:9.4f} deg   knee ({k[0]:.3f}, {k[1]:.3f}, {k[2]:.3f}) mm"
            for i, (s, c, k) in enumerate(zip(servo, coord, result.knees_mm[0]))
        ]
        + [f"reachable: {reason is None}"],
    )
    if reason is not None:
        raise UnreachableTarget(f"point ({args.x_mm:g}, {args.y_mm:g}, {args.z_mm:g}) mm is not reachable: {reason}")
    return 0


def _fk(args: argparse.Namespace) -> int:
    from motion import delta4

    result = delta4.forward_kinematics(args.servo_deg, _geometry(args.geometry), method=args.method)
    pose = dict(zip(("x_mm", "y_mm", "z_mm"), map(float, result.pose_mm[0])))
    residual = float(result.residual_mm[0])
    emit(
        {"pose": pose, "residual_mm": residual},
        args.json,
        [f"{key} = {value:.4f}" for key, value in pose.items()] + [f"residual {residual:.3g} mm ({args.method})"],
    )
    if not result.ok[0]:
        angles = ", ".join(f"{a:g}" for a in args.servo_deg)
        raise BenchError(f"servo angles ({angles}) deg: forward kinematics failed: {result.reason[0]}")
    return 0


def _workspace(args: argparse.Namespace) -> int:
    import numpy as np

    from motion.delta4.workspace import reachable_square_half_width_mm, workspace_volume

    if args.samples < 1:
        raise ConfigError(f"--samples = {args.samples}, expected an integer >= 1")
    geometry = _geometry(args.geometry)
    volume = workspace_volume(args.samples, geometry, seed=args.seed)
    widths = reachable_square_half_width_mm(np.asarray(args.z_mm, dtype=float), geometry) if args.z_mm else np.empty(0)
    squares = [{"z_mm": z, "half_width_mm": float(w)} for z, w in zip(args.z_mm, widths)]
    emit(
        {
            "volume_mm3": volume.volume_mm3,
            "stderr_mm3": volume.standard_error_mm3,
            "samples": volume.count,
            "hits": volume.accepted,
            "squares": squares,
        },
        args.json,
        [
            f"reachable volume (servo {geometry.servo_limits_deg} deg, knee {geometry.knee_limits_deg} deg): "
            f"{volume.volume_mm3:,.0f} +/- {volume.standard_error_mm3:,.0f} mm3 "
            f"({volume.accepted:,} of {volume.count:,})"
        ]
        + [f"  z = {s['z_mm']:g} mm: centred square +-{s['half_width_mm']:g} mm" for s in squares],
    )
    return 0
