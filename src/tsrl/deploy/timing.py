"""Control-loop figures of a deployed episode: the achieved policy rate, latency and jitter.

All on the wall clock (`time.perf_counter`), the one clock every backend shares: a policy step starts
when the loop asks for the state; its latency runs from there until the period's first servo command
has been sent (state read, controller, interpolation, send). On hardware the servo waits pace the loop
to the robot; a MuJoCo backend without `realtime` runs as fast as it can, so its rate is the
simulation's speed, not a robot's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class LoopTiming:
    """One episode's control-loop figures (NaN where an episode has too few steps to give one).

    Attributes:
        steps: policy steps timed.
        nominal_hz: the contract's policy rate, 1 / control period [Hz].
        rate_hz: achieved policy rate: (steps - 1) / (last step's start - first step's start) [Hz].
        jitter_ms: standard deviation of the periods between consecutive step starts [ms].
        worst_period_error_ms: the largest |period - control period| between step starts [ms].
        latency_p50_ms, latency_max_ms: median and largest latency of a step [ms].
    """

    steps: int
    nominal_hz: float
    rate_hz: float
    jitter_ms: float
    worst_period_error_ms: float
    latency_p50_ms: float
    latency_max_ms: float

    @classmethod
    def of(cls, starts: Sequence[float], latencies: Sequence[float], control_period: float) -> LoopTiming:
        """The figures of step start times `starts` (k,) [s] and step latencies `latencies` (k,) [s] of a
        loop with policy period `control_period` [s]."""
        start = np.asarray(starts, dtype=np.float64)
        latency = np.asarray(latencies, dtype=np.float64) * 1e3
        periods = np.diff(start)
        if len(periods):
            rate = len(periods) / float(start[-1] - start[0])
            jitter = float(np.std(periods)) * 1e3
            worst = float(np.max(np.abs(periods - control_period))) * 1e3
        else:
            rate = jitter = worst = math.nan
        p50 = float(np.median(latency)) if len(latency) else math.nan
        most = float(np.max(latency)) if len(latency) else math.nan
        return cls(len(start), 1.0 / control_period, rate, jitter, worst, p50, most)

    def record(self) -> dict[str, float | int]:
        """The figures as a log record's `timing` entry."""
        return asdict(self)

    def summary(self) -> str:
        """One clause for `tsrl deploy`'s episode line."""
        return (
            f"rate {self.rate_hz:.1f} Hz (nominal {self.nominal_hz:g}), latency p50 "
            f"{self.latency_p50_ms:.2f} ms, max {self.latency_max_ms:.2f} ms, jitter {self.jitter_ms:.2f} ms "
            f"(worst period error {self.worst_period_error_ms:.2f} ms)"
        )


def worst_of(timings: Sequence[LoopTiming]) -> str:
    """One clause over episodes for `tsrl deploy`'s summary: the slowest rate, the largest latency and
    jitter."""
    if not timings:
        return "loop: no policy steps"
    return (
        f"loop over episodes: lowest rate {min(t.rate_hz for t in timings):.1f} Hz (nominal "
        f"{timings[0].nominal_hz:g}), latency max {max(t.latency_max_ms for t in timings):.2f} ms, largest "
        f"jitter {max(t.jitter_ms for t in timings):.2f} ms"
    )
