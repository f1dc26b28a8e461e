"""Monte Carlo coverage of the stated expanded uncertainties (k = 2: honest is 95 %) on synthetic campaigns.

Each case draws campaigns of n cycles from a known model, computes the figure and its U as `bench analyze` does,
and counts how often [value - U, value + U] holds the truth. The truths:

- AP (per axis and AP_P): the robot's true mean offset from the command. The instrument adds a bias per campaign
  drawn from N(0, u_inst²) per axis, declared to the analysis as ``instrument_u_mm = u_inst`` (case "AP declared")
  or not declared (case "AP undeclared": the data alone cannot see a bias, which is why the output must say "U
  excludes the instrument: none declared").
- AD: E[D] - D_c for the distance between two poses 100 mm apart, D_j = |p2_j - p4_j| (no instrument term).
- Groover repeatability 3 σ̄: 3 x the mean of the targets' true standard deviations.
- RP: the population l_mean + 3 sigma_l of the simulated scatter (distances to the true mean), computed by a 4·10^6
  draw Monte Carlo of the same model; U must cover it including the estimator's small-sample bias.
- RD, AV, RV, AT_p, RT_p (``--only figures``): the population figure of each set-up (:func:`figure_rows`); RT_p also
  on two further path shapes, a 16-station circle whose stations tie exactly and a line with one dominant station
  (:data:`RT_SHAPES`), so that U(RT_p) is not judged on one path's tie structure alone.

"before" is the method of commit 63b0072 (RP: bootstrap SD x 2; AP: k = 2 on s/√n), "after" this code's. Prints one
row per case and n: coverage before and after, and the binomial standard error of a coverage.

    python benchmarks/bench_uncertainty_coverage.py [--campaigns 2000] [--seed 1]
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Iterator
from functools import lru_cache

import numpy as np

from bench.metrology.iso9283 import distance_characteristics
from bench.metrology.iso9283_dynamics import path_characteristics
from bench.metrology.iso9283_path import path_velocity_characteristics
from bench.metrology.uncertainty import (
    accuracy_uncertainty,
    bootstrap_uncertainty,
    distance_accuracy_uncertainty,
    mean_sd_uncertainty,
    repeatability_uncertainty,
)
from bench.metrology.uncertainty_figures import mean_speed_uncertainty, path_uncertainty, spread_uncertainty

ROBOT_OFFSET_MM = np.array([0.6, -0.4, 0.3])  #: true mean offset from the command (the AP truth)
INSTRUMENT_U_MM = 0.1  #: standard deviation of the per-campaign instrument bias, per axis
TARGET_SIGMAS_MM = np.array([0.02, 0.03, 0.05, 0.04, 0.03])  #: an actuator's per-target scatter (Groover)
SHAPES = {"isotropic 3-D": (0.1, 0.1, 0.1), "anisotropic 3-D": (0.1, 0.03, 0.01), "2-D": (0.1, 0.1)}


def rp_population(sigmas, *, draws: int = 4_000_000, seed: int = 99) -> float:
    """l_mean + 3 sigma_l of a Gaussian scatter of axis sigmas ``sigmas`` about its true mean (the RP measurand)."""
    distances = np.linalg.norm(np.random.default_rng(seed).standard_normal((draws, len(sigmas))) * sigmas, axis=1)
    return float(distances.mean() + 3.0 * distances.std())


def rp_coverage(sigmas, n: int, campaigns: int, seed: int, *, method: str) -> float:
    """Share of campaigns whose RP ± U holds the population RP; ``method`` "bootstrap" (before) or "auto"."""
    rng = np.random.default_rng(seed)
    sigmas = np.asarray(sigmas, dtype=float)
    truth = rp_population(sigmas)
    hits = 0
    for _ in range(campaigns):
        points = rng.standard_normal((n, len(sigmas))) * sigmas
        distances = np.linalg.norm(points - points.mean(axis=0), axis=1)
        rp = distances.mean() + 3.0 * distances.std(ddof=1)
        u = repeatability_uncertainty(points, method=method, resamples=200, seed=int(rng.integers(1 << 30)))
        hits += abs(rp - truth) <= 2.0 * u
    return hits / campaigns


def ap_coverage(n: int, campaigns: int, seed: int, *, declared: bool, method: str) -> tuple[float, float]:
    """Share of campaigns whose AP_x ± U (every axis counted) and AP_P ± U hold the truth."""
    rng = np.random.default_rng(seed)
    truth_axes, truth_norm = ROBOT_OFFSET_MM, float(np.linalg.norm(ROBOT_OFFSET_MM))
    axis_hits = norm_hits = 0
    for _ in range(campaigns):
        bias = rng.normal(0.0, INSTRUMENT_U_MM, 3)
        attained = ROBOT_OFFSET_MM + bias + rng.normal(0.0, 0.3, (n, 3))
        ap, axes = accuracy_uncertainty(attained, np.zeros(3), instrument_u_mm=INSTRUMENT_U_MM if declared else 0.0)
        scale = (lambda m: 2.0 / m.coverage_factor) if method == "before" else (lambda m: 1.0)
        axis_hits += sum(abs(m.value - t) <= m.expanded_uncertainty * scale(m) for m, t in zip(axes, truth_axes))
        norm_hits += abs(ap.value - truth_norm) <= ap.expanded_uncertainty * scale(ap)
    return axis_hits / (3 * campaigns), norm_hits / campaigns


def groover_coverage(n: int, campaigns: int, seed: int, *, method: str) -> float:
    """Share of campaigns whose Groover repeatability 3 σ̄ ± U holds 3 x the mean true per-target SD."""
    rng = np.random.default_rng(seed)
    truth = 3.0 * float(TARGET_SIGMAS_MM.mean())
    hits = 0
    for _ in range(campaigns):
        readings = rng.standard_normal((n, len(TARGET_SIGMAS_MM))) * TARGET_SIGMAS_MM
        value = 3.0 * float(readings.std(axis=0, ddof=1).mean())
        if method == "before":
            u = bootstrap_uncertainty(
                lambda r: 3.0 * float(r.std(axis=0, ddof=1).mean()),
                readings,
                resamples=200,
                seed=int(rng.integers(1 << 30)),
            )
        else:
            u = 3.0 * mean_sd_uncertainty(readings)
        hits += abs(value - truth) <= 2.0 * u
    return hits / campaigns


def ad_coverage(n: int, campaigns: int, seed: int, *, method: str) -> float:
    """Share of campaigns whose AD ± U holds E[D] - D_c (robot scatter 0.3 mm per axis at both poses)."""
    rng = np.random.default_rng(seed)
    offset = np.array([100.0, 0.0, 0.0]) + ROBOT_OFFSET_MM
    population = np.linalg.norm(
        offset + np.random.default_rng(98).normal(0.0, 0.3 * np.sqrt(2.0), (2_000_000, 3)), axis=1
    )
    truth = float(population.mean()) - 100.0
    hits = 0
    for _ in range(campaigns):
        distances = np.linalg.norm(offset + rng.normal(0.0, 0.3, (n, 3)) - rng.normal(0.0, 0.3, (n, 3)), axis=1)
        ad, u = float(distances.mean()) - 100.0, float(distances.std(ddof=1) / np.sqrt(n))
        half = 2.0 * u if method == "before" else distance_accuracy_uncertainty(ad, u, n).expanded_uncertainty
        hits += abs(ad - truth) <= half
    return hits / campaigns


#: The instrument bias cases of the RD, path and velocity rows: none, drawn and declared, drawn and not declared.
BIAS_CASES = ("no bias", "bias declared", "bias undeclared")
#: A straight 100 mm path along x sampled at 11 stations; the robot's systematic deviation peaks mid-path (y) over
#: a constant 0.1 mm (z), so neighbouring stations nearly tie for AT; its scatter grows along the path, so the last
#: stations nearly tie for RT.
PATH_STATIONS_X_MM = np.linspace(0.0, 100.0, 11)
PATH_SYSTEMATIC_MM = np.stack(
    [np.zeros(11), 0.4 * np.sin(np.pi * PATH_STATIONS_X_MM / 100.0), np.full(11, 0.1)], axis=1
)
PATH_CYCLE_OFFSET_MM = np.array([0.0, 0.04, 0.02])  #: SD of a cycle's offset common to all stations, per axis
PATH_LOCAL_MM = np.array([0.0, 0.04, 0.03])  #: SD of each crossing's own scatter at the first station, per axis
SPEED_COMMANDED_MM_S, SPEED_BIAS_PCT = 50.0, 1.5  #: v_c and the robot's true AV
SPEED_CYCLE_SD_MM_S, SPEED_SAMPLE_SD_MM_S, SPEED_SAMPLES = 0.4, 1.0, 40  #: scatter of v̄_j and of each v_ij
INSTRUMENT_SPEED_U_PCT = 0.5  #: SD of the per-campaign scale error of the speed instrument, %


def _local_scale() -> np.ndarray:
    """The growth of the crossings' own scatter along the path: 1 at the first station, 1.5 at the last."""
    return 1.0 + PATH_STATIONS_X_MM / 200.0


