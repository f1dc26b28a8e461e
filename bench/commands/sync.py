"""``bench sync``: push a bench's run store into the lab's PostgreSQL store (see ``bench.store.lab``).

Idempotent and resumable: run it again after a kill or a lost connection and it sends only what the server lacks.
The local file is only read. Progress (one line per committed batch) goes to stderr, the summary to stdout.
"""

from __future__ import annotations

import argparse
import sys

from bench.commands.lazy import defer
from bench.errors import ConfigError

DEFAULT_STORE = "bench.db"


def _add_batch(parser: argparse.ArgumentParser) -> None:
    """``--batch``, whose default is the store's (:data:`bench.store.lab_batches.BATCH_SAMPLES`): added when
    ``sync`` is parsed, so that building the parser imports no store module."""
    from bench.store.lab_batches import BATCH_SAMPLES

    parser.add_argument("--batch", type=int, default=BATCH_SAMPLES, help="samples per transaction")


def register(groups: argparse._SubParsersAction) -> None:
    text = "push runs, calibrations, configurations and samples to the lab's PostgreSQL store"
    sync = groups.add_parser(
        "sync", help=text, description=text, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    sync.add_argument("--store", default=DEFAULT_STORE, help="this bench's run store (SQLite file)")
    sync.add_argument(
        "--to",
        required=True,
        metavar="postgresql://USER:PASSWORD@HOST/DB",
        help="the lab store (PostgreSQL URL; a socket folder as ?host=/path)",
    )
    sync.add_argument(
        "--bench", default=None, help="this bench's name for runs of a file migrated now (default: the host name)"
    )
    defer(sync, _add_batch)
    sync.add_argument("--retries", type=int, default=3, help="reconnections after a lost connection")
    sync.add_argument(
        "--producers",
        type=int,
        default=None,
        help="processes reading and formatting the samples while they are sent, one per connection at most (default: 1 for a sync of "
        "80,000 samples or more on 4 cores or more, else 0)",
    )
    sync.set_defaults(handler=_sync)

    text = "lab-wide figures from the lab's PostgreSQL store"
    lab = groups.add_parser("lab", help=text, description=text)
    lab_commands = lab.add_subparsers(dest="lab_command", required=True, metavar="COMMAND")
    text = (
        "AP and RP (ISO 9283 7.2.1, 7.2.2) per bench, robot, week, pose, velocity and commanded position, "
        "computed by the server"
    )
    summary = lab_commands.add_parser("summary", help=text, description=text)
    summary.add_argument("--store", required=True, metavar="postgresql://USER:PASSWORD@HOST/DB", help="the lab store")
    summary.add_argument("--since", default=None, metavar="DATE", help="only runs started on or after this UTC date")
    summary.add_argument("--until", default=None, metavar="DATE", help="only runs started before this UTC date")
    summary.add_argument("--bench", default=None, help="only this bench's runs")
    summary.add_argument("--robot", default=None, help="only this robot's runs")
    summary.add_argument("--json", action="store_true", help="one JSON object per group")
    summary.set_defaults(
        handler=_lab_summary, lab_store_only=True
    )  # its --store is a URL: a file gets the URL's refusal


def _sync(args: argparse.Namespace) -> int:
    from bench.store import Store
    from bench.store.lab import check_lab_url, redacted, sync_store
    from bench.store.lab_sync import LANES

    check_lab_url(args.to, "--to")
    if args.batch < 1:
        raise ConfigError(f"--batch {args.batch}: expected a positive number of samples")
    if args.retries < 0:
        raise ConfigError(f"--retries {args.retries}: expected 0 or more")
    if args.producers is not None and not 0 <= args.producers <= LANES:
        raise ConfigError(f"--producers {args.producers}: expected a number from 0 to {LANES}")
    # read-only: sync never writes the local file, and a path that names no store is refused, never created
    with Store(args.store, bench=args.bench, read_only=True) as store:
        result = sync_store(
            store,
            args.to,
            batch_size=args.batch,
            retries=args.retries,
            producers=args.producers,
            progress=lambda line: print(line, file=sys.stderr, flush=True),
        )
    print(
        f"synced {result.runs} runs, {result.calibrations} calibrations, {result.samples_sent} new samples "
        f"in {result.seconds:.2f} s ({result.samples_per_s:,.0f} samples/s) to {redacted(args.to)}"
    )
    return 0


def _iso_date(option: str, text: str | None) -> str | None:
    from datetime import datetime

    if text is not None:
        try:
            datetime.fromisoformat(text)
        except ValueError:
            raise ConfigError(f"{option} {text}: expected an ISO date such as 2026-11-01") from None
    return text


def _lab_summary(args: argparse.Namespace) -> int:
    import json

    from bench.store.lab import LabStore, check_lab_url
    from bench.store.lab_summary import pose_summary

    check_lab_url(args.store, "--store")
    since, until = _iso_date("--since", args.since), _iso_date("--until", args.until)
    with LabStore(args.store) as lab:
        groups = pose_summary(lab, since=since, until=until, bench=args.bench, robot=args.robot)
    if args.json:
        for group in groups:
            print(json.dumps(group.as_dict(), default=str))
        return 0
    print(
        f"{'bench':<12} {'robot':<7} {'week':<10} {'pose':<6} {'velocity_pct':>12} {'n':>7} {'AP_mm':>9} {'RP_mm':>9}"
    )
    for g in groups:
        velocity = "-" if g.velocity_pct is None else f"{g.velocity_pct:g}"
        rp = "n<2" if g.rp_mm is None else f"{g.rp_mm:.4f}"
        print(
            f"{g.bench:<12} {g.robot:<7} {g.week.isoformat():<10} {g.pose or '-':<6} {velocity:>12} {g.n:>7} "
            f"{g.ap_mm:9.4f} {rp:>9}"
        )
    return 0
