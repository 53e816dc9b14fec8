"""CMA-ES from the ``cma`` package, from the nominal parameters (mean 0), bounded to the gene
ranges, each gene's initial standard deviation ``sigma0`` times its range; a row per generation
(its population's costs, the best seen so far)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from zrp_ga.algorithms import Algorithm, AlgorithmSize, Result, evaluations, genomes_bytes
from zrp_ga.core import checks
from zrp_ga.core.schema import ConfigError, PopulationConf, section
from zrp_ga.problems.size import FLOAT, ProblemSize


class CMAES(Algorithm):
    def __init__(self, population: PopulationConf | Mapping[str, Any], sigma0: float) -> None:
        super().__init__()
        self.pop_conf: PopulationConf = section(PopulationConf, population, "population")
        checks.cmaes_population(self.pop_conf.lambda_)
        if not (np.isfinite(sigma0) and sigma0 > 0):
            raise ConfigError(f"algorithm.sigma0: must be a number > 0, got {sigma0}")
        self.sigma0 = sigma0

    def size(self, problem: ProblemSize) -> AlgorithmSize:
        """``lambda_`` genomes a generation; the ``cma`` package holds ``4 K^2 + 12 lambda K``
        numbers (its covariance matrix and eigenvectors, the population's copies: tracemalloc's
        peaks were 0.7-0.9 of that for K = 42 to 1200, lambda = 10 to 20 000)."""
        c, K = self.pop_conf, problem.genes
        own = FLOAT * (4 * K * K + 12 * c.lambda_ * K)
        return AlgorithmSize(c.lambda_, evaluations(c.generations, c.max_evals, 0, c.lambda_), genomes_bytes(c.lambda_, K) + own,
                             lower=("population.lambda_", "lower population.lambda_"))  # fmt: skip

    def initialize(self) -> None:
        import cma

        p, c = self.problem, self.pop_conf
        options = {
            "bounds": [list(p.lower), list(p.upper)], "CMA_stds": list(p.upper - p.lower), "popsize": c.lambda_,
            "seed": int(self.rng.integers(1, 2**31 - 1)), "verbose": -9, "tolfun": 0, "tolx": 0, "tolfunhist": 0,
            "maxiter": c.generations if c.generations is not None else np.inf,
            "maxfevals": c.max_evals if c.max_evals is not None else np.inf,
        }  # fmt: skip
        self.es = cma.CMAEvolutionStrategy(np.zeros(p.lower.size), self.sigma0, options)
        self._generation()
        self.initial = (self.X.copy(), self.costs.copy())

    def step(self) -> None:
        self.gen += 1
        self._generation()

    def _generation(self) -> None:
        self.X = np.array(self.es.ask())
        self.costs = self.toolbox.evaluate(self.X)
        self.nevals += len(self.X)
        self.n_nonfinite = int(self.costs.size - np.isfinite(self.costs).sum())
        self.es.tell(list(self.X), list(np.where(np.isfinite(self.costs), self.costs, np.finfo(float).max)))
        self.offer(self.X, self.costs)
        self.stop_reason = ", ".join(self.es.stop())

    def fraction_done(self) -> float | None:
        c = self.pop_conf
        return max((self.gen + 1) / c.generations if c.generations else 0.0, self.nevals / c.max_evals if c.max_evals else 0.0)

    def result(self) -> Result:
        return Result(self.best_x, self.best_cost, self.nevals, self.stop_reason, *self.initial)
