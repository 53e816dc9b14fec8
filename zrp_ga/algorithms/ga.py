"""The genetic algorithm of the ZRP calibration paper (Section 6), on DEAP, a generation at a time.

The operators chosen by the config are registered in a DEAP toolbox (``select``, ``mate``,
``mutate``, ``invert``, ``rotate``, ``repair``, ``refine``, ``evaluate``) and applied to a whole
generation at once: the population is a (mu, K) array and its costs a (mu,) vector, so that a
generation is a handful of numpy calls and one vectorised evaluation. A generation reads like
DEAP's ``eaMuPlusLambda`` (:meth:`GA.step`); survival strategies are the small functions below.
"""

from __future__ import annotations

import functools
import random
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga import operators
from zrp_ga.algorithms import Algorithm, Array, Result
from zrp_ga.config import ConfigError, PopulationConf, RefineConf, Repair, SelectionConf, Strategy, VariationConf, section
from zrp_ga.operators.base import Streams
from zrp_ga.operators.repair import repair
from zrp_ga.problems.protocol import GeneBlocks, LeastSquares, Problem, Repairing, Sampling

UNARY = (("mutate", "mutation"), ("invert", "inversion"), ("rotate", "rotation"))


def rank(costs: Array) -> NDArray[np.intp]:
    """Indices from best to worst, NaN and inf last, ties in order (stable)."""
    return np.argsort(np.where(np.isfinite(costs), costs, np.inf), kind="stable")


def plus(pop: Array, costs: Array, off: Array, off_costs: Array, mu: int, elite: int) -> tuple[Array, Array]:
    """(mu + lambda), the paper's step 9: the best mu of parents and offspring."""
    genes, pool = np.vstack([pop, off]), np.concatenate([costs, off_costs])
    keep = rank(pool)[:mu]
    return genes[keep], pool[keep]


def comma(pop: Array, costs: Array, off: Array, off_costs: Array, mu: int, elite: int) -> tuple[Array, Array]:
    """(mu, lambda): the best mu of the offspring."""
    keep = rank(off_costs)[:mu]
    return off[keep], off_costs[keep]


def generational(pop: Array, costs: Array, off: Array, off_costs: Array, mu: int, elite: int) -> tuple[Array, Array]:
    """The offspring replace the parents, but for the ``elite`` best parents."""
    genes, pool = np.vstack([pop, off]), np.concatenate([costs, off_costs])
    keep = np.concatenate([rank(costs)[:elite], len(costs) + rank(off_costs)[: mu - elite]])
    return genes[keep], pool[keep]


SURVIVAL = {Strategy.mu_plus_lambda: plus, Strategy.mu_comma_lambda: comma, Strategy.generational: generational}


