"""Issue 31 item 12, the big figure: the driver against the simulated controller through a line corrupting 5 % and
10 % of the frames in each direction (bench.simulators.noisy_link), N moves each, every 4th stopped from another
thread. Prints, per rate: moves completed / stopped / failed, MOVEs re-sent, MOVEs executed twice (must be 0), stops
lost (must be 0).

    python benchmarks/bench_pkm5_corrupted_frames.py [--moves 400] [--seed 0]
"""

import argparse
import logging
import time

from bench.simulators.noisy_link import corrupted_frames_drill


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--moves", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    for rate in (0.05, 0.10):
        start = time.monotonic()
        r = corrupted_frames_drill(rate, args.moves, seed=args.seed)
        print(
            f"rate {rate:.0%} each way: {r.moves} moves, {r.completed} completed, {r.stopped} stopped, {r.failed} "
            f"failed; frames corrupted {r.corrupted['to_controller']} to the controller, {r.corrupted['to_host']} "
            f"to the host; MOVEs re-sent {r.resent_moves}, executed twice {r.executed_twice}; stops {r.stops}, "
            f"lost {r.lost_stops} ({time.monotonic() - start:.0f} s)"
        )
        for message in r.failures[:3]:
            print(f"  failed: {message}")


if __name__ == "__main__":
    main()
