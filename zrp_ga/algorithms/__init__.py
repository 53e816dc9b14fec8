"""Optimisers on a problem's vectorised costs: the GA, Levenberg-Marquardt and CMA-ES.

Each one is built from its config (``_target_``) and run as ``algorithm.run(problem, rng,
callbacks) -> Result``. Population algorithms have pymoo's shape: :meth:`Algorithm.setup`
(toolbox and operators), :meth:`Algorithm.initialize` (the first population) or
:meth:`Algorithm.restore` (a checkpoint), :meth:`Algorithm.step` (one generation) while
:meth:`Algorithm.has_next`. After every generation :meth:`Algorithm.run` builds a row (the
population statistics, :func:`population_stats`) and hands it to each callback in turn
(:mod:`zrp_ga.callbacks`: timing, validation error, the convergence CSV, progress,
checkpoints). What an algorithm shows its callbacks: ``gen``, ``nevals``, ``costs`` (the current
population's), ``n_nonfinite`` (of the last evaluated batch), :meth:`Algorithm.current` (the
genome and cost the row reports), ``best_x``/``best_cost`` (the best ever seen) and ``toolbox``
(DEAP's, with at least ``evaluate``).

A new optimiser is one module here with a subclass of :class:`Algorithm` and one config file in
``conf/algorithm`` naming it by ``_target_``.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import numpy as np
from deap import base
from numpy.typing import NDArray

from zrp_ga.problems.protocol import Problem

Array = NDArray[np.float64]

STATS = ("best", "mean", "median", "std", "worst")


def population_stats(costs: Array) -> dict[str, float]:
    """Best, mean, median, std and worst of the finite costs (NaN when none is finite). numpy
    on the array itself: DEAP's ``tools.Statistics`` first turns the population into a tuple of
    Python floats, which cost more than the generation's evaluations on small problems."""
    finite = np.sort(np.asarray(costs, dtype=float))
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return dict.fromkeys(STATS, np.nan)
    return {"best": float(finite[0]), "mean": float(finite.mean()), "median": float(np.median(finite)),
            "std": float(finite.std()), "worst": float(finite[-1])}  # fmt: skip


@dataclasses.dataclass
class Result:
    """What a run found: the best genome ``x`` and its ``cost``, the evaluations it took, why it
    stopped, the first population (the paper's Table 2) and one row per generation."""

    x: Array
    cost: float
    nevals: int
    stop_reason: str
    initial_x: Array
    initial_costs: Array
    rows: list[dict] = dataclasses.field(default_factory=list)

    @property
    def history(self):
        """The rows as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.rows)


class Callback:
    """What happens around a run; every method is optional."""

    def on_start(self, algorithm: Algorithm) -> None: ...

    def on_generation(self, algorithm: Algorithm, row: dict) -> None: ...

    def on_interrupt(self, algorithm: Algorithm) -> None: ...

    def on_end(self, algorithm: Algorithm, result: Result) -> None: ...


class Algorithm:
    """The base of every optimiser (see the module docstring)."""

    checkpointable = False  # state() / restore() round-trip (the GA)

    def __init__(self) -> None:
        self.toolbox = base.Toolbox()
        self.gen = self.nevals = self.n_nonfinite = 0
        self.costs = np.empty(0)
        self.best_x: Array | None = None
        self.best_cost = np.inf
        self.stop_reason = ""
        self._t0 = time.perf_counter()

    # --- what a subclass provides --------------------------------------------------------------
    def setup(self, problem: Problem, rng: np.random.Generator) -> None:
        """Register the problem's cost as ``toolbox.evaluate`` and bind the operators."""
        self.problem, self.rng = problem, rng
        self.toolbox.register("evaluate", problem.costs)

    def initialize(self) -> None:
        raise NotImplementedError

    def step(self) -> None:
        raise NotImplementedError

    def current(self) -> tuple[Array, float]:
        """The genome and cost a generation's row reports (default: the best ever seen)."""
        return self.best_x, self.best_cost

    def fraction_done(self) -> float | None:
        """How much of the budget is spent, for a progress line; None if unknown."""
        return None

    def result(self) -> Result:
        raise NotImplementedError

    # --- shared --------------------------------------------------------------------------------
    def has_next(self) -> bool:
        return not self.stop_reason

    def elapsed(self) -> float:
        """Wall time of the run so far, s (a resumed run's earlier part included)."""
        return time.perf_counter() - self._t0

    def offer(self, X: Array, costs: Array) -> None:
        """Keep the best finite genome of X (P, K) if it beats the best seen (first among equals)."""
        finite = np.where(np.isfinite(costs), costs, np.inf)
        k = int(np.argmin(finite))
        if finite[k] < self.best_cost:
            self.best_x, self.best_cost = np.array(X[k], dtype=float), float(costs[k])

    def row(self) -> dict:
        """This generation's row: gen, nevals, the population statistics, the reported cost."""
        _, cost = self.current()
        return dict(gen=self.gen, nevals=self.nevals, **population_stats(self.costs) | {"best": cost},
                    n_nonfinite=self.n_nonfinite)  # fmt: skip

    def emit(self, callbacks: Sequence[Callback], rows: list[dict]) -> None:
        row = self.row()
        for cb in callbacks:
            cb.on_generation(self, row)
        rows.append(row)

    def run(
        self, problem: Problem, rng: np.random.Generator, callbacks: Sequence[Callback] = (), state: dict | None = None
    ) -> Result:
        """Set up, start (or continue from ``state``), step until a stop criterion, return the
        result; the callbacks see every generation, and an interrupt (Ctrl-C) before re-raising."""
        self.setup(problem, rng)
        rows: list[dict] = []
        for cb in callbacks:
            cb.on_start(self)
        try:
            if state is None:
                self.initialize()
                self.emit(callbacks, rows)
            else:
                self.restore(state)
            while self.has_next():
                self.step()
                self.emit(callbacks, rows)
        except KeyboardInterrupt:
            for cb in callbacks:
                cb.on_interrupt(self)
            raise
        result = self.result()
        result.rows = rows
        for cb in callbacks:
            cb.on_end(self, result)
        return result

    def state(self) -> dict:
        raise NotImplementedError(f"{type(self).__name__} keeps no checkpoints")

    def restore(self, state: dict) -> None:
        raise NotImplementedError(f"{type(self).__name__} keeps no checkpoints")
