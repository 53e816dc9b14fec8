"""Parent selection on a vector of costs (lower is better; NaN and inf count as the worst).

Selections return indices into the population, so that a generation's parents are drawn in
one numpy call; ``tools.selTournament`` of DEAP does the same draw one Python loop at a time.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zrp_ga.operators.base import batched


def _finite(costs: NDArray) -> NDArray:
    return np.where(np.isfinite(costs), costs, np.inf)


@batched
def tournament(costs: NDArray, k: int, rng: np.random.Generator, size: int = 3) -> NDArray:
    """k winners of tournaments among ``size`` individuals drawn with replacement."""
    c = _finite(np.asarray(costs, dtype=float))
    entrants = rng.integers(0, len(c), size=(k, size))
    return entrants[np.arange(k), np.argmin(c[entrants], axis=1)]


@batched
def truncation(costs: NDArray, k: int, rng: np.random.Generator, fraction: float = 0.5) -> NDArray:
    """k parents drawn uniformly from the best ``fraction`` of the population."""
    c = _finite(np.asarray(costs, dtype=float))
    best = np.argsort(c, kind="stable")[: max(1, round(fraction * len(c)))]
    return best[rng.integers(0, len(best), size=k)]


@batched
def random(costs: NDArray, k: int, rng: np.random.Generator) -> NDArray:
    """k parents drawn uniformly, costs ignored (as DEAP's ``varOr`` picks them)."""
    return rng.integers(0, len(costs), size=k)