def rd_coverage(n: int, campaigns: int, seed: int, *, bias: str, method: str) -> float:
    """Share of campaigns whose RD ± U holds 3 SD[D] (the AD set-up; an instrument offset per pose when biased)."""
    rng = np.random.default_rng(seed)
    offset = np.array([100.0, 0.0, 0.0]) + ROBOT_OFFSET_MM
    population = np.linalg.norm(
        offset + np.random.default_rng(98).normal(0.0, 0.3 * np.sqrt(2.0), (2_000_000, 3)), axis=1
    )
    truth = 3.0 * float(population.std())
    hits = 0
    for _ in range(campaigns):
        first = offset + rng.normal(0.0, 0.3, (n, 3))
        second = rng.normal(0.0, 0.3, (n, 3))
        if bias != "no bias":
            first, second = first + rng.normal(0.0, INSTRUMENT_U_MM, 3), second + rng.normal(0.0, INSTRUMENT_U_MM, 3)
        rd = distance_characteristics(first, second, [100.0, 0, 0], [0, 0, 0]).rd_mm
        if method == "before":
            statistic = lambda p: 3.0 * float(np.linalg.norm(p[:, :3] - p[:, 3:], axis=1).std(ddof=1))  # noqa: E731
            half = 2.0 * bootstrap_uncertainty(
                statistic, np.hstack([first, second]), resamples=200, seed=int(rng.integers(1 << 30))
            )
        else:
            half = spread_uncertainty(rd, n, unit="mm").expanded_uncertainty
        hits += abs(rd - truth) <= half
    return hits / campaigns


