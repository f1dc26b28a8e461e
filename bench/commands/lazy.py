"""Sub-command parsers that add their arguments on first use, so ``bench --help`` imports no heavy module.

Building the whole ``bench`` parser must stay cheap (``bench --version`` within a few times ``python -c pass``,
benchmarks/bench_cli_start.py): a command module imports only the standard library and ``bench.errors`` at its top,
imports numpy, pandas, scipy, matplotlib and the like inside its handler, and where its *arguments* need a heavy
module (choices read from a robot model, a simulator's own options) it hands them to :func:`defer`. The deferred
arguments are added when that sub-command is parsed (or its ``--help`` is asked for), which is exactly when its
handler is going to import the same modules anyway.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

ArgumentFiller = Callable[[argparse.ArgumentParser], None]


class DeferredParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` that runs its pending fillers before it parses, prints help or reports usage.

    ``add_subparsers`` makes sub-parsers of ``type(self)``, so one ``DeferredParser`` at the root makes every parser
    of the tree deferrable.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pending: list[ArgumentFiller] = []

    def defer(self, filler: ArgumentFiller) -> None:
        """Run ``filler(self)`` on first use (it adds arguments or defaults; it may import heavy modules)."""
        self._pending.append(filler)

    def fill(self) -> argparse.ArgumentParser:
        """Add every deferred argument now (idempotent); returns the parser."""
        while self._pending:
            self._pending.pop(0)(self)
        return self

    def parse_known_args(self, args=None, namespace=None):  # noqa: ANN001, ANN201 - argparse's signature
        self.fill()
        return super().parse_known_args(args, namespace)

    def format_usage(self) -> str:
        self.fill()
        return super().format_usage()

    def format_help(self) -> str:
        self.fill()
        return super().format_help()


def defer(parser: argparse.ArgumentParser, filler: ArgumentFiller) -> None:
    """Add ``filler``'s arguments to ``parser`` when it is first used, or now if it is a plain ``ArgumentParser``."""
    if isinstance(parser, DeferredParser):
        parser.defer(filler)
    else:
        filler(parser)
