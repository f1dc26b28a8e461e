"""``bench kin ik|fk|workspace pkm5``: the 5-DOF PKM's kinematics on the command line (mm, degrees)."""

from __future__ import annotations

import argparse

from bench.commands.kin import add_sampling_options, emit, new_robot_parser, sampling_progress
from bench.commands.lazy import defer
from bench.errors import ConfigError, UnreachableTarget

_ROBOT = "pkm5"
_HELP = "5-DOF PKM 2-R(Pa-IQ)RR,R(Pa-IQ)R (six lead-screw legs)"


def add_ik(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    parser.add_argument("x_mm", type=float, metavar="X", help="end-effector centre x [mm]")
    parser.add_argument("y_mm", type=float, metavar="Y", help="y [mm]")
    parser.add_argument("z_mm", type=float, metavar="Z", help="z [mm]")
    rotation = parser.add_mutually_exclusive_group()
    rotation.add_argument("--alpha", type=float, default=0.0, metavar="DEG", help="roll about x [deg]")
    rotation.add_argument("--beta", type=float, default=0.0, metavar="DEG", help="pitch about y [deg]")
    parser.set_defaults(handler=_ik)


def add_fk(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    parser.add_argument("lengths_mm", type=float, nargs=6, metavar="L", help="leg lengths L1..L6 |BC| [mm]")
    defer(parser, _add_mode)
    parser.set_defaults(handler=_fk)


def _add_mode(parser: argparse.ArgumentParser) -> None:
    from motion.pkm5.fk import MODES

    parser.add_argument(
        "--mode",
        choices=["auto", *MODES],
        default="auto",
        help="motion mode to solve for (auto: from the length pattern)",
    )


def add_workspace(robots: argparse._SubParsersAction) -> None:
    parser = new_robot_parser(robots, _ROBOT, _HELP)
    defer(parser, _add_workspace_kind)
    add_sampling_options(parser, 200_000)
    parser.add_argument(
        "--hull-points",
        type=int,
        default=12_000,
        help="feasible samples for the convex hull (the dissertation used 12,000)",
    )
    parser.set_defaults(handler=_workspace)


def _add_workspace_kind(parser: argparse.ArgumentParser) -> None:
    from motion.pkm5.workspace import WORKSPACE_KINDS

    parser.add_argument(
        "--kind",
        choices=sorted(WORKSPACE_KINDS),
        default="constant-orientation",
        help="workspace type of the dissertation (000 §6.3)",
    )


def _ik(args: argparse.Namespace) -> int:
    import numpy as np

    from motion import pkm5

    pose = np.array([[args.x_mm, args.y_mm, args.z_mm, np.radians(args.alpha), np.radians(args.beta)]])
    result = pkm5.inverse_kinematics(pose)
    reason = result.reason(0)
    lengths = result.lengths_mm[0].tolist()
    tilts = result.tilt_deg[0].tolist()
    emit(
        {"lengths_mm": lengths, "tilt_deg": tilts, "reachable": reason is None, "reason": reason},
        args.json,
        [f"L{i + 1} = {length:9.4f} mm   tilt {tilt:8.4f} deg" for i, (length, tilt) in enumerate(zip(lengths, tilts))]
        + [f"reachable: {reason is None}"],
    )
    if reason is not None:
        raise UnreachableTarget(
            f"pose ({args.x_mm:g}, {args.y_mm:g}, {args.z_mm:g}) mm, alpha {args.alpha:g} deg, "
            f"beta {args.beta:g} deg is not reachable: {reason}"
        )
    return 0


def _fk(args: argparse.Namespace) -> int:
    import numpy as np

    from motion import pkm5

    result = pkm5.forward_kinematics(np.array([args.lengths_mm]), mode=args.mode)
    x, y, z, alpha, beta = result.pose[0]
    pose = {"x_mm": x, "y_mm": y, "z_mm": z, "alpha_deg": np.degrees(alpha), "beta_deg": np.degrees(beta)}
    pose = {key: float(value) for key, value in pose.items()}
    converged = bool(result.converged[0])
    emit(
        {
            "pose": pose,
            "converged": converged,
            "iterations": int(result.iterations[0]),
            "residual_mm": float(result.residual_mm[0]),
            "mode": str(result.mode[0]),
        },
        args.json,
        [f"{key} = {value:.4f}" for key, value in pose.items()]
        + [
            f"mode {result.mode[0]}, converged {converged}, {int(result.iterations[0])} iterations, "
            f"residual {result.residual_mm[0]:.3g} mm"
        ],
    )
    return 0 if converged else 1


def _workspace(args: argparse.Namespace) -> int:
    from motion import pkm5

    if args.samples < 1 or args.hull_points < 4:
        raise ConfigError(
            f"--samples = {args.samples}, --hull-points = {args.hull_points}, expected integers >= 1 and >= 4"
        )
    with sampling_progress(args, f"pkm5 {args.kind} workspace, samples") as progress:
        estimate = pkm5.estimate_workspace(
            args.kind, samples=args.samples, hull_points=args.hull_points, seed=args.seed, progress=progress
        )
    unit = estimate.unit.replace("^", "")
    emit(
        {
            f"volume_{unit}": estimate.volume,
            f"stderr_{unit}": estimate.stderr,
            f"hull_volume_{unit}": estimate.hull_volume,
            "kind": estimate.kind,
            "samples": estimate.samples,
            "hits": estimate.hits,
            "hull_points": len(estimate.hull_points),
        },
        args.json,
        [
            f"{estimate.kind} workspace of the PKM",
            f"  hit-or-miss (true, non-convex): {estimate.volume:,.0f} +/- {estimate.stderr:,.0f} {estimate.unit} "
            f"({estimate.hits:,} of {estimate.samples:,} box samples)",
            f"  convex hull of {len(estimate.hull_points):,} feasible samples (dissertation's method): "
            f"{estimate.hull_volume:,.0f} {estimate.unit}",
        ],
    )
    return 0
