"""Levenberg-Marquardt on a :class:`~zrp_ga.problems.protocol.LeastSquares` problem, as one
function: ``scipy.optimize.least_squares(method="lm")`` on its residual with its analytic
Jacobian, from the nominal parameters (x = 0) and unbounded, keeping the best genome any
evaluation saw. :class:`zrp_ga.algorithms.lm.LM` runs it as an optimiser (a convergence row per
evaluation); a problem kind that judges its answers by a calibration (the pose-selection
problem) calls it directly, without reaching up into the algorithms. The choices (scaling,
tolerances, ``"trf"`` for fewer rows than parameters) are explained in :mod:`zrp_ga.algorithms.lm`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zrp_ga.problems.protocol import LeastSquares

Array = NDArray[np.float64]
X_SCALE = 1e-3  # m or rad per gene: 1 mm and 1 mrad weigh alike


@dataclasses.dataclass
class Fit:
    """The best genome seen ``x`` (None if no cost was finite) and its ``cost``, the residual
    evaluations after the start's (``nevals``), scipy's ``message`` prefixed by the method,
    and the cost (1,) of the start x = 0."""

    x: Array | None
    cost: float
    nevals: int
    message: str
    initial_cost: Array


def levenberg_marquardt(
    problem: LeastSquares,
    max_evals: int | None = None,
    evaluate: Callable[[Array], Array] | None = None,
    on_evaluation: Callable[[Array, Array, int], None] | None = None,
) -> Fit:
    """Fit ``problem`` from x = 0. ``evaluate``: the costs of a population (default
    ``problem.costs``; an optimiser passes its timed toolbox's); ``on_evaluation(x, costs, k)``
    is called after the start's evaluation (k = 0) and after each residual evaluation (k = 1, 2, ..)."""
    from scipy.optimize import least_squares

    evaluate = evaluate or problem.costs
    x0 = np.zeros(problem.lower.size)
    best: list = [None, np.inf]
    count = [0]

    def seen(x: Array, costs: Array) -> None:
        if np.isfinite(costs[0]) and costs[0] < best[1]:
            best[:] = [np.array(x, dtype=float), float(costs[0])]
        if on_evaluation is not None:
            on_evaluation(x, costs, count[0])

    initial = evaluate(x0[None])
    seen(x0, initial)

    def residual(x: Array) -> Array:
        r = problem.residual(x)
        costs = evaluate(x[None])
        count[0] += 1
        seen(x, costs)
        return r

    method = "lm" if problem.n_rows >= x0.size else "trf"
    fit = least_squares(residual, x0, jac=lambda x: -problem.jacobian(x), method=method, max_nfev=max_evals,
                        x_scale=np.full(x0.size, X_SCALE), ftol=1e-15, xtol=1e-15, gtol=1e-15)  # fmt: skip
    return Fit(best[0], best[1], count[0], f"{method}: {fit.message}", initial)
