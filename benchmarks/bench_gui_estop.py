"""The window's emergency stop under load (issue 31): press -> STOP on the wire, and the longest event-loop block of
the window's thread during a run.

Run with a display: ``xvfb-run -a python benchmarks/bench_gui_estop.py [--presses 200] [--burners 2]``.

Stop latency: the window (``bench gui``'s MainWindow) is shown with its live view redrawing all the time (a feeder
thread hands it a simulated run's pose samples, 20 a second, through a queued signal as the campaign worker does),
the robot panel is connected to the simulated pkm5, and ``--burners`` processes spin on the CPUs. A presser thread
posts a real mouse press on the e-stop button into the window's event queue (``QCoreApplication.postEvent``, as
the X server's event arrives) at a random moment and notes the time; the STOP line's write on the controller's link
notes the time it returned (on the pty). Between presses the latch is reset and the robot's latch released.
The floor: the same robot's ``emergency_stop()`` called from a plain thread (no window), press -> STOP, same load.

Event-loop block: a simulated campaign (``iso9283_pose_quick``, ``--cycles``, the default speed factor) runs from
the window with the live view visible; a 10 ms QTimer probe records how late each of its ticks came; the longest
lateness is the longest time the window's thread could not answer (an e-stop click included).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import random
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from PySide6.QtCore import QCoreApplication, QEvent, QEventLoop, QObject, QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import QApplication

PROBE_MS = 10


def _burn() -> None:
    while True:
        pass


def _serve(ms: int) -> None:
    loop = QEventLoop()
    QTimer.singleShot(ms, loop.quit)
    loop.exec()


def _wait(predicate, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise SystemExit(f"bench_gui_estop: timed out waiting for {what}")
        _serve(10)


class _StopTimes:
    """perf_counter of each STOP write on the link (once written)."""

    def __init__(self, controller) -> None:
        self.times: list[float] = []
        self.written = threading.Condition()  # the presser sleeps on it: no polling thread beside the window's
        link, write = controller.link, controller.link.write

        def noting(data: bytes, *, command: str, **options) -> None:
            write(data, command=command, **options)
            if command == "STOP":
                self.times.append(time.perf_counter())
                with self.written:
                    self.written.notify_all()

        link.write = noting


class _Feeder(QObject):
    sample = Signal(dict)


def _pose_sample(index: int, rng: np.random.Generator) -> dict:
    pose, cycle = index % 5, index // 5
    values = {
        "x_mm": 110.0 + rng.normal(0, 0.05),
        "y_mm": 10.0 * pose + rng.normal(0, 0.05),
        "z_mm": 320.0 + rng.normal(0, 0.05),
        "cmd_x_mm": 110.0,
        "cmd_y_mm": 10.0 * pose,
        "cmd_z_mm": 320.0,
    }
    return {
        "step_index": index,
        "kind": "pose",
        "pose": f"P{pose + 1}",
        "cycle": cycle + 1,
        "t_s": float(index),
        "wall_s": time.time(),
        "values": values,
    }


def stop_latency(window, presses: int) -> tuple[list[float], list[float]]:
    """(window press -> STOP on the wire, direct emergency_stop -> STOP on the wire), seconds each."""
    panel = window.robot_panel
    panel.connect_robot()
    _wait(lambda: panel.mover is not None and not panel.busy(), 60, "the simulator connection")
    mover = panel.mover
    stops = _StopTimes(mover.controller)
    feeder, running = _Feeder(), threading.Event()
    feeder.sample.connect(window.live_view.add_sample)
    window.live_view.clear("bench", started_s=time.time())
    running.set()

    def feed() -> None:
        rng, index = np.random.default_rng(1), 0
        while running.is_set():
            feeder.sample.emit(_pose_sample(index, rng))
            index += 1
            time.sleep(0.05)

    threading.Thread(target=feed, daemon=True).start()
    button = window.estop
    centre = QPointF(button.width() / 2, button.height() / 2)
    through_window, direct = [], []
    rng = random.Random(7)

    def one(press) -> float:
        before = len(stops.times)
        time.sleep(rng.uniform(0.02, 0.3))  # a random moment of the redraw cycle
        started = time.perf_counter()
        with stops.written:
            press()
            stops.written.wait_for(lambda: len(stops.times) > before, 10)
        return stops.times[before] - started if len(stops.times) > before else float("inf")

    def post_press() -> None:
        for kind in (QEvent.Type.MouseButtonPress, QEvent.Type.MouseButtonRelease):
            QCoreApplication.postEvent(
                button,
                QMouseEvent(
                    kind,
                    centre,
                    button.mapToGlobal(centre),
                    Qt.MouseButton.LeftButton,
                    Qt.MouseButton.LeftButton,
                    Qt.KeyboardModifier.NoModifier,
                ),
            )

    done = threading.Event()

    def presser() -> None:
        for _ in range(presses):
            through_window.append(one(post_press))
            window.estop_latch.reset()
            mover.release_stop()
        for _ in range(presses):
            direct.append(one(mover.emergency_stop))
            mover.release_stop()
        done.set()

    threading.Thread(target=presser, daemon=True).start()
    _wait(done.is_set, 60 + presses * 5, "the presses")
    running.clear()
    print(f"  live view pictures drawn meanwhile: {window.live_view.renders}")
    panel.disconnect_robot()
    return through_window, direct


def _probe() -> tuple[QTimer, list[float], list[float], list[float]]:
    """A 10 ms probe timer (not started) and its lists: lateness of each tick (s), its time, the last tick."""
    lateness, at, last = [], [], [time.perf_counter()]

    def tick() -> None:
        now = time.perf_counter()
        lateness.append(max(0.0, now - last[0] - PROBE_MS / 1000))
        at.append(now)
        last[0] = now

    probe = QTimer()
    probe.setTimerType(Qt.TimerType.PreciseTimer)
    probe.timeout.connect(tick)
    return probe, lateness, at, last


def idle_blocks(seconds: float) -> list[float]:
    """The floor: the same probe for ``seconds`` with the window idle (no run, no redraw), same load."""
    probe, lateness, _, last = _probe()
    last[0] = time.perf_counter()
    probe.start(PROBE_MS)
    _serve(round(seconds * 1000))
    probe.stop()
    return lateness


def event_loop_blocks(window, cycles: int) -> tuple[list[float], float]:
    """Lateness of each 10 ms probe tick during one simulated campaign from the window, seconds; its duration."""
    probe, lateness, at, last = _probe()
    panel = window.campaign_panel
    panel.choose_file(Path(__file__).resolve().parents[1] / "examples" / "iso9283_pose_quick.toml")
    panel.form.set_value("cycles", str(cycles))
    panel.form.set_value("settle_s", "0")
    window.tabs.setCurrentWidget(window.live_view)
    panel.start()
    last[0] = time.perf_counter()
    probe.start(PROBE_MS)
    started = last[0]
    _wait(lambda: panel.worker is None, 600, "the campaign")
    probe.stop()
    print(
        f"  campaign: {panel.last_outcome} in {at[-1] - started:.1f} s; live view pictures: {window.live_view.renders}"
    )
    longest = sorted(range(len(lateness)), key=lateness.__getitem__)[-3:]
    print(
        "  longest blocks: "
        + ", ".join(f"{lateness[i] * 1000:.0f} ms at {at[i] - started:.2f} s" for i in reversed(longest))
    )
    return lateness, at[-1] - started


def _figures(seconds: list[float]) -> str:
    ms = np.asarray(seconds) * 1000
    return (
        f"p50 {np.percentile(ms, 50):.1f} ms, p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms "
        f"(min {ms.min():.1f} ms, n = {len(ms)})"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presses", type=int, default=200)
    parser.add_argument("--burners", type=int, default=2)
    parser.add_argument("--cycles", type=int, default=20, help="cycles of the campaign of the event-loop part")
    args = parser.parse_args()
    if not os.environ.get("DISPLAY"):
        print("bench_gui_estop: needs an X server (xvfb-run -a python benchmarks/bench_gui_estop.py)", file=sys.stderr)
        return 2
    from bench.gui.app import MainWindow

    burners = [multiprocessing.Process(target=_burn, daemon=True) for _ in range(args.burners)]
    for burner in burners:
        burner.start()
    app = QApplication.instance() or QApplication(["bench-estop"])
    try:
        with tempfile.TemporaryDirectory() as tmp:
            window = MainWindow(Path(tmp) / "bench.db", Path(tmp) / "reports", open_files=False)
            window.show()
            window.tabs.setCurrentWidget(window.live_view)
            _serve(500)
            print(
                f"bench_gui_estop: {args.burners} CPU burners on {os.cpu_count()} CPUs, platform {app.platformName()}"
            )
            through_window, direct = stop_latency(window, args.presses)
            print(f"press -> STOP on the wire, through the window: {_figures(through_window)}")
            print(f"floor, emergency_stop() from a plain thread:   {_figures(direct)}")
            print(f"  ratio of medians window / floor: {np.median(through_window) / np.median(direct):.2f}")
            lateness, seconds = event_loop_blocks(window, args.cycles)
            print(f"event-loop block during a run ({PROBE_MS} ms probe, its lateness): {_figures(lateness)}")
            floor = idle_blocks(seconds)
            print(f"floor, the same probe with the window idle, as long:  {_figures(floor)}")
            print(f"  ratio of maxima run / idle: {max(lateness) / max(max(floor), 1e-6):.2f}")
            window.close()
            _serve(200)
    finally:
        for burner in burners:
            burner.terminate()
    return 0


if __name__ == "__main__":
    sys.exit(main())