class GA(Algorithm):
    """The paper's GA. Settings come from the config (``zrp_ga.config.GAConf`` and the groups it
    names); every value is checked here, and an error names the config key."""

    checkpointable = True

    def __init__(
        self, population, selection, crossover, mutation, inversion, rotation, refine, strategy, elite, repair,
        target_cost=None, stagnation=None,
    ) -> None:  # fmt: skip
        super().__init__()
        self.pop_conf: PopulationConf = section(PopulationConf, population, "population")
        self.selection: SelectionConf = section(SelectionConf, selection, "selection")
        self.variation = {key: section(VariationConf, node, key) for key, node in
                          (("crossover", crossover), ("mutation", mutation), ("inversion", inversion), ("rotation", rotation))}  # fmt: skip
        self.refine_conf: RefineConf = section(RefineConf, refine, "refine")
        self.strategy, self.repair = Strategy(strategy), Repair(repair)
        self.elite, self.target_cost, self.stagnation = int(elite), target_cost, stagnation
        mu, lam = self.pop_conf.mu, self.pop_conf.lambda_
        if self.strategy is not Strategy.mu_plus_lambda and lam < mu:
            raise ConfigError(f"algorithm.strategy: {self.strategy.value} needs population.lambda_ >= mu, got {lam} < {mu}")
        if not 0 <= self.elite <= mu:
            raise ConfigError(f"algorithm.elite: must be in [0, population.mu = {mu}], got {self.elite}")
        if stagnation is not None and stagnation < 1:
            raise ConfigError(f"algorithm.stagnation: must be at least 1 (or null), got {stagnation}")
        for key, node in [("selection.op", self.selection.op), ("refine.op", self.refine_conf.op)] + [
            (f"{k}.op", v.op) for k, v in self.variation.items()
        ]:
            if node is not None:
                operators.target(node, key)  # the function exists and takes these parameters

    def setup(self, problem: Problem, rng: np.random.Generator) -> None:
        """Bind the operators to the problem's ranges and blocks and register them. The optional
        parts a problem declares (:mod:`zrp_ga.problems.protocol`) count: its gene blocks (else
        one block), its repair, which replaces ``algorithm.repair`` (and its sampling, see
        :meth:`initialize`), e.g. the subsets of :mod:`zrp_ga.problems.selection`."""
        super().setup(problem, rng)
        tb = self.toolbox
        blocks = problem.gene_blocks if isinstance(problem, GeneBlocks) else [(0, problem.lower.size)]
        context = dict(low=problem.lower, up=problem.upper, blocks=blocks, problem=problem)
        self.ops: dict[str, tuple] = {}  # alias -> (function, parameters, key), for runs evolved together
        self._register("select", operators.build(self.selection.op, "selection.op", "selection", rng))
        families = [("mate", "crossover")] + list(UNARY)
        for alias, key in families:
            v = self.variation[key]
            op = operators.build(v.op, f"{key}.op", key, rng, **context) if v.prob > 0 else None
            if op is not None:
                self._register(alias, op)
        if self.refine_conf.share > 0 and self.refine_conf.op is not None:
            self._register("refine", operators.build(self.refine_conf.op, "refine.op", "refine", rng, **context))
        if isinstance(problem, Repairing):
            tb.register("repair", problem.repair, rng=rng)
        else:
            tb.register("repair", repair, low=problem.lower, up=problem.upper, method=self.repair)
        self.probs = np.array([self.variation[key].prob if hasattr(tb, alias) else 0.0 for alias, key in UNARY])

    def _register(self, alias: str, op: Callable) -> None:
        """Register ``op`` in the toolbox; remember its function and parameters (those of a
        :func:`zrp_ga.operators.build` partial) so that runs evolved together with the same
        operator can share one call (:func:`step_together`)."""
        self.toolbox.register(alias, op)
        fn = getattr(op, "func", None)
        if isinstance(op, functools.partial) and getattr(fn, "streams", False):
            params = {k: v for k, v in op.keywords.items() if k != "rng"}
            self.ops[alias] = (fn, params, (alias, fn, tuple((k, _same(v)) for k, v in sorted(params.items()))))

    def initialize(self) -> None:
        """mu genomes uniform in the gene ranges (or the problem's ``sample(rng, mu)``), evaluated: generation 0."""
        p, mu = self.problem, self.pop_conf.mu
        if hasattr(self.toolbox, "refine") and not isinstance(p, LeastSquares):
            raise ConfigError("refine: the pseudo-inverse step needs a calibration problem (its Jacobian); set refine=none "
                              "(experiment=pose_selection does)")
        self.pop = p.sample(self.rng, mu) if isinstance(p, Sampling) else self.rng.uniform(p.lower, p.upper, size=(mu, p.lower.size))
        self.costs = self.toolbox.evaluate(self.pop)
        self.initial = (self.pop.copy(), self.costs.copy())
        self.nevals, self.n_nonfinite = self.pop_conf.mu, int(np.sum(~np.isfinite(self.costs)))
        self.offer(self.pop, self.costs)
        self.best_seen, self.since_improved = self.current()[1], 0
        self.stop_reason = self._stop_reason()

    def step(self) -> None:
        """One generation, the paper's steps 5-9 in the shape of DEAP's ``eaMuPlusLambda``
        (:func:`step_together` with this run alone)."""
        step_together([self])

    @staticmethod
    def step_together(runs: Sequence[GA]) -> None:
        step_together(runs)

    def draws_from_random(self) -> bool:
        """Whether an operator of this run draws from Python's ``random`` (DEAP's own, through
        the adapter): such a run is not evolved together with others, which would share that state."""
        from hydra.utils import get_method

        ops = [self.selection.op, self.refine_conf.op] + [v.op for v in self.variation.values()]
        return any(node is not None and not getattr(get_method(node["_target_"]), "batched", False) for node in ops)

    def _tell(self, offspring: Array, off_costs: Array, new: NDArray, values: Array, refined: NDArray[np.bool_]) -> None:
        """The rest of a generation once the changed offspring ``new`` have their costs
        ``values``: count, survive, remember the best, decide whether to stop."""
        off_costs[new] = values
        self.nevals += new.size + int(refined.sum())  # a pseudo-inverse step evaluates its residual once
        self.n_nonfinite = values.size - int(np.isfinite(values).sum())
        survive = SURVIVAL[self.strategy if len(offspring) >= self.pop_conf.mu else Strategy.mu_plus_lambda]
        self.pop, self.costs = survive(self.pop, self.costs, offspring, off_costs, self.pop_conf.mu, self.elite)
        self.gen += 1
        self.offer(self.pop, self.costs)
        self._update_stagnation()
        self.stop_reason = self._stop_reason()

    def _offspring_count(self) -> int:
        c = self.pop_conf
        return c.lambda_ if c.max_evals is None else max(1, min(c.lambda_, c.max_evals - self.nevals))

    def _update_stagnation(self) -> None:
        cost = self.current()[1]
        if cost < self.best_seen * (1.0 - 1e-12):
            self.best_seen, self.since_improved = cost, 0
        else:
            self.since_improved += 1

    def _stop_reason(self) -> str:
        """Why the run stops after this generation, or "" to go on."""
        c = self.pop_conf
        if c.generations is not None and self.gen >= c.generations:
            return "generations"
        if c.max_evals is not None and self.nevals >= c.max_evals:
            return "max_evals"
        if self.target_cost is not None and self.best_seen <= self.target_cost:
            return "target_cost"
        if self.stagnation and self.since_improved >= self.stagnation:
            return "stagnation"
        return ""

    def current(self) -> tuple[Array, float]:
        """The best genome of the current population (what a generation's row reports)."""
        k = int(rank(self.costs)[0])
        return self.pop[k], float(self.costs[k])

    def fraction_done(self) -> float | None:
        c = self.pop_conf
        return max(self.gen / c.generations if c.generations else 0.0, self.nevals / c.max_evals if c.max_evals else 0.0)

    def result(self) -> Result:
        return Result(None if self.best_x is None else self.best_x.copy(), self.best_cost, self.nevals, self.stop_reason, *self.initial)

    # --- checkpoints (DEAP's recipe: population, best, both random states) ---------------------
    def state(self) -> dict:
        """Everything needed to continue exactly: arrays and plain numbers (no objects)."""
        return dict(
            pop=self.pop, costs=self.costs, initial_x=self.initial[0], initial_costs=self.initial[1],
            best_x=self.best_x, best_cost=self.best_cost, gen=self.gen, nevals=self.nevals,
            n_nonfinite=self.n_nonfinite, best_seen=self.best_seen, since_improved=self.since_improved,
            rng=self.rng.bit_generator.state, random=random.getstate() if self.random_state is None else self.random_state,
            wall_s=self.elapsed(),
        )  # fmt: skip

    def restore(self, state: dict) -> None:
        self.pop, self.costs = np.asarray(state["pop"], dtype=float), np.asarray(state["costs"], dtype=float)
        self.initial = (np.asarray(state["initial_x"]), np.asarray(state["initial_costs"]))
        self.best_x, self.best_cost = np.asarray(state["best_x"], dtype=float), float(state["best_cost"])
        for key in ("gen", "nevals", "n_nonfinite", "since_improved"):
            setattr(self, key, int(state[key]))
        self.best_seen = float(state["best_seen"])
        self.rng.bit_generator.state = state["rng"]
        if self.random_state is None:
            random.setstate(state["random"])
        else:
            self.random_state = state["random"]
        self._t0 -= float(state["wall_s"])
        if self.clock is not None:
            self.clock += float(state["wall_s"])
        self.stop_reason = self._stop_reason()


