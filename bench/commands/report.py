"""``bench report RUN_ID``: the HTML and PDF report of a stored run (or ``--compare`` two runs side by side).

Reads the run store only (no hardware). Pose runs get the ISO 9283 layout; ``actuator_accuracy``, ``payload_ladder``,
``lasergrid_hits``, ``delta_positioning`` and ``iso9283_stabilisation`` runs their own (docs/reports.md). Writes ``report_run<ID>.html``/``.pdf`` and the raw data
``run<ID>_samples.csv`` into ``--out`` and prints their paths on stdout, one per line. ``--compare`` works for
every layout (two runs of the same kind).
"""

from __future__ import annotations

import argparse
import sys
import time

from bench.commands.lazy import defer
from bench.errors import ConfigError

DEFAULT_STORE = "bench.db"


def register(groups: argparse._SubParsersAction) -> None:
    parser = groups.add_parser(
        "report",
        help="HTML/PDF report of a stored run, or two runs compared",
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("run_id", metavar="RUN", help="the run to report: its id, BENCH/ID or its UUID (prefix)")
    defer(parser, _add_arguments)
    parser.set_defaults(handler=_report)


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """Added when ``bench report`` is parsed: the choices come from bench.reports (matplotlib, reportlab)."""
    from bench.reports import ALL_CRITERIA, FORMATS
    from bench.reports.decision import DECISION_RULES

    parser.add_argument(
        "--compare",
        metavar="RUN_B",
        default=None,
        help="second run: write a side-by-side comparison of RUN_ID (A) and RUN_B (B)",
    )
    parser.add_argument(
        "--trend",
        metavar="RUN",
        nargs="+",
        default=None,
        help="more pose runs: write the trend of RUN_ID and these (drift across days)",
    )
    parser.add_argument("--format", choices=(*FORMATS, "all"), default="all", help="report format(s)")
    parser.add_argument("--out", default="reports", help="folder for the report and its raw data")
    parser.add_argument(
        "--store",
        default=DEFAULT_STORE,
        help="run store: SQLite file, or the lab store (postgresql://USER:PASSWORD@HOST/DB)",
    )
    parser.add_argument(
        "--criterion",
        action="append",
        default=[],
        metavar="NAME=LIMIT",
        help=f"project acceptance criterion (an upper limit), repeatable; NAME in {', '.join(ALL_CRITERIA)} "
        "(each layout takes its own: docs/reports.md)",
    )
    identity = parser.add_argument_group(
        "device under test and people (page 1; default: the run's stored "
        "settings.dut, else an empty line to fill in by hand)"
    )
    identity.add_argument("--dut-serial", default=None, metavar="TEXT", help="robot serial number or asset tag")
    identity.add_argument("--customer", default=None, metavar="TEXT", help="customer the robot is tested for")
    identity.add_argument("--order", default=None, metavar="TEXT", help="order or job number")
    identity.add_argument(
        "--measuring-point",
        default=None,
        metavar="TEXT",
        help="point measured (TCP / reference point, ISO 9283 6.3); default: the robot's stored tcp "
        "setting, else the platform centre of the kinematic model",
    )
    identity.add_argument("--operator", default=None, metavar="TEXT", help="operator named in the report")
    identity.add_argument(
        "--lab", "--laboratory", dest="laboratory", default=None, metavar="TEXT", help="laboratory named in the report"
    )
    parser.add_argument(
        "--decision-rule",
        choices=DECISION_RULES,
        default=DECISION_RULES[0],
        help="how the verdict uses U: simple acceptance (ILAC-G8 4.2.1) or guarded acceptance "
        "(ISO 14253-1: pass / not proven / fail)",
    )
    parser.add_argument("--k", type=float, default=2.0, help="coverage factor of the expanded uncertainties")
    parser.add_argument(
        "--band-mm",
        type=float,
        nargs="+",
        default=None,
        metavar="MM",
        help="stabilisation and positioning-time runs: limit bands (default: the ISO comparison bands 0.1 0.5 1)",
    )
    parser.add_argument(
        "--hysteresis-mm",
        type=float,
        default=None,
        metavar="MM",
        help="stabilisation and positioning-time runs: band-edge hysteresis (default: one count of "
        "the run's instrument, 25.4/cpi mm, from its calibration or settings; 0 without one)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.add_argument(
        "--allow-unknown",
        action="store_true",
        help="report even when the run lacks what a deviations row needs (row printed as unknown)",
    )


def parse_criteria(items: list[str]) -> dict[str, float]:
    """``["AP_mm=0.5", "RP_mm=0.2"]`` -> ``{"AP_mm": 0.5, "RP_mm": 0.2}``, refusing unknown names and non-numbers."""
    from bench.reports import ALL_CRITERIA
    from bench.reports.decision import unit_of

    criteria = {}
    for item in items:
        name, _, value = item.partition("=")
        if name not in ALL_CRITERIA:
            raise ConfigError(
                f"--criterion {item}: unknown name {name!r}, expected NAME=LIMIT with NAME in {', '.join(ALL_CRITERIA)}"
            )
        try:
            criteria[name] = float(value)
        except ValueError:
            raise ConfigError(f"--criterion {item}: {value!r} is not a number of {unit_of(name)}") from None
    return criteria


def _identity(args: argparse.Namespace) -> dict[str, str | None]:
    """Page 1's identity options as given (None where not)."""
    return {
        name: getattr(args, name)
        for name in ("dut_serial", "customer", "order", "operator", "laboratory", "measuring_point")
    }


def _progress(started: float):
    def say(message: str) -> None:
        print(f"bench report: {time.monotonic() - started:5.1f} s  {message}", file=sys.stderr, flush=True)

    return say


def _report(args: argparse.Namespace) -> int:
    from bench.reports import FORMATS
    from bench.store.lab import is_lab_url
    from bench.store.lab_reader import open_named_runs

    started = time.monotonic()
    progress = (lambda message: None) if args.quiet else _progress(started)
    formats = FORMATS if args.format == "all" else (args.format,)
    criteria = parse_criteria(args.criterion)
    names = [args.run_id, *([args.compare] if args.compare is not None else []), *(args.trend or [])]
    if is_lab_url(args.store) or not all(str(name).isdigit() for name in names):
        store, ids = open_named_runs(args.store, names)
        with store:
            return _write(args, store, ids, formats, criteria, progress)
    return _write(args, args.store, [int(name) for name in names], formats, criteria, progress)


def _write(args: argparse.Namespace, store, ids: list[int], formats, criteria, progress) -> int:
    """Write what ``args`` ask for, of the runs ``ids`` of ``store`` (a path, a Store or a lab-store view)."""
    from bench.reports import write_comparison, write_report, write_trend

    run_id, others = ids[0], ids[1:]
    if args.trend is not None:
        if criteria or args.compare is not None:
            raise ConfigError("--trend: not used with --criterion or --compare")
        paths = write_trend(store, ids, args.out, formats, k=args.k, progress=progress)
    elif args.compare is not None:
        if criteria:
            raise ConfigError("--criterion: not used with --compare; report each run on its own for a decision")
        if args.band_mm is not None or args.hysteresis_mm is not None:
            raise ConfigError(
                "--band-mm/--hysteresis-mm: not used with --compare; report each run on its own for other bands"
            )
        paths = write_comparison(
            store, run_id, others[0], args.out, formats, k=args.k, identity=_identity(args), progress=progress
        )
    else:
        identity = _identity(args)
        paths = write_report(
            store,
            run_id,
            args.out,
            formats,
            criteria=criteria,
            k=args.k,
            allow_unknown=args.allow_unknown,
            bands_mm=args.band_mm,
            hysteresis_mm=args.hysteresis_mm,
            identity=identity,
            decision_rule=args.decision_rule,
            progress=progress,
        )
    for path in (paths.html, paths.pdf, *paths.csv):
        if path is not None:
            print(path)
    progress("done")
    return 0