@lru_cache(maxsize=1)
def path_truth() -> tuple[float, float]:
    """The population AT_p and RT_p of the synthetic path (the RT of each station from 10^6 draws)."""
    at = float(np.linalg.norm(PATH_SYSTEMATIC_MM, axis=1).max())
    sigmas = np.sqrt(PATH_CYCLE_OFFSET_MM**2 + (PATH_LOCAL_MM * _local_scale()[:, None]) ** 2)  # (m, d)
    squared = np.random.default_rng(97).standard_normal((1_000_000, 3)) ** 2
    rt = 0.0
    for s in sigmas:
        distances = np.sqrt(squared @ s**2)
        rt = max(rt, float(distances.mean() + 3.0 * distances.std()))
    return at, rt


def path_campaign(rng: np.random.Generator, n: int, bias: str) -> list[np.ndarray]:
    """n sampled paths (polylines through the stations' planes, x strictly increasing) of one campaign."""
    x = PATH_STATIONS_X_MM
    offsets = rng.standard_normal((n, 1, 3)) * PATH_CYCLE_OFFSET_MM
    local = rng.standard_normal((n, len(x), 3)) * PATH_LOCAL_MM * _local_scale()[:, None]
    paths = PATH_SYSTEMATIC_MM + offsets + local
    paths[:, :, 0] = x
    if bias != "no bias":
        paths[:, :, 1:] += rng.normal(0.0, INSTRUMENT_U_MM / 2.0, 2)
    return list(paths)


