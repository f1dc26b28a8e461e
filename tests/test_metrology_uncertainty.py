"""GUM helpers: Type A/B components, t-based intervals, the instrument RP floor, AP and RP uncertainty."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import stats

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    accuracy_uncertainty,
    bootstrap_uncertainty,
    combine,
    expanded,
    instrument_rp_floor,
    mean_confidence_interval,
    pose_repeatability,
    rectangular,
    resolution_uncertainty,
    type_a_of_mean,
    welch_satterthwaite,
)


def test_type_b_components_of_iso9283_section_8_2():
    assert resolution_uncertainty(25.4 / 800, difference=True) == pytest.approx(0.0130, abs=5e-5)  # mouse 800 CPI
    assert resolution_uncertainty(25.4 / 800) == pytest.approx(0.0092, abs=5e-5)
    assert resolution_uncertainty(0.01) == pytest.approx(0.0029, abs=5e-5)  # calliper resolution
    assert rectangular(0.02) == pytest.approx(0.0115, abs=5e-5)  # calliper MPE ±0.02 mm
    assert resolution_uncertainty(0.2, difference=True) == pytest.approx(0.082, abs=5e-4)  # 0.2 mm/pixel
    assert resolution_uncertainty(0.00625) == pytest.approx(0.0018, abs=5e-5)  # actuator CR


def test_combined_and_expanded():
    assert combine(0.003, 0.004) == pytest.approx(0.005)
    measured = expanded(1.5, 0.005, unit="mm")
    assert measured.expanded_uncertainty == pytest.approx(0.01)
    assert str(measured) == "1.500 ± 0.010 mm (k = 2)"  # U to two significant digits, GUM 7.2.6
    with pytest.raises(ConfigError, match="standard_uncertainty = nan"):
        expanded(1.0, float("nan"), unit="mm")


def test_type_a_of_mean():
    assert type_a_of_mean([1.0, 2.0, 3.0]) == pytest.approx(1.0 / np.sqrt(3))
    with pytest.raises(InsufficientData, match=r"samples: 1 sample\(s\), at least 2"):
        type_a_of_mean([1.0])


def test_welch_satterthwaite():
    # Two equal components with 4 and inf degrees of freedom: ν_eff = (2u²)² / (u⁴/4) = 16.
    assert welch_satterthwaite([1.0, 1.0], [4, np.inf]) == pytest.approx(16.0)
    assert welch_satterthwaite([1.0], [np.inf]) == np.inf


@pytest.mark.parametrize("k, t", [(3, 4.303), (5, 2.776), (30, 2.045)])
def test_small_sample_interval_uses_student_t(k, t):
    # iso9283.md §10.2 #14: never 1.96.
    result = mean_confidence_interval(np.arange(k, dtype=float))
    assert result.t_quantile == pytest.approx(t, abs=5e-4)
    half = t * np.std(np.arange(k), ddof=1) / np.sqrt(k)
    assert result.high - result.mean == pytest.approx(half, rel=1e-3)


@pytest.mark.parametrize("dims, factor", [(3, 3.616), (2, 3.219), (1, 2.606)])
def test_instrument_rp_floor_constants(dims, factor):
    assert instrument_rp_floor(1.0, dims=dims) == pytest.approx(factor, abs=5e-4)


def test_rp_floor_of_the_dissertation_mouse():
    # iso9283.md §8.4: σ ≈ 0.355 mm per axis -> about 1.14 mm in 2-D and 1.28 mm in 3-D.
    assert instrument_rp_floor(0.355, dims=2) == pytest.approx(1.14, abs=0.005)
    assert instrument_rp_floor(0.355, dims=3) == pytest.approx(1.28, abs=0.005)


def test_rp_floor_matches_simulation_of_a_perfect_robot():
    rng = np.random.default_rng(5)
    noise = rng.normal(0, 0.1, (20000, 3))
    simulated = pose_repeatability(noise).rp_mm
    assert simulated == pytest.approx(instrument_rp_floor(0.1, dims=3), rel=0.02)


def test_accuracy_uncertainty_per_axis_and_norm():
    attained = np.array([[1.0, 0.0, 0.0], [1.2, 0.0, 0.0], [0.8, 0.0, 0.0], [1.0, 0.0, 0.0]])
    ap, axes = accuracy_uncertainty(attained, [0, 0, 0], instrument_u_mm=0.01)
    s2_mean = np.var(attained[:, 0], ddof=1) / 4
    u_x = np.sqrt(s2_mean + 0.01**2)
    # Welch-Satterthwaite: nu_eff = u_x^4 / (s2_mean^2 / 3); k = Student's t at 95.45 % for it, not 2
    nu = u_x**4 / (s2_mean**2 / 3)
    k_x = stats.t.ppf((1 + math.erf(2 / math.sqrt(2))) / 2, nu)
    assert axes[0].coverage_factor == pytest.approx(k_x)
    assert axes[0].expanded_uncertainty == pytest.approx(k_x * u_x)
    assert axes[1].expanded_uncertainty == pytest.approx(0.02)  # instrument only: Type B, k = 2
    assert ap.value == pytest.approx(1.0)
    assert ap.expanded_uncertainty == pytest.approx(k_x * u_x)  # AP lies along x: only u(AP_x) propagates


def test_bootstrap_is_reproducible_and_scales():
    rng = np.random.default_rng(11)
    cloud = rng.normal(0, 0.2, (30, 3))

    def statistic(p):
        return pose_repeatability(p).rp_mm

    a = bootstrap_uncertainty(statistic, cloud, resamples=300, seed=1)
    assert a == bootstrap_uncertainty(statistic, cloud, resamples=300, seed=1)
    assert bootstrap_uncertainty(statistic, cloud * 10, resamples=300, seed=1) == pytest.approx(10 * a)
    assert 0 < a < pose_repeatability(cloud).rp_mm


def test_vectorised_rp_bootstrap_equals_the_generic_one():
    from bench.metrology import repeatability_uncertainty

    cloud = np.random.default_rng(2).normal(0, 0.3, (12, 3))
    generic = bootstrap_uncertainty(lambda p: pose_repeatability(p).rp_mm, cloud, resamples=200, seed=4)
    assert repeatability_uncertainty(cloud, resamples=200, seed=4, method="bootstrap") == pytest.approx(
        generic, rel=1e-12
    )


def test_the_path_model_keeps_each_station_s_scatter_in_its_own_plane():
    """The sides of a rectangle cross planes facing different ways: pooling the stations' scatter toward each other
    (uncertainty_figures._pooled_toward) must pool their shapes, never move one side's scatter out of its plane."""
    from bench.metrology.uncertainty_figures import _covariances, _pooled_toward

    rng = np.random.default_rng(11)
    deviations = rng.normal(0.0, 0.05, (6, 10, 3)) * [0.0, 1.0, 0.5]  # 3 stations on a side along x: y, z scatter
    deviations[3:] = rng.normal(0.0, 0.05, (3, 10, 3)) * [1.0, 0.0, 0.5]  # 3 on a side along y: x, z scatter
    model = _pooled_toward(deviations - deviations.mean(axis=1, keepdims=True))
    assert np.abs(model[:3, :, 0]).max() < 1e-12 and np.abs(model[3:, :, 1]).max() < 1e-12
    # the shapes are pooled: every station's two axis variances move toward the mean of the stations' (never apart)
    before = np.linalg.eigvalsh(_covariances(deviations))[:, 1:]
    after = np.linalg.eigvalsh(_covariances(model))[:, 1:]
    assert np.all(np.abs(after - before.mean(axis=0)) <= np.abs(before - before.mean(axis=0)) + 1e-12)


