"""The genetic algorithm of the ZRP calibration paper (Section 6) on DEAP.

The DEAP types (a minimising fitness and a numpy-genome individual) are created once, here, in
a package module, so that parallel launchers can unpickle them. The toolbox registers the
operators chosen by the config (``mate``, ``mutate``, ``invert``, ``rotate``, ``select``,
``repair``, ``refine``, ``evaluate``); :func:`evolve` runs them on a whole generation at once.
"""

from __future__ import annotations

import dataclasses
import inspect
import random
import time
from collections.abc import Callable

import numpy as np
from deap import base, creator, tools
from numpy.typing import NDArray

from zrp_ga.operators import repair as repair_genes
from zrp_ga.problem import CalibrationProblem

Array = NDArray[np.float64]

if not hasattr(creator, "ZRPFitness"):
    creator.create("ZRPFitness", base.Fitness, weights=(-1.0,))
    creator.create("ZRPIndividual", np.ndarray, fitness=creator.ZRPFitness)

STRATEGIES = ("mu_plus_lambda", "mu_comma_lambda", "generational")


@dataclasses.dataclass(frozen=True)
class GASettings:
    """Sizes, probabilities and stop criteria of one GA run (validated on construction)."""

    mu: int = 20
    lambda_: int = 20
    generations: int | None = 11
    max_evals: int | None = None
    target_cost: float | None = None
    stagnation: int | None = None
    strategy: str = "mu_plus_lambda"
    elite: int = 1
    p_cx: float = 0.8
    p_mut: float = 0.2
    p_inv: float = 0.1
    p_rot: float = 0.1
    refine_share: float = 0.0

    def __post_init__(self) -> None:
        for name in ("p_cx", "p_mut", "p_inv", "p_rot", "refine_share"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name}: probability {value} is outside [0, 1]")
        if self.mu < 1:
            raise ValueError(f"population.mu: must be at least 1, got {self.mu}")
        if self.lambda_ < 1:
            raise ValueError(f"population.lambda_: must be at least 1, got {self.lambda_}")
        if self.strategy not in STRATEGIES:
            raise ValueError(f"algorithm.strategy: unknown {self.strategy!r}; known: {', '.join(STRATEGIES)}")
        if self.strategy != "mu_plus_lambda" and self.lambda_ < self.mu:
            raise ValueError(f"algorithm.strategy {self.strategy} needs lambda_ >= mu, got {self.lambda_} < {self.mu}")
        if not 0 <= self.elite <= self.mu:
            raise ValueError(f"algorithm.elite: must be in [0, mu={self.mu}], got {self.elite}")
        if self.generations is None and self.max_evals is None:
            raise ValueError("population: set generations or max_evals, or both")
        for name in ("generations", "max_evals", "stagnation"):
            value = getattr(self, name)
            if value is not None and value < 0:
                raise ValueError(f"{name}: must be >= 0, got {value}")


@dataclasses.dataclass
class RunResult:
    """What a run found; the GA, LM and CMA-ES all return one."""

    best: Array
    best_cost: float
    initial_genes: Array
    initial_costs: Array
    nevals: int
    stop_reason: str
    logbook: tools.Logbook | None = None
    hall_of_fame: tools.HallOfFame | None = None


def bind(op: Callable | None, rng: np.random.Generator, **available) -> Callable | None:
    """``op`` with ``rng`` and whichever of ``available`` (low, up, blocks) it takes bound."""
    if op is None:
        return None
    params = inspect.signature(op).parameters
    extra = {k: v for k, v in available.items() if k in params and k not in getattr(op, "keywords", {})}
    return lambda *args: op(*args, rng=rng, **extra)


def build_toolbox(
    problem: CalibrationProblem,
    rng: np.random.Generator,
    mate: Callable | None,
    mutate: Callable | None,
    invert: Callable | None,
    rotate: Callable | None,
    select: Callable,
    repair: str = "clip",
) -> base.Toolbox:
    """A DEAP toolbox with the chosen operators bound to the problem's ranges and blocks."""
    blocks = [(s.start, s.stop) for s in problem.layout.blocks.values()]
    avail = dict(low=problem.lower, up=problem.upper, blocks=blocks)
    toolbox = base.Toolbox()
    for alias, op in (("mate", mate), ("mutate", mutate), ("invert", invert), ("rotate", rotate)):
        bound = bind(op, rng, **avail)
        if bound is not None:
            toolbox.register(alias, bound)
    toolbox.register("select", bind(select, rng))
    toolbox.register("repair", repair_genes, low=problem.lower, up=problem.upper, method=repair)
    toolbox.register("refine", problem.refine)
    toolbox.register("evaluate", problem.costs)
    return toolbox