def _rt_of_crossings(crossings: np.ndarray) -> float:
    """RT_p = max_i (l̄_i + 3 S_li) of crossings (m, n, d), as ``path_characteristics`` computes it."""
    distances = np.linalg.norm(crossings - crossings.mean(axis=1, keepdims=True), axis=2)
    return float((distances.mean(axis=1) + 3.0 * distances.std(axis=1, ddof=1)).max())


def path_coverage(n: int, campaigns: int, seed: int, *, bias: str, method: str, draws: int = 1000):
    """Share of campaigns whose AT_p ± U and RT_p ± U hold the population AT_p and RT_p (:func:`path_truth`)."""
    rng = np.random.default_rng(seed)
    truth_at, truth_rt = path_truth()
    stations = np.stack([PATH_STATIONS_X_MM, np.zeros(11), np.zeros(11)], axis=1)
    at_hits = rt_hits = 0
    for _ in range(campaigns):
        paths = path_campaign(rng, n, bias)
        r = path_characteristics(paths, stations)
        crossings = np.stack(paths, axis=1)  # the paths are sampled at the stations: the crossings themselves
        if method == "before":
            flat = crossings.transpose(1, 0, 2).reshape(n, -1)
            reshape = lambda p: p.reshape(len(p), len(stations), 3).transpose(1, 0, 2)  # noqa: E731
            seed_b = int(rng.integers(1 << 30))
            at_half = 2.0 * bootstrap_uncertainty(
                lambda p: float(np.linalg.norm(reshape(p).mean(axis=1) - stations, axis=1).max()),
                flat,
                resamples=200,
                seed=seed_b,
            )
            rt_half = 2.0 * bootstrap_uncertainty(
                lambda p: _rt_of_crossings(reshape(p)),
                flat,
                resamples=200,
                seed=seed_b,
            )
        else:
            declared = INSTRUMENT_U_MM / 2.0 if bias == "bias declared" else 0.0
            u = path_uncertainty(
                crossings, stations, instrument_u_mm=declared, draws=draws, seed=int(rng.integers(1 << 30))
            )
            assert abs(u.at.value - r.at_mm) < 1e-9 and abs(u.rt.value - r.rt_mm) < 1e-9
            at_half, rt_half = u.at.expanded_uncertainty, u.rt.expanded_uncertainty
        at_hits += abs(r.at_mm - truth_at) <= at_half
        rt_hits += abs(r.rt_mm - truth_rt) <= rt_half
    return at_hits / campaigns, rt_hits / campaigns


#: Further RT_p path shapes, so that U(RT_p) is not judged on the one path above alone: each station's crossing
#: plane is spanned by its two rows of ``basis``; a cycle offset common to all stations (SD per axis, x y z),
#: projected into each plane, plus each crossing's own scatter (SD along the two plane axes, per station).
#: "circle": 16 stations on a 50 mm circle, planes facing along the tangent, all stations alike (an exact 16-fold
#: tie for RT); "dominant station": the line above with a uniform scatter except one station at 1.6 x.
RT_SHAPES = ("circle", "dominant station")


