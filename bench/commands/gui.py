"""``bench gui``: open the desktop window on a run store (needs PySide6 and a display)."""

from __future__ import annotations

import argparse

from bench.extras import ensure_installed


def register(groups: argparse._SubParsersAction) -> None:
    gui = groups.add_parser(
        "gui",
        help="open the desktop window (campaigns, live view, calliper, results)",
        description=__doc__,
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    gui.add_argument("--store", default="bench.db", help="run store (SQLite file)")
    gui.add_argument("--reports", default="reports", help="folder for the reports opened from the window")
    gui.set_defaults(handler=_gui, creates_store=True)  # the window starts runs: a new store is its to make


def _gui(args: argparse.Namespace) -> int:
    ensure_installed("PySide6")
    from bench.gui import launch

    return launch(args.store, args.reports)
