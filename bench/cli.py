"""Command-line entry point: parses arguments, configures logging, and turns errors into one line.

Each command group lives in ``bench/commands/<group>.py`` and exposes ``register(subparsers)``; its handlers
return an exit code. Results and paths go to stdout, progress to stderr. A ``BenchError`` (or a
``MotionInputError``) is printed as one line, exit 2 for bad input and 1 for failures; ``--debug`` shows the
traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from bench.commands.lazy import DeferredParser
from bench.errors import BenchError, ConfigError
from motion.errors import MotionInputError

#: Command groups, in the order the help lists them.
COMMAND_MODULES = (
    "bench.commands.kin",
    "bench.commands.analyze",
    "bench.commands.sim",
    "bench.commands.sensors",
    "bench.commands.campaign",
    "bench.commands.station",
    "bench.commands.sync",
    "bench.commands.demo",
    "bench.commands.report",
    "bench.commands.gui",
    "bench.commands.calibrate",
    "bench.commands.store",
)


class _VersionAction(argparse.Action):
    """``--version``: looks the installed version up only when asked (importlib.metadata costs ~40 ms)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, **kwargs) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:  # noqa: ANN001 - argparse's signature
        from bench import __version__

        sys.stdout.write(f"bench {__version__}\n")  # on stdout, as argparse's own version action
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The whole ``bench`` parser; cheap: command modules import their heavy modules in their handlers, and
    arguments that need one are added when their sub-command is parsed (bench/commands/lazy.py)."""
    parser = DeferredParser(
        prog="bench",
        description="Test-bench DAQ and metrology for parallel robots (units: mm, degrees).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--version", action=_VersionAction, help="show the version and exit")
    parser.add_argument("--debug", action="store_true", help="show tracebacks instead of one-line errors")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more progress output on stderr")
    groups = parser.add_subparsers(dest="group", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(groups)
    return parser


def _check_store_urls(args: argparse.Namespace) -> None:
    """A ``--store`` or ``--to`` that is a URL must be a well-formed PostgreSQL one: one line, exit 2, the password
    hidden, before any command opens anything (a file path is each command's to check)."""
    for option in ("store", "to"):
        spec = getattr(args, option, None)
        if isinstance(spec, str) and "://" in spec:
            from bench.store.lab import check_lab_url

            check_lab_url(spec, f"--{option}")


def existing_store(path: str) -> str:
    """``path`` when a store file is there; else one line: a command that reads runs never creates an empty store
    where a typo pointed (only the commands that start runs, marked ``creates_store``, may make a new one)."""
    if not Path(path).exists():
        hint = " (the demo's runs are in demo-out/bench.db)" if Path("demo-out/bench.db").exists() else ""
        raise ConfigError(f"--store {path}: no run store there{hint}, expected the bench.db a run wrote (--store)")
    return path


def _refuse_missing_store(args: argparse.Namespace) -> None:
    """Every command with a ``--store`` file reads an existing store unless it is marked ``creates_store``."""
    spec = getattr(args, "store", None)
    if isinstance(spec, str) and "://" not in spec and not getattr(args, "creates_store", False):
        existing_store(spec)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    import logging  # after parsing: --help and --version never need it

    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        _check_store_urls(args)
        _refuse_missing_store(args)
        return int(args.handler(args) or 0)
    except (BenchError, MotionInputError) as exc:
        if args.debug:
            raise
        print(f"bench: error: {exc}", file=sys.stderr)
        return getattr(exc, "exit_code", 2)
    except KeyboardInterrupt:
        print("bench: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        sqlite3 = sys.modules.get("sqlite3")  # the last net for a database error no store call named: one line
        if args.debug or sqlite3 is None or not isinstance(exc, sqlite3.Error):
            raise
        print(f"bench: error: database: {exc}; check the store with `bench store check STORE`", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
