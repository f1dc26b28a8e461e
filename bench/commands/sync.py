"""``bench sync``: push a bench's run store into the lab's PostgreSQL store (see ``bench.store.lab``).

Idempotent and resumable: run it again after a kill or a lost connection and it sends only what the server lacks.
The local file is only read. Progress (one line per committed batch) goes to stderr, the summary to stdout.
"""

from __future__ import annotations

import argparse
import sys

from bench.errors import ConfigError

DEFAULT_STORE = "bench.db"


def register(groups: argparse._SubParsersAction) -> None:
    text = "push runs, calibrations, configurations and samples to the lab's PostgreSQL store"
    sync = groups.add_parser("sync", help=text, description=text,
                             formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    sync.add_argument("--store", default=DEFAULT_STORE, help="this bench's run store (SQLite file)")
    sync.add_argument("--to", required=True, metavar="postgresql://USER:PASSWORD@HOST/DB",
                      help="the lab store (PostgreSQL URL; a socket folder as ?host=/path)")
    sync.add_argument("--bench", default=None, help="this bench's name for runs of a file migrated now "
                                                    "(default: the host name)")
    sync.add_argument("--batch", type=int, default=20_000, help="samples per transaction")
    sync.add_argument("--retries", type=int, default=3, help="reconnections after a lost connection")
    sync.set_defaults(handler=_sync)


def _sync(args: argparse.Namespace) -> int:
    from bench.store import Store
    from bench.store.lab import is_lab_url, redacted, sync_store

    if not is_lab_url(args.to):
        raise ConfigError(f"--to {args.to}: expected a postgresql://USER:PASSWORD@HOST/DBNAME URL")
    if args.batch < 1:
        raise ConfigError(f"--batch {args.batch}: expected a positive number of samples")
    if args.retries < 0:
        raise ConfigError(f"--retries {args.retries}: expected 0 or more")
    with Store(args.store, bench=args.bench) as store:
        result = sync_store(store, args.to, batch_size=args.batch, retries=args.retries,
                            progress=lambda line: print(line, file=sys.stderr, flush=True))
    print(f"synced {result.runs} runs, {result.calibrations} calibrations, {result.samples_sent} new samples "
          f"in {result.seconds:.2f} s ({result.samples_per_s:,.0f} samples/s) to {redacted(args.to)}")
    return 0
