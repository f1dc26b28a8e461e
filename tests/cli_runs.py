"""``bench run`` in a child process, for the tests that signal, kill or copy a run while it writes; a store's SQL dump,
for the tests that a refused command writes nothing."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from bench.store import Store

#: The ``bench`` entry point of this environment.
BENCH = str(Path(sys.executable).with_name("bench"))
ROOT = Path(__file__).resolve().parents[1]
#: The quick ISO pose protocol and the mice station these child runs rehearse.
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
STATION = ROOT / "examples" / "stations" / "pkm5_mice.toml"


def start_station_run(store: Path, speed_factor: str, *, stdin: int = subprocess.DEVNULL) -> subprocess.Popen:
    """``bench run`` of :data:`QUICK` on :data:`STATION` rehearsed (``--sim``) in a child process writing ``store``;
    ``stdin`` a pipe for a test that answers its prompts."""
    return subprocess.Popen(
        [BENCH, "run", str(QUICK), "--station", str(STATION), "--sim", "--store", str(store), "--no-progress"]
        + ["--speed-factor", speed_factor],
        stdin=stdin,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def wait_for_samples(store: Path, process: subprocess.Popen, at_least: int, timeout_s: float = 60.0) -> None:
    """Wait until the first run of ``store`` holds ``at_least`` samples; fails naming the count if ``process`` ends
    first or the time runs out (the process is then killed)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()
        if store.exists():
            with Store(store) as opened:
                runs = opened.runs()
                if runs and runs[0].n_samples >= at_least:
                    return
        time.sleep(0.05)
    process.kill()
    raise AssertionError(f"no {at_least} samples within {timeout_s:g} s")


def store_dump(path: Path) -> list[str]:
    """The SQL dump of the store at ``path`` (every table and row): equal before and after a command that wrote
    nothing."""
    db = sqlite3.connect(path)
    try:
        return list(db.iterdump())
    finally:
        db.close()
