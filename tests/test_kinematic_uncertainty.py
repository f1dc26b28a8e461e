"""Profile-likelihood standard uncertainties of a kinematic identification (bench.metrology.kinematic_uncertainty):
checked against closed forms on models whose profile is known (the pkm5's seed 55, whose linearised u was too small,
is in tests/test_calibration_campaign.py)."""

import numpy as np
import pytest

from bench.metrology.kinematic_calibration import identify
from bench.metrology.kinematic_uncertainty import LINEAR_TOLERANCE, PROFILE_K, profile_ratios, profile_widths


class _Exponential:
    """Two readings of one parameter, both ``exp(theta)``: a model whose profile interval is a closed form."""

    free, units = ("theta",), ("1",)

    def predict(self, theta):
        return np.full((2, 1), np.exp(theta[0]))

    def jacobian(self, theta):
        return np.full((2, 1, 1), np.exp(theta[0]))


class _Linear:
    """Six readings, linear in three parameters: the profile is the quadratic model exactly."""

    free, units = ("a", "b", "c"), ("mm", "mm", "mm")
    matrix = np.array(
        [[1.0, 0.2, 0.0], [0.3, 1.0, -0.5], [0.0, 0.4, 2.0], [1.0, 1.0, 1.0], [2.0, -1.0, 0.1], [0, 0, 1]]
    )

    def predict(self, theta):
        return (self.matrix @ theta)[:, None]

    def jacobian(self, theta):
        return self.matrix[:, None, :]


def test_the_profile_interval_of_an_exponential_model_is_its_closed_form():
    # readings 1, 1 of exp(theta), u = 0.3: theta_hat = 0, Phi = 2 ((e^theta - 1) / 0.3)^2, linear u = 0.3 / sqrt 2;
    # Phi = k^2 = 4 at e^theta = 1 +- 0.3 sqrt 2: theta = ln(1.4243) = 0.3537 and ln(0.5757) = -0.5522, the wider
    # side 0.5522 / (2 * 0.2121) = 1.3015 of the linear half-width
    fit = identify(_Exponential(), np.ones((2, 1)), 0.3)
    assert fit.values[0] == pytest.approx(0.0, abs=1e-9)
    assert fit.uncertainty[0] == pytest.approx(0.3 / np.sqrt(2))
    wider = -np.log(1.0 - 0.3 * np.sqrt(2)) / (PROFILE_K * 0.3 / np.sqrt(2))
    assert profile_widths(_Exponential(), np.ones((2, 1)), 0.3, fit)[0] == pytest.approx(wider, rel=LINEAR_TOLERANCE)
    assert profile_ratios(_Exponential(), np.ones((2, 1)), 0.3, fit)[0] == pytest.approx(1.3015, rel=0.01)


def test_a_linear_model_keeps_its_linear_uncertainties():
    rng = np.random.default_rng(4)
    measured = _Linear().predict(np.array([0.5, -1.0, 2.0])) + rng.normal(0.0, 0.1, (6, 1))
    fit = identify(_Linear(), measured, 0.1, prior_sigma=[1.0, 2.0, np.inf])
    widths = profile_widths(_Linear(), measured, 0.1, fit)
    assert widths == pytest.approx(np.ones(3), rel=LINEAR_TOLERANCE)
    assert profile_ratios(_Linear(), measured, 0.1, fit).tolist() == np.maximum(widths, 1.0).tolist()


class _ExponentialWithAnEdge(_Exponential):
    """The exponential model, whose 'forward kinematics' cannot place the poses below theta = -0.3."""

    def predict(self, theta):
        return super().predict(theta) if theta[0] >= -0.3 else np.full((2, 1), np.nan)


def test_a_profile_that_leaves_the_models_domain_is_undetermined_not_extrapolated():
    # the left endpoint (-0.5522, test above) lies beyond the edge at -0.3: the profile cannot say how wide the
    # interval is there, so the width is NaN (the caller keeps the linear u and names the parameter)
    fit = identify(_ExponentialWithAnEdge(), np.ones((2, 1)), 0.3)
    assert np.isnan(profile_widths(_ExponentialWithAnEdge(), np.ones((2, 1)), 0.3, fit)[0])
    assert np.isnan(profile_ratios(_ExponentialWithAnEdge(), np.ones((2, 1)), 0.3, fit)[0])
