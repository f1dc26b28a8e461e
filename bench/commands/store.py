"""``bench store check STORE``: SQLite's integrity and foreign-key checks of a run store, one line per problem."""

from __future__ import annotations

import argparse
import sys


def register(groups: argparse._SubParsersAction) -> None:
    store = groups.add_parser("store", help="check a run store file", description="check a run store file")
    actions = store.add_subparsers(dest="store_action", metavar="ACTION", required=True)
    check = actions.add_parser(
        "check",
        help="integrity and foreign-key checks; one line per problem (exit 1)",
        description="PRAGMA integrity_check and foreign_key_check, read-only",
    )
    check.add_argument(
        "path", metavar="STORE", help="the run store (SQLite file), or a lab store (postgresql://...): its checksums"
    )
    check.set_defaults(handler=_check)


def _check(args: argparse.Namespace) -> int:
    from bench.store.connection import check_store
    from bench.store.lab import LabStore, check_lab_url, redacted

    notes: list[str] = []
    if "://" in args.path:  # any URL (mysql:// too) is a lab address to check, its password hidden, not a file
        check_lab_url(args.path, "STORE")
        with LabStore(args.path) as lab:
            problems, notes = lab.check_records()
            damaged_samples, sample_notes = lab.check_samples()
        problems += damaged_samples
        notes += sample_notes
        args.path = redacted(args.path)
    else:
        problems = check_store(args.path, option="STORE")
    for line in notes:
        print(line, file=sys.stderr)
    for line in problems:
        print(line)
    if problems:
        print(f"bench: {len(problems)} problem(s) in {args.path}; work on a backup copy", file=sys.stderr)
        return 1
    print(f"{args.path}: ok")
    return 0
