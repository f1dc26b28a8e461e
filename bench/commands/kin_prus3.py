"""``bench kin ik|fk|workspace prus3``: the 3-PRUS kinematics on the command line (mm, degrees).

The geometry is the reference's stand-in (the paper lost its dimensions). FK needs every leg joint
(slider, revolute, universal): the six actuators alone leave three platform freedoms free.
"""

from __future__ import annotations

import argparse

from bench.commands.kin import add_sampling_options, emit, new_robot_parser, sampling_progress
from bench.commands.lazy import defer
from bench.errors import ConfigError, UnreachableTarget

_ROBOT = "prus3"
_HELP = "3-PRUS spatial parallel manipulator (stand-in dimensions a=600, b=75, c=100 mm)"
_POSE_FIELDS = ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg", "gamma_deg")


def _branch(text: str) -> int:
    if text not in ("+1", "1", "-1"):
        raise argparse.ArgumentTypeError(f"branch {text!r}, expected +1 or -1")
    return int(text)


def add_ik(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    for name, text in zip(
        _POSE_FIELDS,
        (
            "tip x [mm]",
            "y [mm]",
            "z [mm]",
            "roll about x [deg]",
            "pitch about y [deg]",
            "yaw about z [deg]; R = Rz(gamma) Ry(beta) Rx(alpha)",
        ),
    ):
        parser.add_argument(name, type=float, metavar=name.split("_")[0].upper(), help=text)
    parser.add_argument(
        "--branch", type=_branch, nargs=3, default=[1, 1, 1], metavar="SIGMA", help="slider branch per leg (+1 or -1)"
    )
    defer(parser, _add_convention)
    parser.set_defaults(handler=_ik)


def _add_convention(parser: argparse.ArgumentParser) -> None:
    from motion.prus3.revolute import CONVENTIONS

    parser.add_argument(
        "--convention",
        choices=[c for c in CONVENTIONS if c != "fixed"],
        default="clip",
        help="how the redundant revolute x2 is chosen",
    )


def add_fk(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    parser.add_argument("sliders_mm", type=float, nargs=3, metavar="S", help="slider positions s1..s3 [mm]")
    parser.add_argument(
        "--revolute-deg", type=float, nargs=3, required=True, metavar="X2", help="revolute angles x2 of legs 1..3 [deg]"
    )
    parser.add_argument(
        "--universal-deg",
        type=float,
        nargs=6,
        required=True,
        metavar="X3X4",
        help="universal angles x3, x4 of leg 1, then leg 2, then leg 3 [deg]",
    )
    parser.set_defaults(handler=_fk)


def add_workspace(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    add_sampling_options(parser, 400_000)
    parser.add_argument(
        "--orientation-deg",
        type=float,
        nargs=3,
        default=[0.0, 0.0, 0.0],
        metavar="ANGLE",
        help="constant orientation alpha beta gamma [deg]",
    )
    parser.set_defaults(handler=_workspace)


def _ik(args: argparse.Namespace) -> int:
    from motion import prus3

    pose = [getattr(args, name) for name in _POSE_FIELDS]
    result = prus3.inverse_kinematics(pose, branch=args.branch, revolute_convention=args.convention)
    reason = result.reason[0]
    sliders = result.sliders_mm[0].tolist()
    emit(
        {
            "sliders_mm": sliders,
            "reachable": reason is None,
            "reason": reason,
            "revolute_deg": result.revolute_deg[0].tolist(),
            "universal_deg": result.universal_deg[0].tolist(),
            "branch": [int(b) for b in result.branch[0]],
            "ik_margin": float(result.ik_margin[0]),
            "convention": args.convention,
        },
        args.json,
        [
            f"leg {i + 1}: s = {s:10.4f} mm   x2 = {x2:8.3f} deg   x3, x4 = {u[0]:8.3f}, {u[1]:8.3f} deg"
            for i, (s, x2, u) in enumerate(zip(sliders, result.revolute_deg[0], result.universal_deg[0]))
        ]
        + [f"reachable: {reason is None}   ik_margin {result.ik_margin[0]:.4f}"],
    )
    if reason is not None:
        values = ", ".join(f"{v:g}" for v in pose)
        raise UnreachableTarget(f"pose ({values}) mm/deg is not reachable: {reason}")
    return 0


def _fk(args: argparse.Namespace) -> int:
    from motion import prus3

    fit = prus3.forward_kinematics(args.sliders_mm, args.revolute_deg, [args.universal_deg])
    pose = dict(zip(_POSE_FIELDS, map(float, fit.pose[0])))
    residual = float(fit.residual_mm[0])
    emit(
        {"pose": pose, "residual_mm": residual},
        args.json,
        [f"{key} = {value:.4f}" for key, value in pose.items()] + [f"corner residual {residual:.3g} mm (RMS)"],
    )
    return 0


def _workspace(args: argparse.Namespace) -> int:
    from motion import prus3

    if args.samples < 1:
        raise ConfigError(f"--samples = {args.samples}, expected an integer >= 1")
    with sampling_progress(args, "prus3 workspace, samples") as progress:
        volume = prus3.workspace_volume(
            args.samples, orientation_deg=tuple(args.orientation_deg), seed=args.seed, progress=progress
        )
    emit(
        {
            "volume_mm3": volume.volume_mm3,
            "stderr_mm3": volume.standard_error_mm3,
            "samples": volume.count,
            "hits": volume.accepted,
            "orientation_deg": args.orientation_deg,
        },
        args.json,
        [
            f"constant-orientation workspace at {args.orientation_deg} deg: {volume.volume_mm3 / 1e9:.5f} "
            f"+/- {volume.standard_error_mm3 / 1e9:.5f} m3 ({volume.accepted:,} of {volume.count:,} samples)"
        ],
    )
    return 0
