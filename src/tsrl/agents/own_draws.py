"""Random draws apart from a run's: networks an option adds (further critic heads, further clones)
draw from generators of their own, so every network the run had without the option starts, and
trains, as it did."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch as th


@contextmanager
def own_draws(offset: int) -> Iterator[None]:
    """Inside: torch's CPU generator and numpy's global one seeded with the run's torch seed +
    `offset`; after: both as they were before (the run's own draws go on untouched)."""
    numpy_state = np.random.get_state()
    try:
        with th.random.fork_rng(devices=[]):
            seed = th.initial_seed() + offset
            th.manual_seed(seed)
            np.random.seed(seed % 2**32)
            yield
    finally:
        np.random.set_state(numpy_state)