@settings(max_examples=60, deadline=None)
@given(
    arrays(
        float,
        st.tuples(st.integers(1, 4), st.integers(1, 6), st.integers(1, 4)),
        elements=st.floats(-1e150, 1e150, allow_nan=False, allow_infinity=False),
    )
)
def test_the_path_models_lengths_are_numpys_norm_bit_for_bit(vectors):
    """The path model's lengths summed axis by axis (issue 34: np.linalg.norm's reduce was most of its time) give
    its U bit for bit."""
    from bench.metrology.uncertainty_figures import _lengths

    assert np.array_equal(_lengths(vectors.copy()), np.linalg.norm(vectors, axis=-1))


@pytest.mark.parametrize("n", [2, 3, 10, 54, 106, 208])
def test_the_spread_half_width_is_the_root_of_scipy_stats_chi2s_coverage(n):
    """spread_half_width reads chi² through scipy.special (not importing scipy.stats): the same root bit for bit."""
    from scipy import optimize

    from bench.metrology.uncertainty_figures import spread_half_width

    level = math.erf(2.0 / math.sqrt(2.0))

    def shortfall(w):
        upper = 1.0 if w >= 1.0 else float(stats.chi2.cdf((n - 1) / (1.0 - w) ** 2, n - 1))
        return upper - float(stats.chi2.cdf((n - 1) / (1.0 + w) ** 2, n - 1)) - level

    assert spread_half_width(n, level) == optimize.brentq(shortfall, 0.0, 1e3, xtol=1e-10)


@pytest.mark.parametrize("d", [2, 3])
def test_the_population_rt_is_numpys_axis_sum_bit_for_bit(d):
    """The population RT's squared axes summed one after another: .sum(axis=-1)'s values bit for bit."""
    from bench.metrology.uncertainty_figures import _POPULATION_DRAWS, _rt_population

    rng = np.random.default_rng(d)
    factors = rng.normal(size=(7, d, d))
    covariance = factors @ factors.transpose(0, 2, 1)
    sigmas = np.sqrt(np.clip(np.linalg.eigvalsh(covariance), 0.0, None))
    normals = np.random.default_rng(5).standard_normal((_POPULATION_DRAWS, d))
    distances = np.sqrt((normals[None, :, :] ** 2 * sigmas[:, None, :] ** 2).sum(axis=-1))
    expected = distances.mean(axis=1) + 3.0 * distances.std(axis=1)
    assert np.array_equal(_rt_population(covariance, np.random.default_rng(5)), expected)
