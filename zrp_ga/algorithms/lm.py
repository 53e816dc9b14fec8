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

import numpy as np

from zrp_ga.algorithms import Algorithm, Callback, Result
from zrp_ga.config import ConfigError
from zrp_ga.problems.protocol import LeastSquares

X_SCALE = 1e-3  # m or rad per gene: 1 mm and 1 mrad weigh alike


class LM(Algorithm):
    def __init__(self, max_evals: int | None = None) -> None:
        super().__init__()
        if max_evals is not None and max_evals < 1:
            raise ConfigError(f"algorithm.max_evals: must be at least 1 (or null), got {max_evals}")
        self.max_evals = max_evals

    def run(self, problem: LeastSquares, rng: np.random.Generator, callbacks: tuple[Callback, ...] = (), state: dict | None = None) -> Result:
        """One call of ``least_squares``; the callbacks see every residual evaluation."""
        from scipy.optimize import least_squares

        if state is not None:
            raise ConfigError("resume: only GA runs keep checkpoints")
        if not isinstance(problem, LeastSquares):
            raise ConfigError("algorithm: Levenberg-Marquardt needs a residual and its Jacobian (a calibration problem); "
                              "this problem has none")  # fmt: skip
        self.setup(problem, rng)
        rows: list[dict] = []
        for cb in callbacks:
            cb.on_start(self)
        x0 = np.zeros(problem.lower.size)
        self.costs = initial = self.toolbox.evaluate(x0[None])
        self.offer(x0[None], self.costs)
        self.emit(callbacks, rows)

        def residual(x: np.ndarray) -> np.ndarray:
            r = problem.residual(x)
            self.costs = self.toolbox.evaluate(x[None])
            self.gen = self.nevals = self.nevals + 1
            self.n_nonfinite = int(not np.isfinite(self.costs[0]))
            self.offer(x[None], self.costs)
            self.emit(callbacks, rows)
            return r

        method = "lm" if problem.n_rows >= x0.size else "trf"
        try:
            fit = least_squares(residual, x0, jac=lambda x: -problem.jacobian(x), method=method, max_nfev=self.max_evals,
                                x_scale=np.full(x0.size, X_SCALE), ftol=1e-15, xtol=1e-15, gtol=1e-15)  # fmt: skip
        except KeyboardInterrupt:
            for cb in callbacks:
                cb.on_interrupt(self)
            raise
        self.stop_reason = f"{method}: {fit.message}"
        result = Result(self.best_x, self.best_cost, self.nevals, self.stop_reason, x0[None], initial, rows)
        for cb in callbacks:
            cb.on_end(self, result)
        return result