def population_stats(sorted_costs: Array) -> dict[str, float]:
    """Population statistics of costs sorted ascending (NaN and inf, last, left out)."""
    finite = sorted_costs[: int(np.isfinite(sorted_costs).sum())]
    n = finite.size
    if n == 0:
        return dict(best=np.nan, mean=np.nan, median=np.nan, std=np.nan, worst=np.nan)
    mean = finite.sum() / n
    dev = finite - mean
    median = finite[n // 2] if n % 2 else 0.5 * (finite[n // 2 - 1] + finite[n // 2])
    return dict(best=finite[0], mean=mean, median=median, std=np.sqrt(dev @ dev / n), worst=finite[-1])


def _rank(costs: Array) -> Array:
    """Indices from best to worst, NaN and inf last, ties in order (stable)."""
    return np.argsort(np.where(np.isfinite(costs), costs, np.inf), kind="stable")


def evolve(
    problem: CalibrationProblem,
    toolbox: base.Toolbox,
    settings: GASettings,
    rng: np.random.Generator,
    on_generation: Callable[[dict, Array, float], None] | None = None,
    checkpoint: Callable[[dict], None] | None = None,
    checkpoint_every: int = 0,
    state: dict | None = None,
) -> RunResult:
    """Run the GA; ``on_generation(row, best_genome, best_cost)`` is called after every generation.

    Pseudocode (the paper's steps 5-10, in DEAP's ``eaMuPlusLambda`` shape)::

        pop <- mu genomes uniform in the gene ranges; evaluate
        repeat
            parents   <- select(pop, lambda)                    (tournament, truncation)
            offspring <- copies of parents
            pairs cross with p_cx; each child mutates with p_mut, inverts with p_inv,
            rotates with p_rot; genes repaired into their ranges
            a share of the children takes the pseudo-inverse step (step 8); repaired
            evaluate the changed children in one vectorised call   (NaN/inf -> worst)
            pop <- best mu of pop + offspring       (mu_plus_lambda, step 9)
                   best mu of offspring             (mu_comma_lambda)
                   elite best of pop + best of offspring (generational)
        until generations, evaluations, target cost or stagnation

    Checkpoints follow DEAP's recipe (population, hall of fame, logbook, both random states):
    ``checkpoint(state)`` receives the state after every ``checkpoint_every``-th generation,
    after the last one, and on KeyboardInterrupt after the last finished one (then re-raises).
    ``evolve(..., state=state)`` with the same ``rng`` object continues exactly as if never stopped.
    """
    s = settings
    K = problem.layout.size
    t_start = time.perf_counter()
    if state is None:
        pop = rng.uniform(problem.lower, problem.upper, size=(s.mu, K))
        costs = toolbox.evaluate(pop)
        initial_genes, initial_costs = pop.copy(), costs.copy()
        nevals, gen, since_improved = s.mu, 0, 0
        logbook = tools.Logbook()
        hof = tools.HallOfFame(1, similar=np.array_equal)  # the best ever: lost by (mu, lambda) otherwise
    else:
        pop, costs, nevals, gen = state["pop"], state["costs"], state["nevals"], state["gen"]
        initial_genes, initial_costs = state["initial_genes"], state["initial_costs"]
        logbook, hof, since_improved = state["logbook"], state["hall_of_fame"], state["since_improved"]
        rng.bit_generator.state = state["rng"]
        random.setstate(state["random"])
        t_start -= state["wall_s"]
    unary = [getattr(toolbox, alias, None) for alias in ("mutate", "invert", "rotate")]
    probs = np.array([s.p_mut, s.p_inv, s.p_rot]) * [op is not None for op in unary]

    def record(n_nonfinite: int, t_eval: float, t_book: float, t_refine: float, ranked=False) -> dict:
        """Hall of fame and logbook (DEAP bookkeeping, timed with the rest of it), then the callback.
        ``ranked``: the population is already sorted best first (survival by truncation)."""
        t0 = time.perf_counter()
        order = np.arange(len(costs)) if ranked else _rank(costs)
        # Only genomes that can enter the hall of fame become DEAP individuals.
        bar = hof[-1].fitness.values[0] if len(hof) == hof.maxsize else np.inf
        top = []
        for k in order[: hof.maxsize]:
            if not costs[k] < bar:
                break
            ind = pop[k].copy().view(creator.ZRPIndividual)
            ind.fitness = creator.ZRPFitness((costs[k],))
            top.append(ind)
        if top:
            hof.update(top)
        row = dict(gen=gen, nevals=nevals, **population_stats(costs[order]), n_nonfinite=n_nonfinite)
        t_book += time.perf_counter() - t0
        row.update(eval_s=t_eval, bookkeeping_s=t_book, refine_s=t_refine, wall_s=time.perf_counter() - t_start)
        logbook.record(**row)
        if on_generation is not None:
            on_generation(row, pop[order[0]], costs[order[0]])
        return row

    def snapshot() -> dict:
        return dict(
            pop=pop, costs=costs, nevals=nevals, gen=gen, initial_genes=initial_genes, initial_costs=initial_costs,
            logbook=logbook, hall_of_fame=hof, since_improved=since_improved, best_seen=best_seen,
            rng=rng.bit_generator.state, random=random.getstate(), wall_s=time.perf_counter() - t_start,
        )  # fmt: skip

    if state is None:
        best_seen = record(int(np.sum(~np.isfinite(costs))), 0.0, 0.0, 0.0)["best"]
    else:
        best_seen = state["best_seen"]
    last = snapshot()
    stop = _stop_reason(s, gen, nevals, best_seen, since_improved)
    try:
        while not stop:
            gen += 1
            lam = s.lambda_ if s.max_evals is None else max(1, min(s.lambda_, s.max_evals - nevals))
            t0 = time.perf_counter()
            parents = toolbox.select(costs, lam)
            off, off_costs = pop[parents], costs[parents]  # fancy indexing copies: the clones
            changed = np.zeros(lam, dtype=bool)
            if hasattr(toolbox, "mate") and s.p_cx > 0:
                # Parents come in random order, so the first n_cx pairs cross: strided views, no copies.
                n_cx = 2 * rng.binomial(lam // 2, s.p_cx)
                if n_cx:
                    toolbox.mate(off[0:n_cx:2], off[1:n_cx:2])
                    changed[:n_cx] = True
            chosen = rng.random((3, lam)) < probs[:, None]  # who mutates, inverts, rotates
            for op, mask in zip(unary, chosen):
                if op is not None and mask.any():
                    block = off[mask]
                    op(block)
                    off[mask] = block
                    changed |= mask
            toolbox.repair(off)
            t_book = time.perf_counter() - t0
            t0 = time.perf_counter()
            n_refine = int(round(s.refine_share * lam))
            refined = rng.choice(lam, size=n_refine, replace=False) if n_refine else np.empty(0, dtype=int)
            with np.errstate(all="ignore"):
                for k in refined:
                    try:
                        off[k] = toolbox.refine(off[k])
                    except np.linalg.LinAlgError:  # a degenerate genome: leave it to selection
                        continue
            if refined.size:
                toolbox.repair(off)
                changed[refined] = True
            t_refine = time.perf_counter() - t0
            t0 = time.perf_counter()
            new = np.flatnonzero(changed)  # unchanged clones keep their parent's cost
            values = toolbox.evaluate(off[new]) if new.size else np.empty(0)
            off_costs[new] = values
            t_eval = time.perf_counter() - t0
            nevals += new.size + refined.size  # a pseudo-inverse step evaluates its residual once
            t0 = time.perf_counter()
            if s.strategy == "mu_plus_lambda" or lam < s.mu:
                genes, pool = np.vstack([pop, off]), np.concatenate([costs, off_costs])
                order = _rank(pool)[: s.mu]
            elif s.strategy == "mu_comma_lambda":
                genes, pool = off, off_costs
                order = _rank(pool)[: s.mu]
            else:  # generational with elitism
                genes, pool = np.vstack([pop, off]), np.concatenate([costs, off_costs])
                order = np.concatenate([_rank(costs)[: s.elite], len(costs) + _rank(off_costs)[: s.mu - s.elite]])
            pop, costs = genes[order], pool[order]
            t_book += time.perf_counter() - t0
            n_bad = values.size - int(np.isfinite(values).sum())
            row = record(n_bad, t_eval, t_book, t_refine, ranked=s.strategy != "generational")
            if row["best"] < best_seen * (1.0 - 1e-12):
                best_seen, since_improved = row["best"], 0
            else:
                since_improved += 1
            stop = _stop_reason(s, gen, nevals, best_seen, since_improved)
            last = snapshot()
            if checkpoint is not None and (stop or (checkpoint_every and gen % checkpoint_every == 0)):
                checkpoint(last)
    except KeyboardInterrupt:
        if checkpoint is not None:
            checkpoint(last)
        raise
    best = hof[0]  # the best ever seen, whatever the strategy kept
    return RunResult(np.asarray(best).copy(), best.fitness.values[0], initial_genes, initial_costs, nevals, stop, logbook, hof)


def _stop_reason(s: GASettings, gen: int, nevals: int, best: float, since_improved: int) -> str:
    """Why the run stops after generation ``gen``, or "" to go on."""
    if s.generations is not None and gen >= s.generations:
        return "generations"
    if s.max_evals is not None and nevals >= s.max_evals:
        return "max_evals"
    if s.target_cost is not None and best <= s.target_cost:
        return "target_cost"
    if s.stagnation and since_improved >= s.stagnation:
        return "stagnation"
    return ""
