"""The GA's survival against an answer written here: after each generation the population is the
mu best of parents and offspring (``mu_plus_lambda``), of the offspring (``mu_comma_lambda``), or
the ``elite`` best parents and the ``mu - elite`` best offspring (``generational``); NaN costs
last, equal costs in order (parents before offspring). A generation cut short by
``population.max_evals`` to fewer offspring than mu keeps the best mu of both, whatever the
strategy. The offspring are read from the problem as the GA evaluates them (every child is
changed, so every child is evaluated); runs alone and runs evolved together in one call
(:func:`zrp_ga.algorithms.ga.step_together`) are each held to the same answer, so that a bug they
share (the survival code is one) cannot hide behind their agreement."""

from __future__ import annotations

import numpy as np
import pytest

from zrp_ga import config
from zrp_ga.algorithms.ga import GA


class Recorded:
    """A problem whose cost is the sum of the genes rounded to 0.1 (so that costs tie), NaN where
    the first gene exceeds 0.6; it keeps every population it evaluates."""

    lower, upper, names = np.zeros(4), np.ones(4), ["a", "b", "c", "d"]

    def __init__(self):
        self.log: list[np.ndarray] = []

    @staticmethod
    def cost(X):
        X = np.atleast_2d(X)
        return np.where(X[:, 0] > 0.6, np.nan, np.round(X.sum(axis=1), 1))

    def costs(self, X):
        self.log.append(np.array(X, copy=True))
        return self.cost(X)


def _best(costs, m: int) -> list[int]:
    """Indices of the m least costs, NaN counted as the most, equal costs by position."""
    return sorted(range(len(costs)), key=lambda i: (costs[i] if np.isfinite(costs[i]) else np.inf, i))[:m]


def survivors(P, Pc, Q, Qc, mu: int, strategy: str, elite: int):
    """The population (genes, costs) survival should keep, from parents P (mu, K) and offspring Q."""
    if strategy == "mu_plus_lambda" or len(Q) < mu:
        genes, costs = np.vstack([P, Q]), np.concatenate([Pc, Qc])
        keep = _best(costs, mu)
        return genes[keep], costs[keep]
    if strategy == "mu_comma_lambda":
        keep = _best(Qc, mu)
        return Q[keep], Qc[keep]
    kept_parents, kept_children = _best(Pc, elite), _best(Qc, mu - elite)
    return np.vstack([P[kept_parents], Q[kept_children]]), np.concatenate([Pc[kept_parents], Qc[kept_children]])


def _sorted(genes, costs):
    """Rows in an order that does not depend on how survival arranged them."""
    order = np.lexsort((*genes.T[::-1], np.where(np.isfinite(costs), costs, np.inf)))
    return genes[order], costs[order]


def _ga(strategy: str, elite: int, mu: int, lam: int, max_evals: int | None = None) -> GA:
    overrides = ["refine=none", "crossover=blend", "crossover.prob=1", "mutation=gaussian", "mutation.prob=1",
                 "mutation.op.indpb=1.0", "inversion=none", "rotation=none", f"algorithm.strategy={strategy}",
                 f"algorithm.elite={elite}", f"population.mu={mu}", f"population.lambda_={lam}", "population.generations=4",
                 f"population.max_evals={'null' if max_evals is None else max_evals}"]  # fmt: skip
    return config.instantiate(config.load(overrides).algorithm, "algorithm")


CASES = [
    ("mu_plus_lambda", 1, 6, 9, None), ("mu_plus_lambda", 0, 5, 2, None), ("mu_comma_lambda", 1, 6, 9, None),
    ("mu_comma_lambda", 0, 5, 5, None), ("generational", 0, 6, 9, None), ("generational", 1, 6, 6, None),
    ("generational", 3, 6, 13, None), ("generational", 6, 6, 7, None), ("generational", 2, 6, 8, 6 + 8 + 3),
    ("mu_comma_lambda", 1, 6, 8, 6 + 8 + 3),
]  # fmt: skip


def _check_generation(ga: GA, before, offspring, history):
    P, Pc = before
    Q, Qc = offspring, Recorded.cost(offspring)
    mu, elite = ga.pop_conf.mu, ga.elite
    genes, costs = survivors(P, Pc, Q, Qc, mu, ga.strategy.value, elite)
    got = _sorted(ga.pop, ga.costs)
    want = _sorted(genes, costs)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    finite = costs[np.isfinite(costs)]
    if finite.size:
        assert ga.current()[1] == finite.min()  # the generation's reported best
    history.extend(Qc[np.isfinite(Qc)].tolist())
    assert ga.best_cost == min(history)  # the best ever seen, whatever survival kept


@pytest.mark.parametrize("strategy, elite, mu, lam, max_evals", CASES)
def test_survivors_of_a_run_alone_are_the_definitions(strategy, elite, mu, lam, max_evals):
    problem = Recorded()
    ga = _ga(strategy, elite, mu, lam, max_evals)
    ga.setup(problem, np.random.default_rng(mu + lam + elite))
    ga.initialize()
    history = ga.costs[np.isfinite(ga.costs)].tolist()
    while ga.has_next():
        before, nevals = (ga.pop.copy(), ga.costs.copy()), ga.nevals
        problem.log.clear()
        ga.step()
        (offspring,) = problem.log  # every child changed: one evaluation of all of them
        assert ga.nevals == nevals + len(offspring)
        _check_generation(ga, before, offspring, history)


def test_survivors_of_runs_evolved_together_are_each_runs_definition():
    """Runs of every strategy and elite (population 6) in one step_together call: each run's
    survivors its own answer."""
    problem = Recorded()
    runs = [_ga(*case) for case in CASES if case[2] == 6]  # runs together share the population size
    for k, ga in enumerate(runs):
        ga.setup(problem, np.random.default_rng(k))
        ga.initialize()
    histories = [ga.costs[np.isfinite(ga.costs)].tolist() for ga in runs]
    for _ in range(3):
        active = [i for i, ga in enumerate(runs) if ga.has_next()]
        before = {i: (runs[i].pop.copy(), runs[i].costs.copy(), runs[i].nevals) for i in active}
        problem.log.clear()
        GA.step_together([runs[i] for i in active])
        sizes = [runs[i].nevals - before[i][2] for i in active]  # every child changed: each evaluated once
        assert sum(sizes) == len(problem.log[0])
        for i, Q in zip(active, np.split(problem.log[0], np.cumsum(sizes)[:-1])):
            _check_generation(runs[i], before[i][:2], Q, histories[i])
