"""tsrl.experiments.statistics against values computed by hand on small fixed data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rliable import library, metrics

from tsrl.experiments import statistics as st

# Ten seeds' scores, shuffled: sorted 0.1 .. 1.0.
TEN = np.array([0.7, 0.1, 1.0, 0.4, 0.9, 0.2, 0.6, 0.3, 0.8, 0.5])


def test_iqm_is_the_mean_of_the_middle_runs():
    # n = 10: int(10 / 4) = 2 cut at each end -> mean(0.3 .. 0.8) = 0.55.
    assert st.iqm(TEN) == pytest.approx([0.55])
    # n = 8, sorted (0, 1, 3, 4, 5, 100, 200, 300): 2 cut at each end -> mean(3, 4, 5, 100) = 28.
    assert st.iqm(np.array([300, 0, 4, 100, 1, 5, 200, 3])) == pytest.approx([28.0])
    # Per evaluation of a curve (seeds x evaluations): each column on its own.
    curve = np.stack([TEN, TEN * 0 + 1.0], axis=1)
    assert st.iqm(curve) == pytest.approx([0.55, 1.0])
    eleven = np.r_[TEN, 7.0]
    for n in range(1, 12):  # rliable's aggregate_iqm for every n: int(n / 4) cut at each end
        assert st.iqm(eleven[:n])[0] == pytest.approx(metrics.aggregate_iqm(eleven[:n]))


def test_iqm_interval_is_rliables_stratified_percentile_bootstrap():
    est = st.iqm_interval(TEN, resamples=1_000)
    np.random.seed(st.SEED)
    point, interval = library.get_interval_estimates(
        {"a": TEN.reshape(-1, 1)}, lambda s: np.array([metrics.aggregate_iqm(s)]), reps=1_000
    )
    assert est.point == pytest.approx(point["a"]) and est.point == pytest.approx([0.55])
    assert [est.low[0], est.high[0]] == pytest.approx(interval["a"][:, 0])
    assert 0.1 < est.low[0] < 0.55 < est.high[0] < 1.0 and est.sd[0] > 0
    again = st.iqm_interval(TEN, resamples=1_000)
    assert (again.low, again.high) == (est.low, est.high)  # seeded
    one = st.iqm_interval(np.array([0.3]), resamples=100)
    assert (one.point[0], one.low[0], one.high[0], one.sd[0]) == (
        0.3,
        0.3,
        0.3,
        0.0,
    )  # no spread from one seed


def test_probability_of_improvement_counts_pairs():
    assert st.probability_of_improvement([3, 4, 5], [0, 1, 2], resamples=200).point[0] == 1.0
    # pairs (1,1) tie 0.5, (1,3) 0, (2,1) 1, (2,3) 0 -> 1.5 / 4
    poi = st.probability_of_improvement([1, 2], [1, 3], resamples=200)
    assert poi.point[0] == pytest.approx(0.375) and poi.low[0] <= 0.375 <= poi.high[0]
    x, y = TEN.reshape(-1, 1), np.array([[0.5], [0.05], [0.95], [0.3]])
    assert st.probability_of_improvement(x, y, resamples=10).point[0] == metrics.probability_of_improvement(
        x, y
    )


def test_area_under_the_curve_is_the_normalised_trapezoid():
    # 0.5 * 1000 * (0 + 0.5) + 0.5 * 1000 * (0.5 + 1) + 2000 * 1 = 3000, over 4000 env steps.
    steps = np.array([0, 1000, 2000, 4000])
    assert st.area_under_curve(steps, np.array([0.0, 0.5, 1.0, 1.0])) == pytest.approx(0.75)
    both = st.area_under_curve(steps, np.array([[0.0, 0.5, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]]))
    assert both == pytest.approx([0.75, 1.0])


def test_kaplan_meier_median_counts_censored_seeds():
    # Ten seeds: five reach 90% at 1000, 2000, 2000, 3000, 4000 env steps; five never do (censored at
    # the budget, 5000). S: 9/10 = 0.9 at 1000; 0.9 * 7/9 = 0.7 at 2000; 0.7 * 6/7 = 0.6 at 3000;
    # 0.6 * 5/6 = 0.5 at 4000 -> median 4000. Dropping the censored seeds would say 2000.
    times = np.array([1000, 2000, 2000, 3000, 4000, 5000, 5000, 5000, 5000, 5000])
    reached = np.array([True] * 5 + [False] * 5)
    event_times, survival = st.kaplan_meier(times, reached)
    np.testing.assert_array_equal(event_times, [1000, 2000, 3000, 4000])
    np.testing.assert_allclose(survival, [0.9, 0.7, 0.6, 0.5])
    assert st.km_median(times, reached) == 4000
    # Four of ten reach it: S never falls to 0.5, the median lies beyond the budget.
    assert st.km_median(times, np.array([True] * 4 + [False] * 6)) == math.inf
    # A seed censored early leaves the risk set: events at 1000 and 3000, censored at 2000, event at
    # 4000 -> S = 3/4 at 1000, 3/4 * 1/2 = 0.375 at 3000 -> median 3000.
    assert st.km_median(np.array([1000, 2000, 3000, 4000]), np.array([True, False, True, True])) == 3000


def test_holm_adjusts_step_down():
    # sorted 0.01, 0.03, 0.04, 0.2 -> 4 * 0.01 = 0.04; 3 * 0.03 = 0.09; max(0.09, 2 * 0.04) = 0.09; 0.2.
    np.testing.assert_allclose(st.holm([0.01, 0.04, 0.03, 0.2]), [0.04, 0.09, 0.09, 0.2])
    np.testing.assert_allclose(st.holm([0.6, 0.5]), [1.0, 1.0])  # capped at 1
    np.testing.assert_allclose(st.holm([0.02]), [0.02])


def test_mann_whitney_exact_p_values():
    # All 3 of x above all 3 of y: 1 of C(6, 3) = 20 orderings -> one-sided p = 0.05, two-sided 0.1.
    assert st.mann_whitney_p(np.array([3, 4, 5]), np.array([0, 1, 2]), "greater") == pytest.approx(0.05)
    assert st.mann_whitney_p(np.array([3, 4, 5]), np.array([0, 1, 2]), "two-sided") == pytest.approx(0.1)
    assert st.mann_whitney_p(np.array([3, 4, 5]), np.array([0, 1, 2]), "less") == pytest.approx(1.0)
    assert st.mann_whitney_p(np.ones(3), np.ones(4), "greater") == 1.0  # all tied: no evidence


def test_minimum_detectable_effect():
    # (z_0.95 + z_0.8) * sd = (1.6449 + 0.8416) * 0.1; two comparisons: z_0.975 = 1.9600.
    assert st.minimum_detectable_effect(0.1, 1, "greater") == pytest.approx(0.24865, abs=1e-4)
    assert st.minimum_detectable_effect(0.1, 2, "greater") == pytest.approx(0.28016, abs=1e-4)
    assert st.minimum_detectable_effect(0.1, 1, "two-sided") == pytest.approx(0.28016, abs=1e-4)


def _effect(point: float, low: float, high: float, sd: float = 0.05) -> st.Estimate:
    return st.Estimate(np.array([point]), np.array([low]), np.array([high]), np.array([sd]))


def test_verdicts_say_what_the_data_can_decide():
    assert st.verdict("fs1", "baseline", _effect(0.1, 0.05, 0.15), 0.01, 0.04, "greater", None) == (
        "detected: fs1 above baseline"
    )
    assert st.verdict("a", "b", _effect(-0.1, -0.15, -0.05), 0.01, 0.04, "two-sided", None).endswith(
        "a below b"
    )
    plain = st.verdict("a", "b", _effect(0.02, -0.03, 0.07), 0.3, 0.08, "greater", None)
    assert plain == "no detectable difference at this power (detectable with 80% power: 0.08)"
    outside = st.verdict("a", "b", _effect(0.02, -0.03, 0.07), 0.3, 0.08, "greater", 0.1)
    assert outside.endswith("an effect of 0.1 is outside the 95% interval")
    powered = st.verdict("a", "b", _effect(0.02, -0.03, 0.12), 0.3, 0.08, "greater", 0.1)
    assert powered.endswith("it had the power to detect an effect of 0.1 and did not")
    alike = st.verdict("a", "b", _effect(0.0, 0.0, 0.0, sd=0.0), 1.0, 0.0, "greater", 0.1)
    assert alike.endswith("scored alike, so the power cannot be estimated")
    weak = st.verdict("a", "b", _effect(0.02, -0.1, 0.2), 0.3, 0.15, "greater", 0.1)
    assert weak.endswith("too few seeds to detect an effect of 0.1: inconclusive")


def test_performance_profile_is_the_fraction_of_seeds_above_tau():
    profile = st.performance_profile({"a": TEN, "b": np.zeros(4)}, np.array([0.0, 0.45, 0.95]), resamples=200)
    np.testing.assert_allclose(profile["a"].point, [1.0, 0.6, 0.1])
    np.testing.assert_allclose(profile["b"].point, [0.0, 0.0, 0.0])
    assert np.all(profile["a"].low <= profile["a"].point) and np.all(profile["a"].point <= profile["a"].high)
