"""Parent selection on a vector of costs (lower is better; NaN and inf count as the worst).

Selections return indices into the population, so that a generation's parents are drawn in
one numpy call; ``tools.selTournament`` of DEAP does the same draw one Python loop at a time.
With several runs' random streams (:class:`zrp_ga.operators.base.Streams`), ``costs`` is
(runs, population), ``k`` the parents of all runs, and each run's indices point into its own
population.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zrp_ga.operators.base import batched, draw, parts


def _finite(costs: NDArray) -> NDArray:
    return np.where(np.isfinite(costs), costs, np.inf)


def _runs(costs: NDArray, k: int, rng) -> tuple[NDArray, list]:
    """The costs as (runs, population) and each run's (generator, rows of the k parents): one
    run's costs (P,), or with :class:`~zrp_ga.operators.base.Streams` several runs' (R, P)."""
    c = np.atleast_2d(_finite(np.asarray(costs, dtype=float)))
    return c, parts(rng, k)


@batched(streams=True)
def tournament(costs: NDArray, k: int, rng: np.random.Generator, size: int = 3) -> NDArray:
    """k winners of tournaments among ``size`` individuals drawn with replacement."""
    c, runs = _runs(costs, k, rng)
    entrants = draw(rng, k, lambda g, n: g.integers(0, c.shape[1], size=(n, size)))
    run = np.repeat(np.arange(len(runs)), [s.stop - s.start for _, s in runs])
    return entrants[np.arange(k), np.argmin(c[run[:, None], entrants], axis=1)]


@batched(streams=True)
def truncation(costs: NDArray, k: int, rng: np.random.Generator, fraction: float = 0.5) -> NDArray:
    """k parents drawn uniformly from the best ``fraction`` of the population."""
    c, runs = _runs(costs, k, rng)
    best = np.argsort(c, axis=1, kind="stable")[:, : max(1, round(fraction * c.shape[1]))]
    picks = [b[g.integers(0, best.shape[1], size=s.stop - s.start)] for b, (g, s) in zip(best, runs)]
    return picks[0] if len(picks) == 1 else np.concatenate(picks)


@batched(streams=True)
def random(costs: NDArray, k: int, rng: np.random.Generator) -> NDArray:
    """k parents drawn uniformly, costs ignored (as DEAP's ``varOr`` picks them)."""
    return draw(rng, k, lambda g, n: g.integers(0, np.shape(costs)[-1], size=n))
