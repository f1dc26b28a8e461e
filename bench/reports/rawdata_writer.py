"""The raw-data CSV's writer process (:mod:`bench.reports.rawdata_child` starts it):
``python -m bench.reports.rawdata_writer STORE RUN_ID KIND ROWS TARGET`` writes the CSV of run RUN_ID's KIND
samples at TARGET as the report would write it serially, and prints ``SHA256 ROWS SAMPLES`` (or one error line on
stderr, exit 1)."""

from __future__ import annotations

import sys

from bench.reports.rawdata import StreamedSeries
from bench.store import Store

__all__ = ["main"]


def main(argv: list[str]) -> int:
    """The child: ``STORE RUN_ID KIND ROWS TARGET``; prints ``SHA256 ROWS SAMPLES``, or one error line (exit 1)."""
    store_path, run_id, kind, rows, target = argv
    try:
        with Store(store_path, read_only=True) as store:
            series = StreamedSeries(store, int(run_id), kind, int(rows), in_child=False)
            digest, written, samples = series.write_from_store(target)
    except Exception as error:  # any failure: one line for the report's process to show
        print(f"{type(error).__name__}: {' '.join(str(error).split())}", file=sys.stderr)
        return 1
    print(digest, written, samples)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