def rt_shape(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(stations (m, 3), plane bases (m, 2, 3), cycle offset SD (3,), own scatter SD (m, 2)) of an RT shape."""
    if name == "circle":
        angle = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
        stations = 50.0 * np.stack([np.cos(angle), np.sin(angle), np.zeros(16)], axis=1)
        radial = np.stack([np.cos(angle), np.sin(angle), np.zeros(16)], axis=1)
        basis = np.stack([radial, np.tile([0.0, 0.0, 1.0], (16, 1))], axis=1)
        return stations, basis, np.array([0.04, 0.04, 0.02]), np.tile([0.04, 0.03], (16, 1))
    stations = np.stack([PATH_STATIONS_X_MM, np.zeros(11), np.zeros(11)], axis=1)
    basis = np.tile([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], (11, 1, 1))
    scale = np.ones(11)
    scale[6] = 1.6
    return stations, basis, PATH_CYCLE_OFFSET_MM, PATH_LOCAL_MM[1:] * scale[:, None]


def rt_shape_coverage(name: str, n: int, campaigns: int, seed: int, *, method: str, draws: int = 500) -> float:
    """Share of campaigns whose RT_p ± U holds the population RT_p of shape ``name`` (:func:`rt_shape`)."""
    stations, basis, offset_sd, own_sd = rt_shape(name)
    projectors = np.einsum("mai,maj->mij", basis, basis)
    covariances = np.einsum("mij,j,mkj->mik", projectors, offset_sd**2, projectors) + np.einsum(
        "mai,ma,maj->mij", basis, own_sd**2, basis
    )
    squared = np.random.default_rng(97).standard_normal((1_000_000, 3)) ** 2
    distances = np.sqrt(squared @ np.clip(np.linalg.eigvalsh(covariances), 0.0, None).T)  # (draws, m)
    truth = float((distances.mean(axis=0) + 3.0 * distances.std(axis=0)).max())
    rng = np.random.default_rng(seed)
    m = len(stations)
    hits = 0
    for _ in range(campaigns):
        offsets = rng.standard_normal((n, 3)) * offset_sd
        own = rng.standard_normal((m, n, 2)) * own_sd[:, None, :]
        crossings = (
            stations[:, None, :] + np.einsum("mij,nj->mni", projectors, offsets) + np.einsum("mna,mai->mni", own, basis)
        )
        rt = _rt_of_crossings(crossings)
        if method == "before":
            flat = crossings.transpose(1, 0, 2).reshape(n, -1)
            half = 2.0 * bootstrap_uncertainty(
                lambda p: _rt_of_crossings(p.reshape(len(p), m, 3).transpose(1, 0, 2)),
                flat,
                resamples=200,
                seed=int(rng.integers(1 << 30)),
            )
        else:
            u = path_uncertainty(crossings, stations, draws=draws, seed=int(rng.integers(1 << 30)))
            assert abs(u.rt.value - rt) < 1e-9
            half = u.rt.expanded_uncertainty
        hits += abs(rt - truth) <= half
    return hits / campaigns


def velocity_coverage(n: int, campaigns: int, seed: int, *, bias: str, method: str) -> tuple[float, float]:
    """Share of campaigns whose AV ± U and RV ± U hold the robot's AV and 3 SD[v̄_j] / v_c (in %)."""
    rng = np.random.default_rng(seed)
    v_c = SPEED_COMMANDED_MM_S
    cycle_sd = np.hypot(SPEED_CYCLE_SD_MM_S, SPEED_SAMPLE_SD_MM_S / np.sqrt(SPEED_SAMPLES))
    truth_av, truth_rv = SPEED_BIAS_PCT, 300.0 * float(cycle_sd) / v_c
    av_hits = rv_hits = 0
    for _ in range(campaigns):
        scale = 1.0 + (rng.normal(0.0, INSTRUMENT_SPEED_U_PCT) / 100.0 if bias != "no bias" else 0.0)
        means = v_c * (1.0 + SPEED_BIAS_PCT / 100.0) + rng.normal(0.0, SPEED_CYCLE_SD_MM_S, (n, 1))
        speeds = scale * (means + rng.normal(0.0, SPEED_SAMPLE_SD_MM_S, (n, SPEED_SAMPLES)))
        v = path_velocity_characteristics(list(speeds), v_c)
        av_half = 2.0 * 100.0 * float(np.std(v.mean_speed_per_cycle_mm_s, ddof=1)) / v_c / np.sqrt(n)
        if method == "before":
            rv_half = 2.0 * bootstrap_uncertainty(
                lambda p: 300.0 * float(p.std(ddof=1)) / v_c,
                np.array(v.mean_speed_per_cycle_mm_s)[:, None],
                resamples=200,
                seed=int(rng.integers(1 << 30)),
            )
        else:
            declared = INSTRUMENT_SPEED_U_PCT if bias == "bias declared" else 0.0
            av_half = mean_speed_uncertainty(
                v.av_pct, v.mean_speed_per_cycle_mm_s, v_c, instrument_u_pct=declared
            ).expanded_uncertainty
            rv_half = spread_uncertainty(v.rv_pct, n, unit="%").expanded_uncertainty
        av_hits += abs(v.av_pct - truth_av) <= av_half
        rv_hits += abs(v.rv_pct - truth_rv) <= rv_half
    return av_hits / campaigns, rv_hits / campaigns


def figure_rows(
    campaigns: int, path_campaigns: int, seed: int, sizes=(10, 30), draws: int = 500
) -> Iterator[tuple[str, int, float, float]]:
    """(case, n, coverage before, coverage after) of RD, AT_p, RT_p, AV and RV for every bias case and n, and of
    RT_p on the further shapes (:data:`RT_SHAPES`); the path rows (a model Monte Carlo per campaign) over
    ``path_campaigns`` campaigns of ``draws`` simulations."""
    for n in sizes:
        for bias in BIAS_CASES:
            yield (
                (f"RD, {bias}", n, *(rd_coverage(n, campaigns, seed, bias=bias, method=m) for m in ("before", "after")))
            )
            before = velocity_coverage(n, campaigns, seed, bias=bias, method="before")
            after = velocity_coverage(n, campaigns, seed, bias=bias, method="after")
            yield from [(f"AV, {bias}", n, before[0], after[0]), (f"RV, {bias}", n, before[1], after[1])]
            before = path_coverage(n, path_campaigns, seed, bias=bias, method="before")
            after = path_coverage(n, path_campaigns, seed, bias=bias, method="after", draws=draws)
            yield from [(f"AT_p, {bias}", n, before[0], after[0]), (f"RT_p, {bias}", n, before[1], after[1])]
        for shape in RT_SHAPES:
            before_rt, after_rt = (
                rt_shape_coverage(shape, n, path_campaigns, seed, method=m, draws=draws) for m in ("before", "after")
            )
            yield (f"RT_p, {shape}", n, before_rt, after_rt)


def coverage_table(campaigns: int, seed: int, sizes=(10, 30)) -> list[tuple[str, int, float, float]]:
    """(case, n, coverage before, coverage after) of the pose figures for every case and number of cycles."""
    rows = []
    for n in sizes:
        for name, sigmas in SHAPES.items():
            rows.append(
                (
                    f"RP {name}",
                    n,
                    rp_coverage(sigmas, n, campaigns, seed, method="bootstrap"),
                    rp_coverage(sigmas, n, campaigns, seed, method="auto"),
                )
            )
        rows.append(
            ("AD", n, ad_coverage(n, campaigns, seed, method="before"), ad_coverage(n, campaigns, seed, method="after"))
        )
        rows.append(
            (
                "Groover 3 sigma-bar",
                n,
                groover_coverage(n, campaigns, seed, method="before"),
                groover_coverage(n, campaigns, seed, method="after"),
            )
        )
        for declared in (True, False):
            label = "declared" if declared else "undeclared"
            before = ap_coverage(n, campaigns, seed, declared=declared, method="before")
            after = ap_coverage(n, campaigns, seed, declared=declared, method="after")
            rows.append((f"AP_x instrument {label}", n, before[0], after[0]))
            rows.append((f"AP_P instrument {label}", n, before[1], after[1]))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--path-campaigns", type=int, default=400, help="campaigns of the AT_p / RT_p rows")
    parser.add_argument("--draws", type=int, default=500, help="model simulations per AT_p / RT_p campaign")
    parser.add_argument("--only", choices=("all", "figures", "pose"), default="all")
    args = parser.parse_args()
    se = np.sqrt(0.95 * 0.05 / args.campaigns)
    print(f"coverage of value ± U (k = 2, honest 95 %), {args.campaigns} campaigns per row, SE {100 * se:.1f} %")
    print(f"{'case':32s} {'n':>3s} {'before':>8s} {'after':>8s}")
    rows = iter([]) if args.only == "figures" else iter(coverage_table(args.campaigns, args.seed))
    if args.only != "pose":
        rows = itertools.chain(rows, figure_rows(args.campaigns, args.path_campaigns, args.seed, draws=args.draws))
    for case, n, before, after in rows:
        print(f"{case:32s} {n:3d} {100 * before:7.1f}% {100 * after:7.1f}%", flush=True)


if __name__ == "__main__":
    main()
