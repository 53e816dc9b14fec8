"""Exchange algorithm for choosing k of N candidates (pose selection): the one-point form of
Mitchell's DETMAX (T. J. Mitchell, "An algorithm for the construction of 'D-optimal'
experimental designs", Technometrics 16(2), 1974), for any of the problem's indices.

From a random subset S (the problem's ``sample``), each step

1. adds the candidate outside S whose addition gives the lowest cost (N - k subsets of k + 1),
2. removes the member of that k + 1 whose removal gives the lowest cost (k + 1 subsets of k),

and keeps the new subset if its cost is lower than that of S; otherwise S is a local optimum
(no single exchange of this kind improves it) and the run stops. Mitchell's DETMAX also makes
longer excursions (adding or removing several points in a row) when this stalls; they are not
implemented. Each step is a row of convergence.csv; its "population" is S.
"""

from __future__ import annotations

import numpy as np

from zrp_ga.algorithms import Algorithm, AlgorithmSize, Result, genomes_bytes
from zrp_ga.core.problem import Sampling
from zrp_ga.core.schema import ConfigError
from zrp_ga.problems.size import ProblemSize


class Exchange(Algorithm):
    def __init__(self, max_evals: int | None = None) -> None:
        super().__init__()
        if max_evals is not None and max_evals < 1:
            raise ConfigError(f"algorithm.max_evals: must be at least 1 (or null), got {max_evals}")
        self.max_evals = max_evals

    def size(self, problem: ProblemSize) -> AlgorithmSize:
        """A step evaluates every subset with one candidate added (N - k of them), then every one
        with one removed (k + 1), each batch at once; ``max_evals`` evaluations (None: until no
        exchange improves, not known before)."""
        k = problem.genes
        P = max((problem.choices or k + 1) - k, k + 1)
        return AlgorithmSize(P, self.max_evals, genomes_bytes(P, k) + genomes_bytes(P, k + 1),
                             lower=("problem", "the exchange algorithm evaluates a subset per candidate at once: "
                                               "choose among fewer candidate poses"))  # fmt: skip

    def initialize(self) -> None:
        p = self.problem
        if not isinstance(p, Sampling):
            raise ConfigError("algorithm: the exchange algorithm chooses subsets; use it with problem=pose_selection")
        self.S = p.sample(self.rng, 1)[0]
        self.costs = self.toolbox.evaluate(self.S[None])
        self.nevals = 1
        self.offer(self.S[None], self.costs)
        self.initial = (self.S[None].copy(), self.costs.copy())

    def step(self) -> None:
        """One exchange: the best addition, then the best removal; kept if it lowers the cost."""
        evaluate, S, k = self.toolbox.evaluate, self.S, self.S.size
        outside = np.setdiff1d(np.arange(int(self.problem.upper.max()) + 1), S).astype(float)
        grown = evaluate(np.column_stack([np.broadcast_to(S, (outside.size, k)), outside]))
        bigger = np.append(S, outside[np.argmin(np.where(np.isfinite(grown), grown, np.inf))])
        shrunk = np.broadcast_to(bigger, (k + 1, k + 1))[~np.eye(k + 1, dtype=bool)].reshape(k + 1, k)
        costs = evaluate(shrunk)
        self.nevals += outside.size + k + 1
        self.gen += 1
        best = int(np.argmin(np.where(np.isfinite(costs), costs, np.inf)))
        if costs[best] < self.costs[0]:
            self.S, self.costs = shrunk[best].copy(), costs[best : best + 1]
            self.offer(self.S[None], self.costs)
        else:
            self.stop_reason = "no exchange improves"
        if not self.stop_reason and self.max_evals is not None and self.nevals >= self.max_evals:
            self.stop_reason = "max_evals"

    def result(self) -> Result:
        return Result(None if self.best_x is None else self.best_x.copy(), self.best_cost, self.nevals, self.stop_reason, *self.initial)
