"""Optimisers on a problem's vectorised costs: the GA, Levenberg-Marquardt and CMA-ES.

Each one is built from its config (``_target_``) and run as ``algorithm.run(problem, rng,
callbacks) -> Result``. Population algorithms have pymoo's shape: :meth:`Algorithm.setup`
(toolbox and operators), :meth:`Algorithm.initialize` (the first population) or
:meth:`Algorithm.restore` (a checkpoint), :meth:`Algorithm.step` (one generation) while
:meth:`Algorithm.has_next`. After every generation :meth:`Algorithm.run` builds a row (the
population statistics, :func:`population_stats`) and hands it to each callback in turn
(:mod:`zrp_ga.run.callbacks`: timing, validation error, the convergence CSV, progress,
checkpoints). What an algorithm shows its callbacks: ``gen``, ``nevals``, ``costs`` (the current
population's), ``n_nonfinite`` (of the last evaluated batch), :meth:`Algorithm.current` (the
genome and cost the row reports), ``best_x``/``best_cost`` (the best ever seen) and ``toolbox``
(DEAP's, with at least ``evaluate``).

A new optimiser is one module (here, or anywhere Python imports it from) with a subclass of
:class:`Algorithm` and one config file in ``conf/algorithm`` naming it by ``_target_``; its
:meth:`Algorithm.size` declares what it holds and evaluates (:class:`AlgorithmSize`), for the
run's memory and time estimate (:mod:`zrp_ga.run.budget`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Self

import numpy as np
from deap import base
from numpy.typing import NDArray

from zrp_ga.core.problem import Problem
from zrp_ga.problems.size import FLOAT, Lower, ProblemSize

if TYPE_CHECKING:
    import pandas as pd

Array = NDArray[np.float64]
Row = dict[str, Any]  # a generation's row: gen, nevals, the statistics, what the callbacks add
State = dict[str, Any]  # a checkpoint's state: arrays and plain numbers (Algorithm.state)

STATS = ("best", "mean", "median", "std", "worst")
INDIVIDUAL_BYTES = 600  # a DEAP individual's objects beside its genes
HANDLING_S = 3e-4  # per evaluation: DEAP's copying, selection and variation of an individual (measured for the GA)
POPULATION: Lower = ("population", "lower population.mu and population.lambda_")


@dataclasses.dataclass(frozen=True)
class AlgorithmSize:
    """What an optimiser declares about a run on a problem of a given size
    (:meth:`Algorithm.size`): ``population``, the genomes it evaluates at once; ``evaluations``
    in all (None: not known before the run); ``held_bytes``, what it holds itself (its genomes,
    its own state); ``evaluation_s``, its own seconds per evaluation; ``lower``, the setting
    that drives the population's memory and what to do, as the refusal says it."""

    population: int
    evaluations: int | None
    held_bytes: float
    evaluation_s: float = HANDLING_S
    lower: Lower = POPULATION


def genomes_bytes(population: int, genes: int) -> float:
    """Bytes of ``population`` genomes of ``genes`` numbers held twice (the population and its
    variation), with an individual's Python objects."""
    return population * (2 * FLOAT * genes + INDIVIDUAL_BYTES)


def evaluations(generations: int | None, max_evals: int | None, first: int, per_generation: int) -> int | None:
    """The evaluations of a budget of ``generations`` after a ``first`` population, or
    ``max_evals``, whichever is fewer (None: neither is set)."""
    counts = [v for v in (max_evals, generations and first + generations * per_generation) if v]
    return min(counts) if counts else None