# --- generations of several runs at once ---------------------------------------------------------
def _same(v: Any) -> Any:
    """A parameter's value as a key that is equal for equal values (arrays by their bytes,
    other objects by identity: the problem instance)."""
    if isinstance(v, np.ndarray):
        return (v.dtype.str, v.shape, v.tobytes())
    if isinstance(v, (list, tuple)):
        return repr(v)
    return v if isinstance(v, (int, float, str, bool, type(None))) else id(v)


def _groups(runs: Sequence[GA], alias: str, which: Sequence[int]) -> list[list[int]]:
    """The runs of ``which`` (indices into ``runs``) grouped by their ``alias`` operator: runs
    with the same function and parameters share a group when it takes random streams; any other
    run is a group of its own."""
    groups: dict[Any, list[int]] = {}
    for i in which:
        op = runs[i].ops.get(alias)
        groups.setdefault(op[2] if op else ("alone", i), []).append(i)
    return list(groups.values())


def _apply(runs: Sequence[GA], alias: str, blocks: dict[int, tuple[Array, ...]]) -> None:
    """Apply the ``alias`` operator to each run's rows ``blocks[i]`` (one array, or two for
    crossover), in place: one call per group of runs (:func:`_groups`), each run's random
    numbers from its own generator (:class:`zrp_ga.operators.base.Streams`)."""
    for group in _groups(runs, alias, list(blocks)):
        if len(group) == 1:
            getattr(runs[group[0]].toolbox, alias)(*blocks[group[0]])
            continue
        fn, params, _ = runs[group[0]].ops[alias]
        counts = [len(blocks[i][0]) for i in group]
        joined = [np.concatenate([blocks[i][j] for i in group]) for j in range(len(blocks[group[0]]))]
        fn(*joined, rng=Streams([runs[i].rng for i in group], counts), **params)
        start = 0
        for i, n in zip(group, counts):
            for j, part in enumerate(joined):
                blocks[i][j][:] = part[start : start + n]
            start += n


