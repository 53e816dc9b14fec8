"""Levenberg-Marquardt: ``scipy.optimize.least_squares(method="lm")`` on the problem's residual
with its analytic Jacobian, from the nominal parameters and unbounded; its final cost is the
floor the GA is judged against. With fewer residual rows than parameters (one pose) MINPACK's
LM refuses, and the trust-region reflective method (``"trf"``) is used instead. A row is
written per residual evaluation (its "population" is that one genome).

Scaling: every gene has the characteristic scale ``X_SCALE`` = 1e-3 (``x_scale`` of
``least_squares``), so that a millimetre of a body vector and a milliradian of an axis weigh
alike and the first trust region spans about 0.1 m or rad, whatever the arm. scipy's default
for ``"lm"`` since 1.16 (``x_scale="jac"``, the inverse column norms of the Jacobian) makes the
step sizes depend on how well each parameter is seen, so that weakly seen ones (the tilts of an
axis that passes near the measured point) may take the largest steps. On the problems measured
so far (the UR10 series, experiments/own_arm, the 30-pose simulation) both end at the same
cost; the fixed scale took as many or fewer evaluations."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from zrp_ga.algorithms import Algorithm, AlgorithmSize, Callback, Result, Row, State, genomes_bytes
from zrp_ga.core.problem import LeastSquares, Problem
from zrp_ga.core.schema import ConfigError
from zrp_ga.problems.least_squares import X_SCALE, levenberg_marquardt  # noqa: F401 (X_SCALE: named here as before)
from zrp_ga.problems.size import FLOAT, ProblemSize


class LM(Algorithm):
    def __init__(self, max_evals: int | None = None) -> None:
        super().__init__()
        if max_evals is not None and max_evals < 1:
            raise ConfigError(f"algorithm.max_evals: must be at least 1 (or null), got {max_evals}")
        self.max_evals = max_evals

    def size(self, problem: ProblemSize) -> AlgorithmSize:
        """One genome at a time and its Jacobian ``(R, K)`` twice (scipy's and MINPACK's copy);
        ``max_evals`` evaluations (None: MINPACK's own count, not known before)."""
        held = genomes_bytes(1, problem.genes) + FLOAT * 2 * problem.rows * problem.genes
        return AlgorithmSize(1, self.max_evals, held, lower=("problem", "Levenberg-Marquardt holds one genome: lower the problem's size"))

    def run(self, problem: Problem, rng: np.random.Generator, callbacks: Sequence[Callback] = (), state: State | None = None) -> Result:
        """One fit (:func:`zrp_ga.problems.least_squares.levenberg_marquardt`); the callbacks see
        every residual evaluation."""
        if state is not None:
            raise ConfigError("resume: only GA runs keep checkpoints")
        if not isinstance(problem, LeastSquares):
            raise ConfigError("algorithm: Levenberg-Marquardt needs a residual and its Jacobian (a calibration problem); "
                              "this problem has none")  # fmt: skip
        self.setup(problem, rng)
        rows: list[Row] = []
        for cb in callbacks:
            cb.on_start(self)

        def evaluated(x: np.ndarray, costs: np.ndarray, k: int) -> None:
            self.costs = costs
            if k:
                self.gen = self.nevals = k
                self.n_nonfinite = int(not np.isfinite(costs[0]))
            self.offer(x[None], costs)
            self.emit(callbacks, rows)

        try:
            fit = levenberg_marquardt(problem, self.max_evals, self.toolbox.evaluate, evaluated)
        except KeyboardInterrupt:
            for cb in callbacks:
                cb.on_interrupt(self)
            raise
        self.stop_reason = fit.message
        x0 = np.zeros(problem.lower.size)
        result = Result(self.best_x, self.best_cost, self.nevals, self.stop_reason, x0[None], fit.initial_cost, rows)
        for cb in callbacks:
            cb.on_end(self, result)
        return result
