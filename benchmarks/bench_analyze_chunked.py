"""``bench analyze iso9283`` a chunk at a time on 10^7 and 10^8 rows: time against reading the same CSV with pandas in
chunks (the raw-data floor), and peak memory at both sizes (bounded by a chunk, not the run), measured in one run.

A seeded table of ``--rows`` rows (default 10^7, 100 poses, as ``bench_analyze_large.py`` writes it) is written to
``--folder`` (default a temporary folder; 0.6 GB per 10^7 rows), then ``--copies`` (default 10) copies of it with
their poses renamed (C2P1.., 1000 poses of 10^5 cycles for 10^8 rows) are concatenated into the large table. Each
size, in a fresh process: ``bench analyze iso9283 FILE --json --chunk-rows 1048576`` and the peer, pandas
``read_csv(chunksize=1048576)`` summing the attained columns (the parse alone: what reading the raw data costs).
Printed: wall time and peak memory (``ru_maxrss``) of each, the time ratio, the seconds per 10^6 rows, and the peak
at the large size over the peak at the small one. Targets (issue 34): 10^8 rows analysed on this 24 GiB machine,
memory bounded by a chunk.

    python benchmarks/bench_analyze_chunked.py [--rows 1e7] [--copies 10] [--repeat 1] [--folder DIR]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from _timing import load_line
from bench_analyze_large import measured, write_table

CHUNK_ROWS = 1 << 20

#: The floor: the parse of every row, a chunk at a time (what any analysis of the raw data must at least do).
PEER = textwrap.dedent(f"""
    import sys
    import pandas as pd
    total = 0.0
    for chunk in pd.read_csv(sys.argv[1], chunksize={CHUNK_ROWS}):
        total += float(chunk[["x_mm", "y_mm", "z_mm"]].to_numpy().sum())
    print(total)
""")


def concatenate_copies(base: Path, large: Path, copies: int) -> None:
    """``large``: the header of ``base`` and ``copies`` copies of its rows, copy i's pose labels prefixed ``C{i}``
    (copy 1 as it is), a line-aligned block at a time."""
    with large.open("wb") as out:
        for copy in range(1, copies + 1):
            prefix = b"" if copy == 1 else f"C{copy}".encode()
            with base.open("rb") as handle:
                header = handle.readline()
                if copy == 1:
                    out.write(header)
                rest = b""
                while block := handle.read(1 << 26):
                    block = rest + block
                    cut = block.rfind(b"\n") + 1
                    block, rest = block[:cut], block[cut:]
                    out.write((b"\n" + block).replace(b"\nP", b"\n" + prefix + b"P")[1:])
                out.write(rest)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=float, default=1e7)
    parser.add_argument("--copies", type=int, default=10)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--folder", type=Path, default=None, help="where the tables go (default: a temporary one)")
    args = parser.parse_args()
    started = os.getloadavg()
    with tempfile.TemporaryDirectory(dir=args.folder) as folder:
        base, large = Path(folder) / "base.csv", Path(folder) / "large.csv"
        start = time.perf_counter()
        write_table(base, 100, int(args.rows) // 100)
        concatenate_copies(base, large, args.copies)
        print(
            f"tables: {int(args.rows):,} rows ({base.stat().st_size / 1e9:.2f} GB) and {int(args.rows) * args.copies:,}"
            f" rows ({large.stat().st_size / 1e9:.2f} GB), written in {time.perf_counter() - start:.0f} s"
        )
        sizes = []
        for rows, table in ((int(args.rows), base), (int(args.rows) * args.copies, large)):
            bench = [
                measured(
                    [sys.executable, "-m", "bench.cli", "analyze", "iso9283", str(table), "--json"]
                    + ["--chunk-rows", str(CHUNK_ROWS)]
                )[0]
                for _ in range(args.repeat)
            ]
            peer = [measured([sys.executable, "-c", PEER, str(table)])[0] for _ in range(args.repeat)]
            bench_s, peer_s = (statistics.median(r["wall_s"] for r in runs) for runs in (bench, peer))
            bench_mb, peer_mb = (statistics.median(r["peak_mb"] for r in runs) for runs in (bench, peer))
            sizes.append((rows, bench_s, bench_mb))
            print(
                f"{rows:>13,} rows: bench {bench_s:7.1f} s, {bench_mb:6.0f} MB peak; pandas chunked read {peer_s:7.1f} s, "
                f"{peer_mb:6.0f} MB; time {bench_s / peer_s:.2f}x the read; bench {bench_s / rows * 1e6:.2f} s per 10^6 rows"
                + (
                    f" (min {min(r['wall_s'] for r in bench):.1f}, max {max(r['wall_s'] for r in bench):.1f} s)"
                    if args.repeat > 1
                    else ""
                )
            )
    (small, small_s, small_mb), (big, big_s, big_mb) = sizes
    print(
        f"{big // small}x the rows: {big_s / small_s:.2f}x the time, {big_mb / small_mb:.2f}x the peak memory "
        f"({small_mb:.0f} -> {big_mb:.0f} MB)"
    )
    print(load_line(started))


if __name__ == "__main__":
    main()
