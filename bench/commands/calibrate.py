"""``bench calibrate RUN_ID``: identify the robot's geometry (pkm5, delta4) from a stored run of commanded and
measured poses.

Identifies the geometry (``--fit map``, the default: every parameter, the manufacturing tolerances as the prior;
``--fit free-set``, the default with ``--free``: the free parameters, default what the pose set and instrument can
identify; docs/calibration.md) and stores the result as a new version of the calibration ``pkm5_kinematics`` /
``delta4_kinematics`` with the source run, the residuals, the observability, the fit and its prior
(:func:`bench.calibration.identify.identify_run`, the window's "Identify" button runs the same).
Heavy modules load inside the handler.
"""

from __future__ import annotations

import argparse
import json

from bench.calibration.identify import DEFAULT_TARGET_GAIN, DEFAULT_UNCERTAINTY_MM, FITS

DEFAULT_STORE = "bench.db"


def register(groups: argparse._SubParsersAction) -> None:
    parser = groups.add_parser(
        "calibrate",
        help="identify the robot geometry (pkm5, delta4) from a stored run of measured poses",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("run_id", metavar="RUN_ID", type=int, help="the run with commanded and measured poses")
    parser.add_argument(
        "--fit",
        choices=FITS,
        default=None,
        help="map: maximum a posteriori of every parameter with the manufacturing tolerances as "
        "the prior (the default); free-set: least squares of the free parameters, the others "
        "held at their documented values (the default with --free)",
    )
    parser.add_argument(
        "--free",
        nargs="+",
        metavar="PARAM",
        default=None,
        help="free parameters (default: every one for --fit map, the identifiable set for "
        "--fit free-set); see docs/calibration.md",
    )
    parser.add_argument(
        "--uncertainty-mm",
        type=float,
        default=None,
        help="the instrument's standard uncertainty per reading and axis, mm, the floor of the "
        "measured scatter each pose's mean is weighted by (default: pkm5 mice "
        f"{DEFAULT_UNCERTAINTY_MM:g}; delta4: the run's instrument, camera plane calibration "
        "RMS or laser-grid window / sqrt 3)",
    )
    parser.add_argument(
        "--target-gain",
        type=float,
        default=DEFAULT_TARGET_GAIN,
        help="the held-out AP gain the printed campaign plan (cycles per pose, robot time) is for",
    )
    parser.add_argument("--store", default=DEFAULT_STORE, help="run store (SQLite file)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from bench.calibration.identify import check_uncertainty, identify_run, summary_lines
    from bench.errors import ConfigError
    from bench.store import Store

    check_uncertainty(args.uncertainty_mm)
    if not 1 < args.target_gain < float("inf"):
        raise ConfigError(
            f"--target-gain = {args.target_gain!r}, expected a number above 1 (the held-out AP before / after)"
        )
    with Store(args.store) as store:
        identified = identify_run(
            store,
            args.run_id,
            free=args.free,
            uncertainty_mm=args.uncertainty_mm,
            fit=args.fit,
            target_gain=args.target_gain,
        )
    if args.json:
        record = identified.record
        print(json.dumps({"calibration": record.name, "version": record.version, "id": record.id, **identified.params}))
        return 0
    print("\n".join(summary_lines(identified)))
    return 0
