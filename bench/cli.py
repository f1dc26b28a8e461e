"""Command-line entry point: parses arguments, configures logging, and turns errors into one line.

Each command group lives in ``bench/commands/<group>.py`` and exposes ``register(subparsers)``; its handlers
return an exit code. Results and paths go to stdout, progress to stderr. A ``BenchError`` (or a
``MotionInputError``) is printed as one line, exit 2 for bad input and 1 for failures; ``--debug`` shows the
traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from bench import __version__
from bench.errors import BenchError
from motion.errors import MotionInputError

#: Command groups, in the order the help lists them.
COMMAND_MODULES = (
    "bench.commands.kin",
    "bench.commands.analyze",
    "bench.commands.sim",
    "bench.commands.sensors",
    "bench.commands.campaign",
    "bench.commands.demo",
    "bench.commands.report",
    "bench.commands.gui",
    "bench.commands.calibrate",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bench",
        description="Test-bench DAQ and metrology for parallel robots (units: mm, degrees).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"bench {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks instead of one-line errors")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more progress output on stderr")
    groups = parser.add_subparsers(dest="group", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(groups)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        return int(args.handler(args) or 0)
    except (BenchError, MotionInputError) as exc:
        if args.debug:
            raise
        print(f"bench: error: {exc}", file=sys.stderr)
        return getattr(exc, "exit_code", 2)
    except KeyboardInterrupt:
        print("bench: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
