"""Statistics across seeds, on rliable (Agarwal et al. 2021, "Deep RL at the Edge of the Statistical
Precipice"): interquartile means with stratified-bootstrap intervals, probability of improvement,
performance profiles; and what rliable lacks: the normalised area under a success curve, Kaplan-Meier
time to a threshold (seeds that never reach it are censored, not dropped), one-sided Mann-Whitney
p-values (exact where SciPy can), Holm's correction, the minimum detectable effect, the verdict rule
and floor/ceiling flags.

One interval method everywhere (`tsrl report`, `tsrl plot`): the 95% percentile interval of rliable's
stratified bootstrap (what `rliable.library.get_interval_estimates` returns with method="percentile"),
RESAMPLES resamples of the runs, seeded. A study has one task per arm, so the strata are trivial and
the bootstrap resamples the seeds of each arm with replacement; each evaluation of a curve is
resampled on its own (pointwise intervals).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.integrate
import scipy.stats
from rliable import library

RESAMPLES = 5_000
"""Bootstrap resamples of every interval."""
SEED = 0
"""Seed of numpy's global RNG during a bootstrap: the same data always give the same interval."""
CONFIDENCE = 0.95
ALPHA = 0.05
"""Family-wise error rate of a study's comparisons (Holm)."""
POWER = 0.8
"""Power at which the minimum detectable effect is stated."""
THRESHOLDS: tuple[float, ...] = (0.5, 0.9, 0.95)
"""Success rates whose time to reach is reported (and drawn in the learning curves); 95 % is where
the benchmarks' and issues' targets stand."""

Direction = Literal["greater", "less", "two-sided"]


@dataclass(frozen=True)
class Estimate:
    """A point estimate with its bootstrap interval and standard deviation (arrays for curves)."""

    point: np.ndarray
    low: np.ndarray
    high: np.ndarray
    sd: np.ndarray
    """Standard deviation of the bootstrap distribution (the estimate's standard error)."""


@contextlib.contextmanager
def _seeded(seed: int) -> Iterator[None]:
    """rliable 1.2 draws resampling indices from numpy's global RNG (its `random_state` argument
    does not reach them): seed it for the block and restore the caller's state after."""
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


def bootstrap(
    func: Callable[..., np.ndarray], *samples: np.ndarray, resamples: int = RESAMPLES, seed: int = SEED
) -> Estimate:
    """`func` of `samples` (each (runs, tasks[, evaluations])) with its 95% percentile interval from
    rliable's stratified bootstrap: one sample resampled by StratifiedBootstrap, several each on its
    own (StratifiedIndependentBootstrap). `func` returns a 1-D array."""
    bs = (
        library.StratifiedBootstrap(samples[0])
        if len(samples) == 1
        else library.StratifiedIndependentBootstrap(*samples)
    )
    with _seeded(seed):
        cov = bs.cov(func, reps=resamples)
        low, high = bs.conf_int(func, reps=resamples, size=CONFIDENCE, method="percentile", reuse=True)
    return Estimate(np.asarray(func(*samples)), low, high, np.sqrt(np.diag(np.atleast_2d(cov))))


def iqm(scores: np.ndarray) -> np.ndarray:
    """Interquartile mean over runs (axis 0), per remaining column: rliable's aggregate_iqm (scipy's
    25% trimmed mean: int(n / 4) runs cut at each end), for every evaluation of a curve at once and
    without scipy's per-call overhead (a bootstrap calls it thousands of times)."""
    scores = np.asarray(scores, dtype=float).reshape(len(scores), -1)
    cut = len(scores) // 4
    return np.sort(scores, axis=0)[cut : len(scores) - cut].mean(axis=0)


def iqm_interval(values: np.ndarray, resamples: int = RESAMPLES) -> Estimate:
    """IQM across seeds and its interval; values (n seeds,) or (n seeds, m evaluations)."""
    values = np.asarray(values, dtype=float)
    return bootstrap(iqm, values.reshape(len(values), 1, -1), resamples=resamples)


