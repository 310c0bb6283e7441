"""The shared log-log power-law fit against closed forms and scipy's linear regression."""

import math

import numpy as np
import pytest
from scipy import stats

from continuum_vs_network.fits import PowerLaw, power_law, trend


def test_an_exact_power_law_is_recovered_with_zero_error():
    x = np.geomspace(1.0, 1e3, 7)
    fit = power_law(x, 3.5 * x**-2.0)
    assert fit.exponent == pytest.approx(-2.0, abs=1e-12)
    assert fit.prefactor == pytest.approx(3.5, rel=1e-12)
    assert fit.exponent_error == pytest.approx(0.0, abs=1e-12)
    assert fit.rms_log_residual == pytest.approx(0.0, abs=1e-12)
    assert fit.points == 7


def test_exponent_and_error_equal_scipy_linregress_on_the_logarithms():
    rng = np.random.default_rng(3)
    x = np.geomspace(10, 1e4, 12)
    y = 0.7 * x**0.45 * np.exp(rng.normal(0, 0.3, x.size))
    fit = power_law(x, y)
    ref = stats.linregress(np.log(x), np.log(y))
    assert fit.exponent == pytest.approx(ref.slope, rel=1e-12)
    assert fit.exponent_error == pytest.approx(ref.stderr, rel=1e-10)
    assert math.log(fit.prefactor) == pytest.approx(ref.intercept, rel=1e-12)


def test_the_error_covers_the_true_exponent_at_the_stated_rate():
    """Over many noisy draws the true exponent lies within 2 SE about 95 % of the time
    (Student t with 6 degrees of freedom: 90.8 %)."""
    rng = np.random.default_rng(0)
    x = np.geomspace(1, 100, 8)
    hits = 0
    for _ in range(2000):
        fit = power_law(x, x**1.3 * np.exp(rng.normal(0, 0.2, x.size)))
        hits += abs(fit.exponent - 1.3) <= 2 * fit.exponent_error
    assert 0.88 <= hits / 2000 <= 0.94


def test_non_positive_points_are_skipped_and_two_points_give_no_error():
    fit = power_law([1.0, 2.0, 4.0, -1.0, 8.0], [1.0, 4.0, np.nan, 5.0, 0.0])
    assert fit.points == 2
    assert fit.exponent == pytest.approx(2.0)
    assert math.isnan(fit.exponent_error)
    assert trend(fit) == "undetermined"
    assert "no error estimate" in fit.describe("tau", "N")


def test_trend_is_stated_only_beyond_two_standard_errors():
    def law(slope, error):
        return PowerLaw(slope, error, 1.0, 5, 0.1)

    assert trend(law(0.5, 0.1)) == "grows"
    assert trend(law(-0.5, 0.1)) == "falls"
    assert trend(law(0.19, 0.1)) == "no trend"
    assert law(0.49, 0.13).describe("tau", "N") == "tau ~ N^(0.49 +- 0.13), grows"


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        ([1.0, 2.0], [1.0], "same length"),
        ([1.0, 1.0], [1.0, 2.0], "distinct x"),
        ([1.0], [1.0], "two"),
    ],
)
def test_too_few_or_mismatched_points_are_one_clear_error(x, y, match):
    with pytest.raises(ValueError, match=match):
        power_law(x, y)


def test_robust_trend_needs_every_size_left_out_to_agree():
    from continuum_vs_network.fits import robust_trend

    rng = np.random.default_rng(0)
    n = np.repeat([64.0, 256.0, 1024.0, 4096.0], 3)
    clean = 2.0 * n**0.5 * np.exp(0.05 * rng.standard_normal(n.size))
    r = robust_trend(n, clean)
    assert r.trend == "grows" and len(r.exponents) == 4
    assert all(abs(e - 0.5) < 0.1 for e in r.exponents)
    # flat except at the largest size: the full fit "grows", without N = 4096 it does not
    step = np.where(n == 4096.0, 30.0, 1.0) * np.tile([0.5, 1.0, 2.0], 4)
    assert trend(power_law(n, step)) == "grows"
    r = robust_trend(n, step)
    assert r.trend == "no robust trend"
    assert min(r.exponents) == pytest.approx(0.0, abs=1e-12) and max(r.exponents) > 0.4
    assert "no robust trend" in r.describe("rho*", "N")
    # two sizes: nothing can be left out and keep a trend
    assert robust_trend([64.0, 64.0, 256.0, 256.0], [1.0, 1.1, 2.0, 2.1]).trend == (
        "no robust trend"
    )


def test_against_states_consistency_within_two_standard_errors():
    from continuum_vs_network.fits import against

    assert against(PowerLaw(2.05, 0.03, 1.0, 6, 0.1), 2.0) == "consistent with 2 (within 2 SE)"
    assert against(PowerLaw(2.26, 0.03, 1.0, 6, 0.1), 2.0) == "differs from 2 by 8.7 SE"
    assert "no error estimate" in against(PowerLaw(2.26, math.nan, 1.0, 2, 0.0), 2.0)
