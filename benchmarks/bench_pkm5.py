"""Throughput of the PKM kinematics, numpy reference against the compiled kernels, measured in one run.

Prints rates and ratios, asserts nothing; every figure is min / median / max of ``--repeat`` timed runs.

* IK: N = 10^6 random poses in the constant-orientation box, one call, ``engine='numpy'`` and ``'compiled'``,
  against the memory-bandwidth floor: the bytes of the poses read and of every result array written, at the copy
  bandwidth (np.copyto) measured in the same run.
* FK: N = 10^5 leg-length sets of reachable poses (translation, alpha and beta mixed), batched LM, numpy and
  compiled. Both start from the same k-d-tree guesses (part of the timed call).
* Per-pose peer: the compiled single-pose solver (the same kernel, same Jacobian, same restarts) called once per
  pose from Python, from the same initial guesses, on a subset: what a loop over poses costs with no numpy overhead.
  It runs on one thread, so the batched FK is compared with it at equal threads: the batched call again with this
  process held to one CPU (its thread pool then runs every chunk on the calling thread).

Targets on a 2-core machine (issues 3 and 17): IK within 10x of its floor; batched FK >= 100 k solves/s.
Usage: ``python benchmarks/bench_pkm5.py [--ik N] [--fk N] [--peer N] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _timing import copy_bandwidths_bytes_s, load_line, min_median_max, nbytes_of, spread, timed

from motion import kernels, pkm5
from motion.pkm5 import compiled
from motion.pkm5.fk import MODES, _initial_guess


def per_pose_peer(lengths: np.ndarray, geometry=pkm5.DEFAULT_GEOMETRY):
    """Seconds of the compiled single-pose solver called once per pose, and the poses it found."""
    modes = pkm5.detect_mode(lengths, 1e-6)
    packed = compiled.pack_geometry(geometry)
    targets, starts, codes, tables, cols = [], [], [], [], []
    for i, mode in enumerate(modes):
        angle_col = MODES[mode]
        columns = [0, 1, 2] + ([angle_col] if angle_col is not None else [])
        q0 = np.zeros((1, 4))
        q0[0, : len(columns)] = _initial_guess(lengths[i : i + 1], mode, geometry)[0]
        targets.append(np.ascontiguousarray(lengths[i : i + 1]))
        starts.append(q0)
        codes.append(compiled.MODE_CODES[mode])
        tables.append(compiled.restart_table(mode))
        cols.append(columns)
    compiled.fk_pose(targets[0], starts[0].copy(), codes[0], tables[0], packed)  # load the kernel
    begin = time.perf_counter()
    for target, q0, code, table in zip(targets, starts, codes, tables):
        compiled.fk_pose(target, q0, code, table, packed)
    seconds = time.perf_counter() - begin
    poses = np.zeros((len(lengths), 5))
    for i, (q0, columns) in enumerate(zip(starts, cols)):
        poses[i, columns] = q0[0, : len(columns)]
    return seconds, poses


def on_one_thread(function, *args, **kwargs):
    """``spread(function, ...)`` with this thread held to one CPU and the kernels' thread pool rebuilt for it (no
    pool: every chunk on the calling thread); the CPUs and the pool are given back afterwards."""
    cpus = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cpus)})
    kernels._pool.cache_clear()
    try:
        return spread(function, *args, **kwargs)
    finally:
        os.sched_setaffinity(0, cpus)
        kernels._pool.cache_clear()


def _stats(times, count, unit, scale):
    rates = sorted(count / t / scale for t in times)
    return f"{rates[len(rates) // 2]:8.2f} {unit} (min {rates[0]:.2f}, max {rates[-1]:.2f})"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ik", type=int, default=1_000_000, help="poses for the IK benchmark")
    parser.add_argument("--fk", type=int, default=100_000, help="poses for the batched FK benchmark")
    parser.add_argument("--peer", type=int, default=5_000, help="poses for the per-pose compiled peer")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of each (min / median / max)")
    args = parser.parse_args(argv)
    started = os.getloadavg()
    if not kernels.available():
        raise SystemExit("numba is not installed (pip install 'bench[fast]'): only the numpy path exists")

    rng = np.random.default_rng(0)
    ik_poses = np.zeros((args.ik, 5))
    ik_poses[:, 0] = rng.uniform(46.5, 235.14, args.ik)
    ik_poses[:, 1] = rng.uniform(-136.12, 136.12, args.ik)
    ik_poses[:, 2] = rng.uniform(262.08, 356.68, args.ik)
    load_time, _ = timed(pkm5.inverse_kinematics, ik_poses[:10], engine="compiled", repeat=1)
    np_times, np_result = spread(pkm5.inverse_kinematics, ik_poses, engine="numpy", repeat=args.repeat)
    c_times, c_result = spread(pkm5.inverse_kinematics, ik_poses, engine="compiled", repeat=args.repeat)
    ik_same = np.abs(c_result.lengths_mm - np_result.lengths_mm).max()
    # floor: read the poses once and write every result array once, at this machine's copy bandwidth
    # a floor and a kernel are compared like with like: the median copy against the median call (both as the VM
    # gives them in this run; its neighbours slow both), and the best against the best
    bandwidths = copy_bandwidths_bytes_s(repeat=args.repeat)
    bandwidth = float(np.median(bandwidths))
    ik_bytes = ik_poses.nbytes + nbytes_of(np_result)
    ik_floor, ik_floor_best = ik_bytes / bandwidth, ik_bytes / max(bandwidths)
    np_med, c_med = float(np.median(np_times)), float(np.median(c_times))

    poses = pkm5.sample_reachable(args.fk, kinds=("constant-orientation", "alpha", "beta"), seed=1)
    lengths = pkm5.inverse_kinematics(poses).lengths_mm
    # the seed tables (4,000 reachable poses per mode and their k-d trees) are built once per process
    setup_time, _ = timed(pkm5.forward_kinematics, lengths[:3], engine="compiled", repeat=1)
    fk_np_times, fk_np = spread(pkm5.forward_kinematics, lengths, engine="numpy", repeat=args.repeat)
    fk_c_times, fk_c = spread(pkm5.forward_kinematics, lengths, engine="compiled", repeat=args.repeat)
    fk_np_med, fk_c_med = float(np.median(fk_np_times)), float(np.median(fk_c_times))
    peer_times, peer_poses = [], None
    for _ in range(args.repeat):
        seconds, peer_poses = per_pose_peer(lengths[: args.peer])
        peer_times.append(seconds)
    peer_med = float(np.median(peer_times))
    c_rate, peer_rate = args.fk / fk_c_med, args.peer / peer_med
    fk_c1_times, _ = on_one_thread(pkm5.forward_kinematics, lengths, engine="compiled", repeat=args.repeat)
    c1_rate = args.fk / float(np.median(fk_c1_times))
    threads = len(os.sched_getaffinity(0))

    print(f"IK {args.ik:,} poses ({args.repeat} runs each; rates: median (min, max))")
    print(f"  numpy     {_stats(np_times, args.ik, 'M poses/s', 1e6)}   {min_median_max(np_times)}")
    print(f"  compiled  {_stats(c_times, args.ik, 'M poses/s', 1e6)}   {min_median_max(c_times)}")
    print(
        f"  memory-bandwidth floor {ik_floor:.4f} s median, {ik_floor_best:.4f} s best ({ik_bytes / 1e6:.0f} MB "
        f"at {bandwidth / 1e9:.1f} GB/s median copy bandwidth, {max(bandwidths) / 1e9:.1f} best): medians: numpy / "
        f"floor = {np_med / ik_floor:.1f}x, compiled / floor = {c_med / ik_floor:.1f}x (target <= 10x); best: "
        f"compiled / floor = {min(c_times) / ik_floor_best:.1f}x; numpy / compiled = {np_med / c_med:.2f}x; "
        f"max |dL| {ik_same:.1e} mm"
    )
    print(f"  one-off kernel load (numba import + cache, or first compile): {load_time:.2f} s")
    print(f"FK {args.fk:,} solves (translation, alpha, beta mixed)")
    print(
        f"  numpy     {_stats(fk_np_times, args.fk, 'k solves/s', 1e3)}   {min_median_max(fk_np_times)}, "
        f"max error {np.abs(fk_np.pose - poses).max():.1e} mm, converged {fk_np.converged.mean():.4%}"
    )
    print(
        f"  compiled  {_stats(fk_c_times, args.fk, 'k solves/s', 1e3)}   {min_median_max(fk_c_times)}, "
        f"max error {np.abs(fk_c.pose - poses).max():.1e} mm, converged {fk_c.converged.mean():.4%} "
        f"(target >= 100 k/s); compiled / numpy = {fk_np_med / fk_c_med:.2f}x"
    )
    print(f"  one-off seed-table build (first call in a process): {setup_time:.3f} s")
    print(
        f"  per-pose peer, the compiled single-pose solver called per pose ({args.peer:,} solves): "
        f"{_stats(peer_times, args.peer, 'k solves/s', 1e3)}, max error "
        f"{np.abs(peer_poses - poses[: args.peer]).max():.1e} mm"
    )
    print(
        f"  compiled batched on 1 thread {_stats(fk_c1_times, args.fk, 'k solves/s', 1e3)}; at equal threads "
        f"(1): batched / per-pose = {c1_rate / peer_rate:.2f}x; batched on {threads} threads / per-pose on 1 = "
        f"{c_rate / peer_rate:.2f}x"
    )
    print(load_line(started))


if __name__ == "__main__":
    main()
