"""Any DEAP operator (or any function with DEAP's calling convention) inside the batched GA.

A config can name a function by its dotted path, e.g. ``crossover.op._target_=deap.tools.cxBlend``.
It is then applied one individual (or pair) at a time: each genome row becomes a Python list,
so that DEAP's slice swaps work (on numpy rows they silently do not: slices are views), the
operator changes it in place, and it is written back. DEAP's operators draw from the ``random``
module, which the app seeds. Selection operators get light individuals whose fitness is the
cost (minimised; NaN and inf count as the worst) and return the chosen ones' indices.

This is for comparison with the batched operators of this package, not for speed: a Python
call per individual costs more than evaluating it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from deap import base

from zrp_ga.operators.base import Array, rows


class _Fitness(base.Fitness):
    weights = (-1.0,)


class _Individual(list[int]):
    """A stand-in individual for DEAP's selection operators: its row in the batch and fitness."""

    def __init__(self, index: int, cost: float):
        super().__init__([index])
        self.row = index  # (not ``index``: that is list's method)
        self.fitness = _Fitness((cost if np.isfinite(cost) else np.inf,))


def _lists(params: dict) -> dict:
    """Bounds as lists: DEAP indexes them per gene and zips them with the individual."""
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in params.items()}


def crossover(fn: Callable, ind1: Array, ind2: Array, **params) -> tuple[Array, Array]:
    A, B = rows(ind1), rows(ind2)
    for r in range(A.shape[0]):
        a, b = A[r].tolist(), B[r].tolist()
        fn(a, b, **params)
        A[r], B[r] = a, b
    return ind1, ind2


def mutation(fn: Callable, ind: Array, **params) -> tuple[Array]:
    A = rows(ind)
    for r in range(A.shape[0]):
        a = A[r].tolist()
        fn(a, **params)
        A[r] = a
    return (ind,)


def selection(fn: Callable, costs: Array, k: int, **params) -> np.ndarray:
    chosen = fn([_Individual(i, c) for i, c in enumerate(np.asarray(costs, dtype=float))], k, **params)
    return np.array([ind.row for ind in chosen], dtype=np.intp)


def wrap(fn: Callable, family: str, **params) -> Callable:
    """``fn`` with ``params`` bound, applied per individual as an operator of ``family``
    (``crossover``, ``selection``, or any one-genome family: mutation, inversion, rotation)."""
    params = _lists(params)
    adapters: dict[str, Callable[..., Any]] = {"crossover": crossover, "selection": selection}
    adapter = adapters.get(family, mutation)
    return functools.partial(adapter, fn, **params)
