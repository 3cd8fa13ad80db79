"""The verdict rule with the registered relevant effect, the floor/ceiling flags and the Mann-Whitney
method (tsrl.experiments.statistics), against hand-worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats

from tsrl.experiments import statistics as st


def _effect(point: float, low: float, high: float, sd: float = 0.01) -> st.Estimate:
    return st.Estimate(np.array([point]), np.array([low]), np.array([high]), np.array([sd]))


def test_a_detection_wholly_below_the_relevant_effect_says_so():
    # The 2 cm reach's fs2 > baseline: significant, interval [+0.002, +0.023] against 0.05.
    small = st.verdict("fs2", "baseline", _effect(0.013, 0.002, 0.023), 0.034, 0.02, "greater", 0.05)
    assert small == (
        "detected, smaller than the relevant effect: fs2 above baseline by less than 0.05 "
        "(the whole 95% interval)"
    )
    # The interval reaches the relevant effect: a plain detection.
    assert (
        st.verdict("a", "b", _effect(0.04, 0.01, 0.06), 0.01, 0.03, "greater", 0.05) == "detected: a above b"
    )
    # Without a registered relevant effect there is nothing to be smaller than.
    assert (
        st.verdict("a", "b", _effect(0.013, 0.002, 0.023), 0.01, 0.02, "greater", None)
        == "detected: a above b"
    )
    # "less": the interval's far end is its low end; -0.03 lies within 0.05 of 0.
    less = st.verdict("a", "b", _effect(-0.02, -0.03, -0.01), 0.01, 0.02, "less", 0.05)
    assert less.startswith("detected, smaller than the relevant effect: a below b")
    assert st.verdict("a", "b", _effect(-0.1, -0.2, -0.01), 0.01, 0.02, "less", 0.05) == "detected: a below b"
    # two-sided, detected below: as "less"; detected above: as "greater".
    assert st.verdict("a", "b", _effect(-0.02, -0.04, -0.01), 0.01, 0.02, "two-sided", 0.05).startswith(
        "detected, smaller than the relevant effect: a below b"
    )
    assert (
        st.verdict("a", "b", _effect(0.2, 0.1, 0.3), 0.01, 0.02, "two-sided", 0.05) == "detected: a above b"
    )
    # Not significant: the rule does not apply (the old wording stays).
    assert st.verdict("a", "b", _effect(0.01, -0.01, 0.02), 0.2, 0.02, "greater", 0.05).endswith(
        "an effect of 0.05 is outside the 95% interval"
    )


def test_floor_and_ceiling_flags():
    assert st.bound_flags(0.0, 0.5) == "floor"
    assert st.bound_flags(0.02, 0.5) == "floor"  # within one episode in 50 of 0
    assert st.bound_flags(0.5, 0.98) == "ceiling"
    assert st.bound_flags(0.01, 1.0) == "floor, ceiling"
    assert st.bound_flags(0.03, 0.97) == ""
    assert st.bound_flags(0.94, 0.97) == ""


def test_mann_whitney_is_exact_without_ties_and_says_which():
    x, y = np.arange(10.0) + 10, np.arange(10.0)  # every x above every y
    assert st.mann_whitney_method(x, y) == "exact"
    # 1 of C(20, 10) orderings puts all of x above all of y.
    assert st.mann_whitney_p(x, y, "greater") == pytest.approx(1 / math.comb(20, 10), rel=1e-9)
    normal = scipy.stats.mannwhitneyu(x, y, alternative="greater", method="asymptotic").pvalue
    assert normal > 10 * st.mann_whitney_p(x, y, "greater")  # what the normal approximation said
    tied = np.r_[y[:-1], 10.0]  # one y ties one x
    assert st.mann_whitney_method(x, tied) == "normal approximation, tie-corrected"
    assert st.mann_whitney_p(x, tied, "greater") == pytest.approx(
        scipy.stats.mannwhitneyu(x, tied, alternative="greater", method="asymptotic").pvalue
    )
    assert st.mann_whitney_method(np.ones(3), np.ones(4)) == "none: every score equal"


def test_interaction_is_the_change_of_the_effect_between_conditions():
    # Condition 1: a - b = 0.6 - 0.2 = 0.4; condition 2: 0.9 - 0.8 = 0.1 -> interaction -0.3.
    a1, b1 = np.full(4, 0.6), np.full(4, 0.2)
    a2, b2 = np.full(4, 0.9), np.full(4, 0.8)
    est = st.interaction(a1, b1, a2, b2, resamples=200)
    assert est.point[0] == pytest.approx(-0.3) and est.low[0] == pytest.approx(-0.3)
    assert est.sd[0] == pytest.approx(0, abs=1e-12)
    # Spread in one cell widens the interval around the same point (IQM of 8 seeds: the middle 4).
    spread = np.array([0.5, 0.55, 0.6, 0.6, 0.6, 0.6, 0.65, 0.7])
    est = st.interaction(spread, np.full(8, 0.2), a2, b2, resamples=500)
    assert est.point[0] == pytest.approx(-0.3) and est.low[0] < -0.3 < est.high[0]


def test_a_non_detection_whose_interval_lies_beyond_the_relevant_effect_says_so():
    # Across many comparisons Holm can leave a large bootstrap effect unconfirmed: not "outside".
    beyond = st.verdict("fs1", "baseline", _effect(0.35, 0.16, 0.51), 0.07, 0.33, "greater", 0.05)
    assert beyond.endswith(
        "the 95% interval lies beyond an effect of 0.05, the test at this level does not confirm it"
    )
    below = st.verdict("a", "b", _effect(0.01, -0.01, 0.02), 0.3, 0.03, "greater", 0.05)
    assert below.endswith("an effect of 0.05 is outside the 95% interval")
