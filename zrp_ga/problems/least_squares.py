"""Levenberg-Marquardt on a :class:`~zrp_ga.core.problem.LeastSquares` problem, as one
function: ``scipy.optimize.least_squares(method="lm")`` on its residual with its analytic
Jacobian, from the nominal parameters (x = 0) and unbounded, keeping the best genome any
evaluation saw. :class:`zrp_ga.algorithms.lm.LM` runs it as an optimiser (a convergence row per
evaluation); a problem kind that judges its answers by a calibration (the pose-selection
problem) calls it directly, without reaching up into the algorithms. The choices (scaling,
tolerances, ``"trf"`` for fewer rows than parameters) are explained in :mod:`zrp_ga.algorithms.lm`.
A robust problem (:class:`zrp_ga.problems.robust.RobustProblem`) is fitted by ``"trf"`` with
scipy's ``loss`` and ``f_scale`` on its plain rows (MINPACK's LM takes no loss).
MINPACK is handed one parameter more than the problem has, with a zero Jacobian column, so that
the same fit gives the same numbers every time (:func:`_padded` says why).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.problem import LeastSquares

Array = NDArray[np.float64]
X_SCALE = 1e-3  # m or rad per gene: 1 mm and 1 mrad weigh alike


@runtime_checkable
class RobustRows(Protocol):
    """What a least-squares problem with a robust ``loss`` (scipy's name, or ``linear``) of scale
    ``loss_scale`` has beside :class:`~zrp_ga.core.problem.LeastSquares`: its plain rows and
    their Jacobian, which scipy fits with that loss (:class:`zrp_ga.problems.robust.RobustProblem`)."""

    loss: str
    loss_scale: float

    def plain_residual(self, x: ArrayLike) -> Array: ...

    def plain_jacobian(self, x: ArrayLike) -> Array: ...


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

    # a robust problem (zrp_ga.problems.robust): scipy's loss on its plain rows
    robust_rows = problem if isinstance(problem, RobustRows) and problem.loss != "linear" else None
    rows = problem.residual if robust_rows is None else robust_rows.plain_residual

    def residual(x: Array) -> Array:
        r = rows(x)
        costs = evaluate(x[None])
        count[0] += 1
        seen(x, costs)
        return r

    method = "lm" if problem.n_rows >= x0.size and robust_rows is None else "trf"
    fun, jac, start = residual, lambda x: -(problem.jacobian(x) if robust_rows is None else robust_rows.plain_jacobian(x)), x0
    if method == "lm":
        fun, jac, start = _padded(residual, jac, x0.size, problem.n_rows)
    robust = {} if robust_rows is None else {"loss": robust_rows.loss, "f_scale": robust_rows.loss_scale}
    fit = least_squares(fun, start, jac=jac, method=method, max_nfev=max_evals, x_scale=np.full(start.size, X_SCALE),
                        ftol=1e-15, xtol=1e-15, gtol=1e-15, **robust)  # fmt: skip
    return Fit(best[0], best[1], count[0], f"{method}: {fit.message}", initial)


def _padded(residual: Callable[[Array], Array], jacobian: Callable[[Array], Array], n: int, rows: int):
    """The residual, Jacobian and start x = 0 with one more parameter that nothing depends on
    (a zero last Jacobian column), and a zero row when there are no more rows than parameters.

    Why: scipy's MINPACK (C since scipy 1.15, up to 1.17.1 at least) re-computes in its QR
    factorisation (``qrfac``) the norm of a column that has lost most of its length with one
    element too many, reading the element after the column; for the last column of the Jacobian
    that is past the end of its array, memory whose content depends on what the process
    allocated before (valgrind: "Invalid read of size 8 ... enorm, qrfac, LMDER ... 0 bytes after
    a block of size 8 m n"). The column pivoting then depends on it: the same fit took 39 to 47
    evaluations and ended 1e-13..1e-9 apart from one call to the next in one process. A zero
    column is never re-computed (its norm is 0) and is never pivoted forward (only a strictly
    larger norm is), so it stays last and the element read after each real column is in the
    array. Its step is always exactly 0: it changes no gene and no cost, only MINPACK's lower
    bound on the LM parameter (0 for a singular Jacobian), so the path differs from the unpadded
    fit's by rounding."""
    extra_row = rows <= n  # MINPACK's LM needs at least as many rows as parameters

    def fun(z: Array) -> Array:
        r = residual(z[:-1])
        return np.append(r, 0.0) if extra_row else r

    def jac(z: Array) -> Array:
        J = jacobian(z[:-1])
        return np.pad(J, ((0, int(extra_row)), (0, 1)))

    return fun, jac, np.zeros(n + 1)