def stats_together(costs: Sequence[Array]) -> list[dict[str, float] | None]:
    """:func:`population_stats` of several runs' costs of one size at once (None for a run with
    a NaN or inf cost: its statistics are of its finite costs, computed alone)."""
    C = np.sort(np.stack(costs), axis=1)
    ok = np.asarray(np.isfinite(C).all(axis=1))
    if not ok.any():
        return [None] * len(costs)
    F = C[ok]
    cols = zip(F[:, 0].tolist(), F.mean(axis=1).tolist(), np.median(F, axis=1).tolist(), F.std(axis=1).tolist(), F[:, -1].tolist())
    it = iter([dict(zip(STATS, c)) for c in cols])
    return [next(it) if good else None for good in ok]


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

    x: Array | None  # None: no genome had a finite cost
    cost: float
    nevals: int
    stop_reason: str
    initial_x: Array
    initial_costs: Array
    rows: list[Row] = dataclasses.field(default_factory=list)

    @property
    def history(self) -> pd.DataFrame:
        """The rows as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.rows)


class Callback:
    """What happens around a run; every method is optional."""

    @classmethod
    def together(cls, pairs: Sequence[tuple[Self, Algorithm]]) -> None:
        """Before the ``on_generation`` calls of runs evolved together
        (:meth:`Algorithm.run_together`): the work of all these callbacks of this class, each
        with its run, that is cheaper done at once (judging every run's new best genome in one call)."""

    def on_start(self, algorithm: Algorithm) -> None: ...

    def on_generation(self, algorithm: Algorithm, row: Row) -> None: ...

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
        self.shared_s = {"eval_s": 0.0, "refine_s": 0.0}  # this run's share of work done for runs together
        self.clock: float | None = None  # evolved together: this run's share of the wall time so far, s
        self.random_state: tuple[Any, ...] | None = None  # evolved together: this run's state of `random` (Algorithm.state)
        self._stats: dict[str, float] | None = None  # this generation's statistics, when computed together

    # --- what a subclass provides --------------------------------------------------------------
    def setup(self, problem: Problem, rng: np.random.Generator) -> None:
        """Register the problem's cost as ``toolbox.evaluate`` and bind the operators."""
        self.problem, self.rng = problem, rng
        self.toolbox.register("evaluate", problem.costs)

    def initialize(self) -> None:
        raise NotImplementedError

    def step(self) -> None:
        raise NotImplementedError

    @classmethod
    def step_together(cls, runs: Sequence[Self]) -> None:
        """One generation of each of ``runs`` (set up on one problem); a subclass that can share
        the work of its runs' generations overrides it (the GA)."""
        for a in runs:
            a.step()

    def current(self) -> tuple[Array | None, float]:
        """The genome and cost a generation's row reports (default: the best ever seen; None
        before a finite cost)."""
        return self.best_x, self.best_cost

    def fraction_done(self) -> float | None:
        """How much of the budget is spent, for a progress line; None if unknown."""
        return None

    def draws_from_random(self) -> bool:
        """Whether the run draws from Python's ``random`` (one state per process): such a run is
        not evolved together with others (the GA, when an operator is DEAP's own)."""
        return False

    def size(self, problem: ProblemSize) -> AlgorithmSize | None:
        """What this optimiser, as configured, holds and evaluates on a problem of ``problem``'s
        size (:class:`AlgorithmSize`), declared before the problem is built. None: it declares
        nothing, and the estimate counts it as a population of ``population.mu +
        population.lambda_`` genomes, saying so (:mod:`zrp_ga.run.budget`)."""
        return None

    def result(self) -> Result:
        raise NotImplementedError

    # --- shared --------------------------------------------------------------------------------
    def has_next(self) -> bool:
        return not self.stop_reason

    def elapsed(self) -> float:
        """Wall time of the run so far, s (a resumed run's earlier part included; evolved with
        others, its share of their time)."""
        return time.perf_counter() - self._t0 if self.clock is None else self.clock

    def offer(self, X: Array, costs: Array) -> None:
        """Keep the best finite genome of X (P, K) if it beats the best seen (first among equals)."""
        finite = np.where(np.isfinite(costs), costs, np.inf)
        k = int(np.argmin(finite))
        if finite[k] < self.best_cost:
            self.best_x, self.best_cost = np.array(X[k], dtype=float), float(costs[k])

    def row(self) -> Row:
        """This generation's row: gen, nevals, the population statistics, the reported cost."""
        _, cost = self.current()
        stats, self._stats = self._stats or population_stats(self.costs), None
        return dict(gen=self.gen, nevals=self.nevals, **stats | {"best": cost}, n_nonfinite=self.n_nonfinite)

    def emit(self, callbacks: Sequence[Callback], rows: list[Row]) -> None:
        row = self.row()
        for cb in callbacks:
            cb.on_generation(self, row)
        rows.append(row)

    def run(
        self, problem: Problem, rng: np.random.Generator, callbacks: Sequence[Callback] = (), state: State | None = None
    ) -> Result:
        """Set up, start (or continue from ``state``), step until a stop criterion, return the
        result; the callbacks see every generation, and an interrupt (Ctrl-C) before re-raising."""
        self.setup(problem, rng)
        rows: list[Row] = []
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

    @classmethod
    def run_together(
        cls, algorithms: Sequence[Self], problem: Problem, rngs: Sequence[np.random.Generator],
        callbacks: Sequence[Sequence[Callback]], states: Sequence[State | None],
        finished: Callable[[int, Result], object] | None = None,
    ) -> list[Result | Exception]:  # fmt: skip
        """:meth:`run` for several runs of this class on one problem, evolved in lockstep: a
        generation of all the runs still going at once (:meth:`step_together`), then each run's
        row to its callbacks (after :meth:`Callback.together`). Each run has its own generator,
        callbacks and state (a checkpoint's, or None), and ends on its own stop criterion (the
        others go on); ``finished(k, result)`` is called as run ``k`` ends. Returns each run's
        result, or the exception it failed with (that run alone). At Ctrl-C every unfinished
        run's callbacks see ``on_interrupt`` (their checkpoints) before KeyboardInterrupt goes on."""
        n = len(algorithms)
        out: list[Result | Exception | None] = [None] * n
        rows: list[list[Row]] = [[] for _ in range(n)]
        live: list[int] = []
        fresh: list[int] = []
        for k, a in enumerate(algorithms):
            t0 = time.perf_counter()
            try:
                a.clock = 0.0
                a.setup(problem, rngs[k])
                state = states[k]
                if state is not None:
                    a.restore(state)
                for cb in callbacks[k]:
                    cb.on_start(a)
                if state is None:
                    a.initialize()
                    fresh.append(k)
                live.append(k)
            except Exception as exc:
                out[k] = exc
            a.clock = (a.clock or 0.0) + time.perf_counter() - t0
        try:
            cls._emit_together(algorithms, callbacks, rows, fresh, out, 0.0)
            live = [k for k in live if out[k] is None]
            while live:
                t0 = time.perf_counter()
                going = [k for k in live if algorithms[k].has_next()]
                if going:
                    try:
                        cls.step_together([algorithms[k] for k in going])
                    except Exception as exc:  # a shared step failed: every run in it
                        for k in going:
                            out[k] = exc
                        going = []
                cls._emit_together(algorithms, callbacks, rows, going, out, time.perf_counter() - t0)
                for k in live:
                    if out[k] is None and not algorithms[k].has_next():
                        try:
                            result = algorithms[k].result()
                            result.rows = rows[k]
                            for cb in callbacks[k]:
                                cb.on_end(algorithms[k], result)
                            out[k] = result
                            if finished is not None:
                                finished(k, result)
                        except Exception as exc:
                            out[k] = exc
                live = [k for k in live if out[k] is None]
        except KeyboardInterrupt:
            for k in live:
                if out[k] is None:
                    for cb in callbacks[k]:
                        cb.on_interrupt(algorithms[k])
            raise
        ended = [r for r in out if r is not None]
        assert len(ended) == n  # every run ended with its result or its error
        return ended

    @staticmethod
    def _emit_together(algorithms: Sequence[Algorithm], callbacks: Sequence[Sequence[Callback]], rows: list[list[Row]],
                       ks: list[int], out: list[Result | Exception | None], spent: float) -> None:  # fmt: skip
        """The rows of runs ``ks`` to their callbacks: statistics at once, each callback class's
        shared work (:meth:`Callback.together`), then each run's callbacks; ``spent``: the
        generation's time so far, shared among the runs. A run whose callback fails ends with
        the error (in ``out``)."""
        if not ks:
            return
        t0 = time.perf_counter()
        for k, stats in zip(ks, stats_together([algorithms[k].costs for k in ks])):
            algorithms[k]._stats = stats
        by_class: dict[type[Callback], list[tuple[Callback, Algorithm]]] = {}
        for k in ks:
            for cb in callbacks[k]:
                by_class.setdefault(type(cb), []).append((cb, algorithms[k]))
        for kind, pairs in by_class.items():
            kind.together(pairs)
        share = (spent + time.perf_counter() - t0) / len(ks)
        for k in ks:
            algorithms[k].clock = (algorithms[k].clock or 0.0) + share  # 0.0 from the start (run_together)
            try:
                algorithms[k].emit(callbacks[k], rows[k])
            except Exception as exc:
                out[k] = exc

    def state(self) -> State:
        raise NotImplementedError(f"{type(self).__name__} keeps no checkpoints")

    def restore(self, state: State) -> None:
        raise NotImplementedError(f"{type(self).__name__} keeps no checkpoints")
