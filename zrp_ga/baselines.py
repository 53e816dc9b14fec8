"""The methods a user would otherwise pick, on the same problem and writing the same files.

- :func:`lm`: Levenberg-Marquardt, ``scipy.optimize.least_squares(method="lm")`` on the
  problem's residual with its analytic Jacobian, unbounded (its cost is the floor the GA is
  judged against). With fewer residual rows than parameters (one pose) MINPACK's LM refuses, and
  the trust-region reflective method (``"trf"``) is used instead.
- :func:`cmaes`: CMA-ES from the ``cma`` package, bounded to the gene ranges, each gene's
  initial standard deviation ``sigma0`` times its range.

Both call ``on_generation(row, best_genome, best_cost)`` like :func:`zrp_ga.ga.evolve`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import cma
import numpy as np
from scipy.optimize import least_squares

from zrp_ga.ga import RunResult, population_stats
from zrp_ga.problem import CalibrationProblem


def _row(gen: int, nevals: int, costs: np.ndarray, t_start: float, t_eval: float) -> dict:
    stats = population_stats(np.sort(costs))  # np.sort puts NaN last, inf after every finite cost
    return dict(
        gen=gen, nevals=nevals, **stats, n_nonfinite=int(costs.size - np.isfinite(costs).sum()),
        eval_s=t_eval, bookkeeping_s=0.0, refine_s=0.0, wall_s=time.perf_counter() - t_start,
    )


def lm(
    problem: CalibrationProblem, max_evals: int | None = None, on_generation: Callable | None = None
) -> RunResult:
    """Levenberg-Marquardt from the nominal parameters; one row per residual evaluation."""
    K = problem.layout.size
    t_start = time.perf_counter()
    x0 = np.zeros(K)
    state = {"nevals": 0, "best": np.inf, "x": x0}

    def fun(x: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        r = problem.residual(x)
        cost = problem.costs(x)
        state["nevals"] += 1
        if cost[0] < state["best"]:
            state["best"], state["x"] = float(cost[0]), x.copy()
        if on_generation is not None:
            row = _row(state["nevals"], state["nevals"], cost, t_start, time.perf_counter() - t0)
            row["best"] = state["best"]
            on_generation(row, state["x"], state["best"])
        return r

    initial = problem.costs(x0)
    if on_generation is not None:
        on_generation(_row(0, 0, initial, t_start, 0.0), x0, float(initial[0]))
    method = "lm" if problem.n_rows >= K else "trf"
    res = least_squares(fun, x0, jac=lambda x: -problem.jacobian(x), method=method, max_nfev=max_evals,
                        ftol=1e-15, xtol=1e-15, gtol=1e-15)  # fmt: skip
    return RunResult(state["x"], state["best"], x0[None], initial, state["nevals"], f"{method}: {res.message}")


def cmaes(
    problem: CalibrationProblem,
    popsize: int,
    rng: np.random.Generator,
    generations: int | None = None,
    max_evals: int | None = None,
    sigma0: float = 0.3,
    on_generation: Callable | None = None,
) -> RunResult:
    """CMA-ES from the nominal parameters (mean 0) within the gene ranges; a row per generation."""
    t_start = time.perf_counter()
    K = problem.layout.size
    width = problem.upper - problem.lower
    options = {
        "bounds": [list(problem.lower), list(problem.upper)], "CMA_stds": list(width), "popsize": popsize,
        "seed": int(rng.integers(1, 2**31 - 1)), "verbose": -9, "tolfun": 0, "tolx": 0, "tolfunhist": 0,
        "maxiter": generations if generations is not None else np.inf,
        "maxfevals": max_evals if max_evals is not None else np.inf,
    }  # fmt: skip
    es = cma.CMAEvolutionStrategy(np.zeros(K), sigma0, options)
    best, best_cost, nevals, gen = np.zeros(K), np.inf, 0, 0
    initial_genes = initial_costs = None
    while not es.stop():
        X = np.array(es.ask())
        t0 = time.perf_counter()
        costs = problem.costs(X)
        t_eval = time.perf_counter() - t0
        nevals += len(X)
        if initial_genes is None:
            initial_genes, initial_costs = X.copy(), costs.copy()
        es.tell(list(X), list(np.where(np.isfinite(costs), costs, np.finfo(float).max)))
        k = int(np.argmin(np.where(np.isfinite(costs), costs, np.inf)))
        if costs[k] < best_cost:
            best, best_cost = X[k].copy(), float(costs[k])
        if on_generation is not None:
            row = _row(gen, nevals, costs, t_start, t_eval)
            row["best"] = best_cost
            on_generation(row, best, best_cost)
        gen += 1
    stop = ", ".join(f"{k}" for k in es.stop())
    return RunResult(best, best_cost, initial_genes, initial_costs, nevals, stop)
