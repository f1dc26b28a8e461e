"""Time to the first window of ``bench gui`` (the loading window) and to the main window, against the floor of a
bare Qt window (PySide6 started, one label shown), in fresh processes; min / median / max of ``--repeat`` runs.

Run with a display (``xvfb-run -a python benchmarks/bench_gui_startup.py``); each child prints the seconds since
its interpreter started (``time.perf_counter`` against the process start time from ``/proc/self/stat``) when the
window is shown, then quits.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: Seconds since this process started (Linux: its start time in clock ticks since boot, /proc/self/stat field 22).
_SINCE_START = """
import os, time
def since_start():
    ticks = int(open('/proc/self/stat').read().rsplit(')', 1)[1].split()[19])
    uptime = float(open('/proc/uptime').read().split()[0])
    return uptime - ticks / os.sysconf('SC_CLK_TCK')
"""

FLOOR = (
    _SINCE_START
    + """
from PySide6.QtWidgets import QApplication, QLabel
app = QApplication([])
label = QLabel("floor"); label.show(); app.processEvents()
print(f"{since_start():.3f} {since_start():.3f}")
"""
)

BENCH_GUI = (
    _SINCE_START
    + """
import sys
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QLabel
shown = {}
_show = QLabel.show
def show(self):
    _show(self)
    shown.setdefault("first", since_start())
QLabel.show = show
def main_window():
    from bench.gui.app import MainWindow
    for widget in QApplication.topLevelWidgets():
        if isinstance(widget, MainWindow) and widget.isVisible():
            shown["main"] = since_start()
            widget.close()
            return
    QTimer.singleShot(10, main_window)
app = QApplication([])
QTimer.singleShot(0, main_window)
from bench.gui import launch
launch(sys.argv[1], sys.argv[2])
print(f"{shown['first']:.3f} {shown['main']:.3f}")
"""
)


def _run(script: str, folder: str) -> tuple[float, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run(
        [sys.executable, "-c", script, f"{folder}/b.db", f"{folder}/reports"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    first, main = (float(v) for v in done.stdout.split()[-2:])
    return first, main


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    repeat = parser.parse_args().repeat
    with tempfile.TemporaryDirectory() as folder:
        floor = np.array([_run(FLOOR, folder)[0] for _ in range(repeat)])
        gui = np.array([_run(BENCH_GUI, folder) for _ in range(repeat)])
    for name, values in (
        ("bare Qt window (floor)", floor),
        ("bench gui: first window", gui[:, 0]),
        ("bench gui: main window", gui[:, 1]),
    ):
        print(
            f"{name:28s} min {values.min():6.2f} s  median {np.median(values):6.2f} s  max {values.max():6.2f} s"
            f"  ratio to floor (median) {np.median(values) / np.median(floor):5.2f}"
        )


if __name__ == "__main__":
    main()
