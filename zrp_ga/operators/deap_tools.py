"""The ZRP cost and zrp_ga's operators in an ordinary DEAP script.

For people who come from DEAP: a calibration problem's cost as a DEAP fitness function
(:func:`evaluator`), a ``toolbox.map`` that evaluates a whole population in one vectorised call
(:func:`batched_map`), zrp_ga's operators (:mod:`zrp_ga.operators`, the pseudo-inverse step
among them) as DEAP operators on list individuals (:func:`for_deap`), the checkBounds recipe
(:func:`within`), and DEAP types created once, here in a package module, so that parallel
workers can unpickle them (``creator.create`` in a script run as ``__main__`` breaks them). DEAP's
own ``algorithms.eaMuPlusLambda`` then runs unchanged; experiments/deap_example.py shows a whole
script.

zrp_ga's operators take numpy genomes (one (K,) or a batch (N, K)) and a
``numpy.random.Generator``; DEAP's individuals are lists, so an operator registered as it is
fails (``'ZRPIndividual' object has no attribute 'ndim'``). :func:`for_deap` binds the
generator and the parameters and converts: the lists' genes go into an array, the operator
changes it, the new genes go back into the same lists (DEAP's in-place convention); a selection
takes the individuals' fitness as the cost and returns the chosen individuals.

>>> import numpy as np
>>> from deap import base
>>> from zrp_ga.io import presets
>>> from zrp_ga.problems import simulated
>>> problem = simulated.build(presets.get("puma560"), seed=0, n_poses=5, cost="nonlinear").problem
>>> toolbox = base.Toolbox()
>>> toolbox.register("evaluate", evaluator(problem))
>>> toolbox.register("map", batched_map(problem))
>>> pop = [Individual(x) for x in np.zeros((3, problem.lower.size))]
>>> [f[0] for f in toolbox.map(toolbox.evaluate, pop)] == [problem.costs(np.zeros(36))[0]] * 3
True
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterable, Sequence

import numpy as np
from deap import base, creator

from zrp_ga.core.problem import Problem
from zrp_ga.operators.repair import repair

if not hasattr(creator, "ZRPFitness"):
    creator.create("ZRPFitness", base.Fitness, weights=(-1.0,))  # minimise the cost
    creator.create("ZRPIndividual", list, fitness=creator.ZRPFitness)

Fitness = creator.ZRPFitness
Individual = creator.ZRPIndividual  # a list of genes: DEAP's operators swap slices of lists correctly


def evaluator(problem: Problem) -> Callable[[Iterable[float]], tuple[float]]:
    """``evaluate(individual) -> (cost,)`` for one individual; NaN or inf (genes that break the
    model) become the largest float, DEAP's worst fitness for minimisation."""

    def evaluate(individual: Iterable[float]) -> tuple[float]:
        cost = float(problem.costs(np.asarray(individual, dtype=float)[None])[0])
        return (cost if np.isfinite(cost) else np.finfo(float).max,)

    evaluate.problem = problem  # type: ignore[attr-defined]  # a function attribute: batched_map knows its evaluator by it
    return evaluate


def batched_map(problem: Problem) -> Callable:
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


def _family(op: Callable) -> str:
    """``crossover`` (two genomes first), ``selection`` (costs first) or ``mutation`` (one genome)."""
    first = list(inspect.signature(op).parameters)[:2]
    if first[:1] == ["costs"]:
        return "selection"
    return "crossover" if first[1:] == ["ind2"] else "mutation"


def _cost(ind) -> float:
    """The cost of a DEAP individual: its first fitness value (NaN while invalid)."""
    return ind.fitness.values[0] if ind.fitness.valid else np.nan


def for_deap(op: Callable, rng: np.random.Generator, family: str | None = None, **params) -> Callable:
    """A zrp_ga operator ``op`` with ``rng`` and ``params`` bound, in DEAP's convention on list
    individuals: ``mate(ind1, ind2) -> (ind1, ind2)`` and ``mutate(ind) -> (ind,)`` change the
    lists in place (one-genome families: mutation, inversion, rotation, the pseudo-inverse step
    ``zrp_ga.operators.refine.pinv``); ``select(individuals, k) -> k individuals`` by their
    first fitness value, lower is better (costs, as :class:`Fitness` minimises them).
    ``family``: ``crossover``, ``selection`` or ``mutation``; by default from ``op``'s first
    parameters (``ind1, ind2``: crossover; ``costs``: selection; else one genome).

    >>> import random
    >>> from zrp_ga.operators import crossover
    >>> mate = for_deap(crossover.two_point, np.random.default_rng(0))
    >>> a, b = Individual([0.0] * 6), Individual([1.0] * 6)
    >>> mate(a, b) == (a, b) and sorted(a + b) == [0.0] * 6 + [1.0] * 6 and type(a) is Individual
    True
    """
    family = family or _family(op)
    bound = functools.partial(op, rng=rng, **params)
    if family == "selection":

        @functools.wraps(op)
        def select(individuals: Sequence, k: int) -> list:
            chosen = bound(np.array([_cost(ind) for ind in individuals], dtype=float), k)
            return [individuals[i] for i in chosen]

        return select
    if family == "crossover":

        @functools.wraps(op)
        def mate(ind1: list, ind2: list) -> tuple[list, list]:
            A, B = np.array([ind1], dtype=float), np.array([ind2], dtype=float)
            bound(A, B)
            ind1[:], ind2[:] = A[0].tolist(), B[0].tolist()
            return ind1, ind2

        return mate

    @functools.wraps(op)
    def mutate(ind: list) -> tuple[list]:
        A = np.array([ind], dtype=float)
        bound(A)
        ind[:] = A[0].tolist()
        return (ind,)

    return mutate


def within(low: Iterable[float], up: Iterable[float]) -> Callable:
    """DEAP's checkBounds recipe (``toolbox.decorate("mate", within(low, up))``): the children an
    operator returns are clipped into [low, up] in place, as zrp_ga's GA repairs them."""
    low, up = np.asarray(low, dtype=float), np.asarray(up, dtype=float)

    def decorator(op: Callable) -> Callable:
        @functools.wraps(op)
        def wrapped(*args, **kwargs):
            children = op(*args, **kwargs)
            for child in children:
                child[:] = repair(np.array(child, dtype=float), low, up).tolist()
            return children

        return wrapped

    return decorator


def sometimes(op: Callable, prob: float, rng: np.random.Generator) -> Callable:
    """A decorator: each child the decorated operator returns then takes ``op`` (a one-genome
    operator, e.g. the pseudo-inverse step of :func:`for_deap`) with probability ``prob``, as a
    share of zrp_ga's children takes the pseudo-inverse step (``refine.share``)."""

    def decorator(vary: Callable) -> Callable:
        @functools.wraps(vary)
        def wrapped(*args, **kwargs):
            children = vary(*args, **kwargs)
            for child in children:
                if rng.random() < prob:
                    op(child)
            return children

        return wrapped

    return decorator
