"""Link check of the PKM5 wire protocol under random corruption, measured in one run (prints counts, asserts nothing).

N random command/reply frames (default 10^6) each get one random corruption (1-3 bit flips, or a burst of up to
16 bits: ``bench.robots.line_fuzz``); the script counts how many still decode. Version 2 (CRC-16-CCITT) against the
peer version 1 (XOR-8) on the same corruptions.
Usage: ``python benchmarks/bench_pkm5_link.py [--frames N]``.
"""

from __future__ import annotations

import argparse
import time

from bench.robots.line_fuzz import accepted_count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10**6)
    frames = parser.parse_args().frames
    for label, version in (("v2 CRC-16", 2), ("v1 XOR-8 (peer)", 1)):
        start = time.perf_counter()
        accepted = accepted_count(frames, version, seed=16)
        print(
            f"{label:28s} {accepted:8d} of {frames} corrupted frames accepted ({accepted / frames:.4%}), "
            f"{frames / (time.perf_counter() - start):,.0f} frames/s"
        )


if __name__ == "__main__":
    main()
