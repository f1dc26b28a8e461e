"""A long run's raw-data CSV written by a second process while the report's analysis reads the same run.

Writing a long path run's CSV (:mod:`bench.reports.rawdata_text`) costs about as much again as reading its samples:
1.4 s of the report's CPU at 1.16 million points, on one core while a second waits. Here a child process
(``python -m bench.reports.rawdata_writer``) opens the store read-only (SQLite in WAL mode lets readers run beside
each other and beside a writer), reads the run's samples of the kind itself and writes their CSV with the same code
as the serial path (:meth:`bench.reports.rawdata.StreamedSeries.write_from_store`: the same bytes) to a temporary
file; the report joins it before the document cites the file's SHA-256 (:meth:`CsvInChild.join`), and moves the
file into place only then. A child that fails is one line (its error), nothing is left at the CSV's path, and a
child whose run differs from the analysed one (a resumed run that gained samples between the two reads) is refused,
never cited. A process start and its imports cost 0.5 s (0.6 s of CPU, measured on the 2-core machine), so runs
under :data:`PROCESS_MIN_SAMPLES` samples, and any run while the machine is busy, keep the serial path.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import weakref
from pathlib import Path
from typing import Any

from bench.errors import BenchError
from bench.reports.cores import core_time_free
from bench.store.child_env import bench_child_env

__all__ = ["PROCESS_MIN_SAMPLES", "CsvInChild", "long_enough", "worth_a_process"]

#: The fewest samples of a kind for which the CSV gets its own process: 1,000 path samples are about 160,000
#: streamed points, whose CSV the report writes serially in about 0.2 s, less than a process start and its imports.
PROCESS_MIN_SAMPLES = 1000


def long_enough(store: Any, run_id: int, kind: str) -> bool:
    """Whether run ``run_id`` is long enough for its ``kind`` samples' CSV to be worth a process: a store file (not
    a lab view, not in memory) holding at least :data:`PROCESS_MIN_SAMPLES` such samples (an index count)."""
    if not hasattr(store, "iter_samples_text") or not hasattr(store, "sample_kinds"):
        return False
    if store.path == ":memory:" or not Path(store.path).is_file():
        return False
    return bool(store.sample_kinds(run_id).get(kind, 0) >= PROCESS_MIN_SAMPLES)


def worth_a_process(store: Any, run_id: int, kind: str) -> bool:
    """Whether the CSV is written by a process of its own: the run is :func:`long_enough` and the machine has core
    time free now (:func:`bench.reports.cores.core_time_free`; the child reads and decodes the samples again, 3.8 s
    of CPU at 1.16 million points against the 1.4 s of CSV it takes off the report: on a busy machine a loss)."""
    return long_enough(store, run_id, kind) and core_time_free()


def _abandon(process: subprocess.Popen[bytes], folder: str) -> None:
    """Stop a child that is no longer wanted and remove its folder with its partial file."""
    if process.poll() is None:
        process.kill()
    process.communicate()
    shutil.rmtree(folder, ignore_errors=True)


class CsvInChild:
    """The CSV of run ``run_id``'s ``kind`` samples in store file ``store_path``, being written by a child process
    (started here) to a temporary file; :meth:`join` waits for it and moves the file to where the report wants it."""

    def __init__(self, store_path: str, run_id: int, kind: str, rows: int) -> None:
        self.run_id = run_id
        # a private folder; the file in it is created by the child as any CSV of a report is (the same mode)
        self.folder = tempfile.mkdtemp(prefix=f"run{run_id}_csv_")
        self.temporary = str(Path(self.folder) / "samples.csv")
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "bench.reports.rawdata_writer",
                store_path,
                str(run_id),
                kind,
                str(rows),
                self.temporary,
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=bench_child_env(),
        )
        # a report that fails before joining (or is dropped) stops the child and leaves no partial file behind
        self._abandon = weakref.finalize(self, _abandon, self.process, self.folder)

    def join(self, path: str | Path, samples: int | None) -> tuple[str, int]:
        """Wait for the child, then move its CSV to ``path``; its SHA-256 and rows. ``samples``: how many samples
        the analysis read (None: not counted), which the child's must equal.

        Raises
        ------
        BenchError
            One line: the child's error, or the run changed between the two reads; nothing is written at ``path``.
        """
        out, err = self.process.communicate()
        failed = None
        if self.process.returncode != 0:
            said = err.decode(errors="replace").strip().splitlines()
            failed = said[-1] if said else f"it ended with code {self.process.returncode}"
        elif len(out.split()) != 3 or not out.split()[1].isdigit() or not out.split()[2].isdigit():
            failed = f"it answered {out.decode(errors='replace').strip()[:80]!r}, expected: SHA256 ROWS SAMPLES"
        else:
            digest, rows, written = out.decode().split()
            if samples is not None and int(written) != samples:
                failed = (
                    f"it read {written} samples and the analysis {samples}: the run changed while the report was "
                    "written; write the report again"
                )
        if failed is not None:
            self._abandon()
            raise BenchError(f"run {self.run_id}: the raw-data CSV was not written ({failed})")
        shutil.move(self.temporary, path)
        self._abandon()  # the folder, now empty
        return digest, int(rows)
