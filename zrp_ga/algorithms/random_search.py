"""Random search: independent random genomes, the best kept. On a pose-selection problem these
are random subsets (the problem's ``sample``): ``samples=1`` is the choice of poses an engineer
makes without any design, more samples a search as blind as it is cheap. On any other problem
the genomes are uniform in the gene ranges."""

from __future__ import annotations

import numpy as np

from zrp_ga.algorithms import Algorithm, AlgorithmSize, Result, genomes_bytes
from zrp_ga.core.problem import Sampling
from zrp_ga.core.schema import ConfigError
from zrp_ga.problems.size import ProblemSize


class RandomSearch(Algorithm):
    """``samples`` genomes in batches of ``batch``, one row of convergence.csv per batch."""

    def __init__(self, samples: int = 1, batch: int = 100) -> None:
        super().__init__()
        for key, value in (("samples", samples), ("batch", batch)):
            if value < 1:
                raise ConfigError(f"algorithm.{key}: must be at least 1, got {value}")
        self.samples, self.batch = int(samples), int(batch)

    def size(self, problem: ProblemSize) -> AlgorithmSize:
        """A batch of genomes at a time, ``samples`` in all."""
        P = min(self.batch, self.samples)
        return AlgorithmSize(P, self.samples, genomes_bytes(P, problem.genes), lower=("algorithm.batch", "lower algorithm.batch"))

    def initialize(self) -> None:
        self._draw()
        self.initial = (self.X.copy(), self.costs.copy())

    def step(self) -> None:
        self.gen += 1
        self._draw()

    def _draw(self) -> None:
        p, n = self.problem, min(self.batch, self.samples - self.nevals)
        self.X = p.sample(self.rng, n) if isinstance(p, Sampling) else self.rng.uniform(p.lower, p.upper, size=(n, p.lower.size))
        self.costs = self.toolbox.evaluate(self.X)
        self.nevals += n
        self.n_nonfinite = int(n - np.isfinite(self.costs).sum())
        self.offer(self.X, self.costs)
        self.stop_reason = "samples" if self.nevals >= self.samples else ""

    def fraction_done(self) -> float | None:
        return self.nevals / self.samples

    def result(self) -> Result:
        return Result(None if self.best_x is None else self.best_x.copy(), self.best_cost, self.nevals, self.stop_reason, *self.initial)