def _improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X > Y) + P(X = Y) / 2 over all pairs of x (n_x, 1) and y (n_y, 1): the value of rliable's
    metrics.probability_of_improvement on one task (the Mann-Whitney U over n_x n_y), without a scipy
    call per bootstrap resample."""
    diff = x[:, 0, None] - y[None, :, 0]
    return np.array([np.mean((diff > 0) + 0.5 * (diff == 0))])


def probability_of_improvement(x: np.ndarray, y: np.ndarray, resamples: int = RESAMPLES) -> Estimate:
    """P(X > Y) + P(X = Y) / 2 for a random seed of each arm and its interval, from per-seed scores x
    (n_x,) and y (n_y,)."""
    return bootstrap(
        _improvement,
        np.reshape(x, (-1, 1)).astype(float),
        np.reshape(y, (-1, 1)).astype(float),
        resamples=resamples,
    )


def iqm_difference(x: np.ndarray, y: np.ndarray, resamples: int = RESAMPLES) -> Estimate:
    """IQM(x) - IQM(y) over per-seed scores, each arm's seeds resampled on their own."""
    return bootstrap(
        lambda a, b: iqm(a) - iqm(b),
        np.reshape(x, (-1, 1)).astype(float),
        np.reshape(y, (-1, 1)).astype(float),
        resamples=resamples,
    )


def performance_profile(
    scores: dict[str, np.ndarray], taus: np.ndarray, resamples: int = RESAMPLES
) -> dict[str, Estimate]:
    """Per arm, the fraction of its seeds whose score exceeds each tau, with its interval (rliable's
    score distribution); scores: arm -> per-seed scores (n,)."""
    arrays = {k: np.reshape(v, (-1, 1)).astype(float) for k, v in scores.items()}
    with _seeded(SEED):
        points, intervals = library.create_performance_profile(arrays, taus, reps=resamples)
    nan = np.full(len(taus), math.nan)
    return {k: Estimate(points[k], intervals[k][0], intervals[k][1], nan) for k in scores}


def area_under_curve(env_steps: np.ndarray, success: np.ndarray) -> np.ndarray:
    """Normalised area under success curves: the trapezoid integral over env steps divided by the
    span of env steps, in [0, 1] (1: success 1 at every evaluation). success (m,) or (n seeds, m)."""
    env_steps = np.asarray(env_steps, dtype=float)
    if len(env_steps) < 2:
        raise ValueError("the area under a curve needs at least two evaluations")
    return scipy.integrate.trapezoid(success, env_steps, axis=-1) / (env_steps[-1] - env_steps[0])


