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

"before" is the method of commit 63b0072 (RP: bootstrap SD x 2; AP: k = 2 on s/√n), "after" this code's. Prints one
row per case and n: coverage before and after, and the binomial standard error of a coverage.

    python benchmarks/bench_uncertainty_coverage.py [--campaigns 2000] [--seed 1]
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.metrology.uncertainty import (
    accuracy_uncertainty,
    bootstrap_uncertainty,
    distance_accuracy_uncertainty,
    mean_sd_uncertainty,
    repeatability_uncertainty,
)

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


def coverage_table(campaigns: int, seed: int, sizes=(10, 30)) -> list[tuple[str, int, float, float]]:
    """(case, n, coverage before, coverage after) for every case and number of cycles."""
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
    args = parser.parse_args()
    se = np.sqrt(0.95 * 0.05 / args.campaigns)
    print(f"coverage of value ± U (k = 2, honest 95 %), {args.campaigns} campaigns per row, SE {100 * se:.1f} %")
    print(f"{'case':32s} {'n':>3s} {'before':>8s} {'after':>8s}")
    for case, n, before, after in coverage_table(args.campaigns, args.seed):
        print(f"{case:32s} {n:3d} {100 * before:7.1f}% {100 * after:7.1f}%")


if __name__ == "__main__":
    main()