def step_together(runs: Sequence[GA]) -> None:
    """One generation of each GA of ``runs`` (set up on the same problem, with the same
    population size), exactly as :meth:`GA.step` makes it for each alone: every run draws its
    random numbers from its own generator in the order it draws them alone, while each operator
    is applied once to the rows of all the runs that use it (:func:`_apply`) and every run's
    changed offspring are evaluated in one call of the problem's cost.

    A generation, the paper's steps 5-9 in the shape of DEAP's ``eaMuPlusLambda``: ``lambda``
    parents selected; the first pairs crossed with ``crossover.prob`` (parents come in random
    order), then each child mutated, inverted and rotated with their probabilities, genes
    repaired into their ranges; a share of the children takes the pseudo-inverse step; the
    changed children evaluated (unchanged clones keep their parent's cost); survival."""
    R = len(runs)
    lams = [ga._offspring_count() for ga in runs]
    parents = _select(runs, lams)
    offspring = [ga.pop[p] for ga, p in zip(runs, parents)]  # fancy indexing copies: the clones
    off_costs = [ga.costs[p] for ga, p in zip(runs, parents)]
    changed = [np.zeros(lam, dtype=bool) for lam in lams]
    # crossover of the first pairs: how many pairs, drawn by each run, then the pairs changed in place
    pairs = {}
    for i, ga in enumerate(runs):
        if hasattr(ga.toolbox, "mate"):
            n_cx = 2 * ga.rng.binomial(lams[i] // 2, ga.variation["crossover"].prob)
            if n_cx:
                pairs[i] = (offspring[i][0:n_cx:2], offspring[i][1:n_cx:2])  # strided views
                changed[i][:n_cx] = True
    _apply(runs, "mate", pairs)
    chosen = [ga.rng.random((3, lam)) < ga.probs[:, None] for ga, lam in zip(runs, lams)]  # who mutates, inverts, rotates
    for j, (alias, _) in enumerate(UNARY):
        picked = {i: (offspring[i][chosen[i][j]],) for i in range(R) if hasattr(runs[i].toolbox, alias) and chosen[i][j].any()}
        _apply(runs, alias, picked)
        for i, (block,) in picked.items():
            offspring[i][chosen[i][j]] = block
            changed[i] |= chosen[i][j]
    for i, ga in enumerate(runs):
        ga.toolbox.repair(offspring[i])
    refined = _refine(runs, offspring)
    new = [np.flatnonzero(c | r) for c, r in zip(changed, refined)]
    values = _evaluate(runs, [off[n] for off, n in zip(offspring, new)])
    for i, ga in enumerate(runs):
        ga._tell(offspring[i], off_costs[i], new[i], values[i], refined[i])


def _select(runs: Sequence[GA], lams: list[int]) -> list[NDArray[np.intp]]:
    """Each run's ``lambda`` parents, indices into its population."""
    out: list[Any] = [None] * len(runs)
    for group in _groups(runs, "select", range(len(runs))):
        if len(group) == 1:
            out[group[0]] = runs[group[0]].toolbox.select(runs[group[0]].costs, lams[group[0]])
            continue
        fn, params, _ = runs[group[0]].ops["select"]
        counts = [lams[i] for i in group]
        picked = fn(np.stack([runs[i].costs for i in group]), sum(counts), rng=Streams([runs[i].rng for i in group], counts), **params)
        for i, part in zip(group, np.split(picked, np.cumsum(counts)[:-1])):
            out[i] = part
    return out


def _refine(runs: Sequence[GA], offspring: list[Array]) -> list[NDArray[np.bool_]]:
    """A share of each run's children takes the pseudo-inverse step (the paper's step 8);
    repaired. Returns which children took it."""
    refined = [np.zeros(len(off), dtype=bool) for off in offspring]
    picked, rows = {}, {}
    for i, (ga, off) in enumerate(zip(runs, offspring)):
        n = round(ga.refine_conf.share * len(off)) if hasattr(ga.toolbox, "refine") else 0
        if n:
            rows[i] = ga.rng.choice(len(off), size=n, replace=False)
            picked[i] = (off[rows[i]],)
            refined[i][rows[i]] = True
    if not picked:
        return refined
    t0 = time.perf_counter()
    _apply(runs, "refine", picked)
    share = (time.perf_counter() - t0) / len(picked) if len(picked) > 1 else 0.0
    for i, (block,) in picked.items():
        offspring[i][rows[i]] = block
        runs[i].toolbox.repair(offspring[i])
        runs[i].shared_s["refine_s"] += share
    return refined


def _evaluate(runs: Sequence[GA], changed: list[Array]) -> list[Array]:
    """The costs of each run's changed offspring, from one call of the problem's cost (a run
    alone: its toolbox's ``evaluate``, which a callback may time)."""
    if len(runs) == 1:
        return [runs[0].toolbox.evaluate(changed[0]) if len(changed[0]) else np.empty(0)]
    counts = [len(c) for c in changed]
    if not sum(counts):
        return [np.empty(0) for _ in runs]
    t0 = time.perf_counter()
    values = runs[0].problem.costs(np.concatenate(changed))
    spent = time.perf_counter() - t0
    for ga, n in zip(runs, counts):
        ga.shared_s["eval_s"] += spent * n / sum(counts)
    return np.split(values, np.cumsum(counts)[:-1])