def kaplan_meier(times: np.ndarray, reached: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kaplan-Meier estimate of P(not yet reached at t): event times t_j and S(t_j) = prod over
    t_i <= t_j of (1 - d_i / n_i), d_i seeds reaching at t_i, n_i seeds not reached before t_i (a
    censored seed stays at risk up to and including its censoring time).

    times: per seed, the first evaluation at the threshold, or the last evaluation if it never got
    there; reached: whether it got there (False: censored at `times`)."""
    times = np.asarray(times, dtype=float)
    reached = np.asarray(reached, dtype=bool)
    event_times = np.unique(times[reached])
    at_risk = np.array([(times >= t).sum() for t in event_times])
    events = np.array([(reached & (times == t)).sum() for t in event_times])
    return event_times, np.cumprod(1.0 - events / at_risk)


def km_median(times: np.ndarray, reached: np.ndarray) -> float:
    """The Kaplan-Meier median time: the first event time with S(t) <= 0.5; inf when fewer than
    half the seeds are known to have reached it (the median lies beyond the budget)."""
    event_times, survival = kaplan_meier(times, reached)
    below = np.flatnonzero(survival <= 0.5 + 1e-12)  # S is a product of fractions: 0.5 up to rounding
    return float(event_times[below[0]]) if len(below) else math.inf


#: The largest n_a x n_b at which SciPy's exact Mann-Whitney distribution is used (without ties).
EXACT_MAX_PAIRS = 10_000
MannWhitneyMethod = Literal["exact", "normal approximation, tie-corrected", "none: every score equal"]


def mann_whitney_method(x: np.ndarray, y: np.ndarray) -> MannWhitneyMethod:
    """How mann_whitney_p computes p for scores x and y: SciPy's exact null distribution when no score
    is tied and n_x n_y <= EXACT_MAX_PAIRS (the exact distribution assumes no ties), otherwise the normal
    approximation with tie and continuity correction; no test when every score is the same."""
    scores = np.concatenate([x, y])
    if np.ptp(scores) == 0:
        return "none: every score equal"
    if len(np.unique(scores)) == len(scores) and len(x) * len(y) <= EXACT_MAX_PAIRS:
        return "exact"
    return "normal approximation, tie-corrected"


def mann_whitney_p(x: np.ndarray, y: np.ndarray, direction: Direction) -> float:
    """p-value of the Mann-Whitney U test of per-seed scores x against y, by mann_whitney_method;
    direction "greater": the alternative is that x tends to exceed y."""
    method = mann_whitney_method(x, y)
    if method == "none: every score equal":
        return 1.0  # every seed of both arms has the same score: no evidence either way
    scipy_method = "exact" if method == "exact" else "asymptotic"
    return float(scipy.stats.mannwhitneyu(x, y, alternative=direction, method=scipy_method).pvalue)


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values (family-wise error control over a study's comparisons):
    the i-th smallest p becomes max over j <= i of min(1, (m - j + 1) p_(j))."""
    p = np.asarray(p_values, dtype=float)
    order = np.argsort(p, kind="stable")
    m = len(p)
    adjusted = np.minimum(1.0, np.maximum.accumulate((m - np.arange(m)) * p[order]))
    out = np.empty(m)
    out[order] = adjusted
    return out


def minimum_detectable_effect(sd: float, comparisons: int, direction: Direction) -> float:
    """The effect a test at level ALPHA / comparisons (Holm's strictest step) detects with power POWER,
    for an estimate with standard error `sd` (normal approximation): (z_{1-a} + z_power) sd, with
    a = ALPHA / comparisons, halved for a two-sided test."""
    level = ALPHA / comparisons / (2 if direction == "two-sided" else 1)
    return float((scipy.stats.norm.ppf(1 - level) + scipy.stats.norm.ppf(POWER)) * sd)


def verdict(
    a: str,
    b: str,
    effect: Estimate,
    p_holm: float,
    mde: float,
    direction: Direction,
    min_effect: float | None,
) -> str:
    """What a comparison's data can say, and no more: a difference is "detected" only at a
    Holm-adjusted p below ALPHA, and "detected, smaller than the relevant effect" when the comparison
    states the effect that matters (`min_effect`, e.g. the paper's) and the whole 95% interval lies
    on the near side of it; otherwise "no detectable difference at this power", with the minimum
    detectable effect and, with `min_effect`, whether the interval excludes it, whether the study could
    have detected it, or that it could not (inconclusive)."""
    if p_holm >= ALPHA and effect.sd[0] == 0:
        return (
            "no detectable difference; the seeds of each arm scored alike, so the power cannot be estimated"
        )
    if p_holm < ALPHA:
        higher = direction == "greater" or (direction == "two-sided" and effect.point[0] > 0)
        found = f"{a} {'above' if higher else 'below'} {b}"
        # the interval's far end on the detected side: its largest distance from 0 in that direction
        far = effect.high[0] if higher else -effect.low[0]
        if min_effect is not None and far < min_effect:
            return (
                f"detected, smaller than the relevant effect: {found} by less than {min_effect:g} "
                "(the whole 95% interval)"
            )
        return f"detected: {found}"
    text = f"no detectable difference at this power (detectable with {POWER:.0%} power: {mde:.3g})"
    if min_effect is None:
        return text
    claimed = {"greater": [min_effect], "less": [-min_effect], "two-sided": [min_effect, -min_effect]}[
        direction
    ]
    if not any(effect.low[0] <= c <= effect.high[0] for c in claimed):
        beyond = effect.low[0] > min_effect if direction != "less" else effect.high[0] < -min_effect
        if beyond or (direction == "two-sided" and effect.high[0] < -min_effect):
            return f"{text}; the 95% interval lies beyond an effect of {min_effect:g}, the test at this level does not confirm it"
        return f"{text}; an effect of {min_effect:g} is outside the 95% interval"
    if mde <= min_effect:
        return f"{text}; it had the power to detect an effect of {min_effect:g} and did not"
    return f"{text}; too few seeds to detect an effect of {min_effect:g}: inconclusive"


BOUND_MARGIN = 0.02
"""An interval of a rate within this of 0 or 1 touches the floor or the ceiling (0.02: one
evaluation episode in 50, the studies' resolution)."""


def bound_flags(low: float, high: float) -> str:
    """ "floor" when an interval of a rate in [0, 1] (success, AUC) touches 0, "ceiling" when it
    touches 1 (within BOUND_MARGIN), both joined by ", ", or "": a difference at a bound says little,
    the bound caps it."""
    flags = ["floor"] * bool(low <= BOUND_MARGIN) + ["ceiling"] * bool(high >= 1 - BOUND_MARGIN)
    return ", ".join(flags)


def interaction(
    a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray, resamples: int = RESAMPLES
) -> Estimate:
    """The interaction of a 2 x 2 design from per-seed scores of its four cells: how much the effect
    IQM(a) - IQM(b) changes from condition 1 to condition 2, [IQM(a2) - IQM(b2)] - [IQM(a1) - IQM(b1)],
    with its 95% interval (each cell's seeds resampled on their own)."""
    cells = [np.reshape(v, (-1, 1)).astype(float) for v in (a1, b1, a2, b2)]
    return bootstrap(lambda w, x, y, z: (iqm(y) - iqm(z)) - (iqm(w) - iqm(x)), *cells, resamples=resamples)
