"""The ZRP cost in an ordinary DEAP script.

For people who come from DEAP: a calibration problem's cost as a DEAP fitness function
(:func:`evaluator`), a ``toolbox.map`` that evaluates a whole population in one vectorised call
(:func:`batched_map`), and DEAP types created once, here in a package module, so that parallel
workers can unpickle them (``creator.create`` in a script run as ``__main__`` breaks them). DEAP's
own ``algorithms.eaMuPlusLambda`` and operators then run unchanged; experiments/deap_example.py
shows a whole script.

>>> import numpy as np
>>> from deap import base
>>> from zrp_ga import robots
>>> from zrp_ga.problems import simulated
>>> problem = simulated.build(robots.get("puma560"), seed=0, n_poses=5, cost="nonlinear").problem
>>> toolbox = base.Toolbox()
>>> toolbox.register("evaluate", evaluator(problem))
>>> toolbox.register("map", batched_map(problem))
>>> pop = [Individual(x) for x in np.zeros((3, problem.lower.size))]
>>> [f[0] for f in toolbox.map(toolbox.evaluate, pop)] == [problem.costs(np.zeros(36))[0]] * 3
True
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np
from deap import base, creator

if not hasattr(creator, "ZRPFitness"):
    creator.create("ZRPFitness", base.Fitness, weights=(-1.0,))  # minimise the cost
    creator.create("ZRPIndividual", list, fitness=creator.ZRPFitness)

Fitness = creator.ZRPFitness
Individual = creator.ZRPIndividual  # a list of genes: DEAP's operators swap slices of lists correctly


def evaluator(problem) -> Callable[[Iterable[float]], tuple[float]]:
    """``evaluate(individual) -> (cost,)`` for one individual; NaN or inf (genes that break the
    model) become the largest float, DEAP's worst fitness for minimisation."""

    def evaluate(individual: Iterable[float]) -> tuple[float]:
        cost = float(problem.costs(np.asarray(individual, dtype=float)[None])[0])
        return (cost if np.isfinite(cost) else np.finfo(float).max,)

    evaluate.problem = problem
    return evaluate


def batched_map(problem) -> Callable:
    """A ``toolbox.map``: the problem's own evaluator is applied to the whole population in one
    vectorised ``problem.costs`` call; any other function is mapped as the builtin ``map`` does."""

    def mapper(func: Callable, *iterables: Iterable) -> list:
        if getattr(func, "problem", None) is problem and len(iterables) == 1:
            individuals = list(iterables[0])
            if not individuals:
                return []
            costs = problem.costs(np.asarray(individuals, dtype=float))
            return [(float(c) if np.isfinite(c) else np.finfo(float).max,) for c in costs]
        return list(map(func, *iterables))

    return mapper
