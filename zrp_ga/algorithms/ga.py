"""The genetic algorithm of the ZRP calibration paper (Section 6), on DEAP, a generation at a time.

The operators chosen by the config are registered in a DEAP toolbox (``select``, ``mate``,
``mutate``, ``invert``, ``rotate``, ``repair``, ``refine``, ``evaluate``) and applied to a whole
generation at once: the population is a (mu, K) array and its costs a (mu,) vector, so that a
generation is a handful of numpy calls and one vectorised evaluation. A generation reads like
DEAP's ``eaMuPlusLambda`` (:meth:`GA.step`); survival strategies are the small functions below.
"""

from __future__ import annotations

import functools
import itertools
import random
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray

import zrp_ga.operators as operators  # the package, not the top module (which leads up to the API)
from zrp_ga.algorithms import Algorithm, AlgorithmSize, Array, Result, State, evaluations, genomes_bytes
from zrp_ga.core.problem import GeneBlocks, LeastSquares, Problem, Repairing, Sampling
from zrp_ga.core.schema import ConfigError, PopulationConf, RefineConf, Repair, SelectionConf, Strategy, VariationConf, section
from zrp_ga.operators.base import Streams
from zrp_ga.operators.repair import repair
from zrp_ga.problems.size import ProblemSize

UNARY = (("mutate", "mutation"), ("invert", "inversion"), ("rotate", "rotation"))
Settings = Mapping[str, Any]  # a config section's settings, before the schema's check (zrp_ga.core.schema.section)
# An operator runs evolved together can share: its function, its parameters, and a key equal for equal ones.
Shared = tuple[Callable[..., Any], dict[str, Any], tuple[Any, ...]]


def rank(costs: Array) -> NDArray[np.intp]:
    """Indices from best to worst (along the last axis: each run's, for several runs' costs),
    NaN and inf last, ties in order (stable)."""
    return np.argsort(np.where(np.isfinite(costs), costs, np.inf), axis=-1, kind="stable")


class GA(Algorithm):
    """The paper's GA. Settings come from the config (``zrp_ga.core.schema.GAConf`` and the groups it
    names); every value is checked here, and an error names the config key."""

    checkpointable = True

    def __init__(
        self, population: PopulationConf | Settings, selection: SelectionConf | Settings, crossover: VariationConf | Settings,
        mutation: VariationConf | Settings, inversion: VariationConf | Settings, rotation: VariationConf | Settings,
        refine: RefineConf | Settings, strategy: Strategy | str, elite: int, repair: Repair | str,
        target_cost: float | None = None, stagnation: int | None = None,
    ) -> None:  # fmt: skip
        super().__init__()
        self.pop_conf: PopulationConf = section(PopulationConf, population, "population")
        self.selection: SelectionConf = section(SelectionConf, selection, "selection")
        self.variation = {key: section(VariationConf, node, key) for key, node in
                          (("crossover", crossover), ("mutation", mutation), ("inversion", inversion), ("rotation", rotation))}  # fmt: skip
        self.refine_conf: RefineConf = section(RefineConf, refine, "refine")
        self.strategy, self.repair = Strategy(strategy), Repair(repair)
        self.elite, self.target_cost, self.stagnation = int(elite), target_cost, stagnation
        self._best: int | None = None  # the index of the current population's best, once known
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

    def size(self, problem: ProblemSize) -> AlgorithmSize:
        """Parents and offspring (``mu + lambda_``) held and evaluated at once; ``mu`` first,
        then ``lambda_`` a generation."""
        c = self.pop_conf
        P = c.mu + c.lambda_
        return AlgorithmSize(P, evaluations(c.generations, c.max_evals, c.mu, c.lambda_), genomes_bytes(P, problem.genes))

    def setup(self, problem: Problem, rng: np.random.Generator) -> None:
        """Bind the operators to the problem's ranges and blocks and register them. The optional
        parts a problem declares (:mod:`zrp_ga.problems.protocol`) count: its gene blocks (else
        one block), its repair, which replaces ``algorithm.repair`` (and its sampling, see
        :meth:`initialize`), e.g. the subsets of :mod:`zrp_ga.problems.selection`."""
        super().setup(problem, rng)
        tb = self.toolbox
        blocks = problem.gene_blocks if isinstance(problem, GeneBlocks) else [(0, problem.lower.size)]
        context = dict(low=problem.lower, up=problem.upper, blocks=blocks, problem=problem)
        self.ops: dict[str, Shared] = {}  # alias -> (function, parameters, key), for runs evolved together
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
        self.has = {alias for alias in ("mate", "mutate", "invert", "rotate", "refine") if hasattr(tb, alias)}
        # runs evolved together that repair alike into the same ranges are repaired in one call
        self.repair_key = None if isinstance(problem, Repairing) else (self.repair, id(problem))

    def _register(self, alias: str, op: Callable[..., Any]) -> None:
        """Register ``op`` in the toolbox; remember its function and parameters (those of a
        :func:`zrp_ga.operators.build` partial) so that runs evolved together with the same
        operator can share one call (:func:`step_together`)."""
        self.toolbox.register(alias, op)
        if isinstance(op, functools.partial) and getattr(op.func, "streams", False):
            fn = op.func
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
        self._best = None
        self.initial = (self.pop.copy(), self.costs.copy())
        self.nevals, self.n_nonfinite = self.pop_conf.mu, int(np.sum(~np.isfinite(self.costs)))
        self.offer(self.pop, self.costs)
        self.best_seen, self.since_improved = self.current()[1], 0
        self.stop_reason = self._stop_reason()

    def step(self) -> None:
        """One generation, the paper's steps 5-9 in the shape of DEAP's ``eaMuPlusLambda``
        (:func:`step_together` with this run alone)."""
        step_together([self])

    @classmethod
    def step_together(cls, runs: Sequence[Self]) -> None:
        step_together(runs)

    def draws_from_random(self) -> bool:
        """Whether an operator of this run draws from Python's ``random`` (DEAP's own, through
        the adapter): such a run is not evolved together with others, which would share that state."""
        ops = [("selection.op", self.selection.op), ("refine.op", self.refine_conf.op)]
        ops += [(f"{key}.op", v.op) for key, v in self.variation.items()]
        return any(node is not None and not getattr(operators.target(node, key)[0], "batched", False) for key, node in ops)

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
        k = int(rank(self.costs)[0]) if self._best is None else self._best
        return self.pop[k], float(self.costs[k])

    def fraction_done(self) -> float | None:
        c = self.pop_conf
        return max(self.gen / c.generations if c.generations else 0.0, self.nevals / c.max_evals if c.max_evals else 0.0)

    def result(self) -> Result:
        return Result(None if self.best_x is None else self.best_x.copy(), self.best_cost, self.nevals, self.stop_reason, *self.initial)

    # --- checkpoints (DEAP's recipe: population, best, both random states) ---------------------
    def state(self) -> State:
        """Everything needed to continue exactly: arrays and plain numbers (no objects)."""
        return dict(
            pop=self.pop, costs=self.costs, initial_x=self.initial[0], initial_costs=self.initial[1],
            best_x=self.best_x, best_cost=self.best_cost, gen=self.gen, nevals=self.nevals,
            n_nonfinite=self.n_nonfinite, best_seen=self.best_seen, since_improved=self.since_improved,
            rng=self.rng.bit_generator.state, random=random.getstate() if self.random_state is None else self.random_state,
            wall_s=self.elapsed(),
        )  # fmt: skip

    def restore(self, state: State) -> None:
        self.pop, self.costs = np.asarray(state["pop"], dtype=float), np.asarray(state["costs"], dtype=float)
        self._best = None
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


def _apply(runs: Sequence[GA], alias: str, rows: NDArray[np.intp], owner: NDArray[np.intp], off: Array,
           partner: NDArray[np.intp] | None = None) -> None:  # fmt: skip
    """Apply each run's ``alias`` operator to its offspring ``off[rows]`` (with ``off[partner]``
    for crossover's pairs; ``owner``: the run of each row, rows in the order of the runs), in
    place: one call per group of runs (:func:`_groups`) on the rows of all its runs, each run's
    random numbers from its own generator (:class:`zrp_ga.operators.base.Streams`)."""
    if not len(rows):
        return
    per_run = np.bincount(owner, minlength=len(runs))
    present = np.flatnonzero(per_run)
    groups = _groups(runs, alias, present.tolist())
    for group in groups:
        if len(groups) == 1:
            sel: slice | NDArray[np.bool_] = slice(None)
        else:
            member = np.zeros(len(runs), dtype=bool)
            member[group] = True
            sel = member[owner]
        index = [rows[sel]] if partner is None else [rows[sel], partner[sel]]
        genes = [off[ix] for ix in index]  # copies; the operators change them in place
        if len(group) == 1:
            getattr(runs[group[0]].toolbox, alias)(*genes)
        else:
            fn, params, _ = runs[group[0]].ops[alias]
            fn(*genes, rng=Streams([runs[i].rng for i in group], per_run[group].tolist()), **params)
        for ix, g in zip(index, genes):
            off[ix] = g


def step_together(runs: Sequence[GA]) -> None:
    """One generation of each GA of ``runs`` (set up on the same problem, with the same
    population size), exactly as each makes it alone: every run draws its random numbers from
    its own generator, in the order it draws them alone, while the offspring of all runs are
    one array, each operator is applied once to the rows of all the runs that use it
    (:func:`_apply`), every changed offspring is evaluated in one call of the problem's cost,
    and survival and statistics are computed for all runs at once.

    A generation, the paper's steps 5-9 in the shape of DEAP's ``eaMuPlusLambda``: ``lambda``
    parents selected; the first pairs crossed with ``crossover.prob`` (parents come in random
    order), then each child mutated, inverted and rotated with their probabilities, genes
    repaired into their ranges; a share of the children takes the pseudo-inverse step; the
    changed children evaluated (unchanged clones keep their parent's cost); survival."""
    R = len(runs)
    lams = np.array([ga._offspring_count() for ga in runs])
    starts = np.concatenate([[0], np.cumsum(lams)]).astype(np.intp)
    spans = [slice(int(a), int(b)) for a, b in itertools.pairwise(starts)]
    owner = np.repeat(np.arange(R), lams)  # the run of each offspring
    place = np.arange(len(owner)) - starts[owner]  # its place among its run's offspring
    parents = _select(runs, lams.tolist())
    if R == 1:
        off, off_costs = runs[0].pop[parents[0]], runs[0].costs[parents[0]]  # fancy indexing copies: the clones
    else:
        bases = np.concatenate([[0], np.cumsum([len(ga.pop) for ga in runs])[:-1]])
        flat = np.concatenate(parents) + np.repeat(bases, lams)
        off, off_costs = np.concatenate([ga.pop for ga in runs])[flat], np.concatenate([ga.costs for ga in runs])[flat]
    # crossover of each run's first pairs: how many, drawn by the run; then the pairs, in place
    n_cx = np.array([2 * ga.rng.binomial(lam // 2, ga.variation["crossover"].prob) if "mate" in ga.has else 0
                     for ga, lam in zip(runs, lams.tolist())])  # fmt: skip
    changed = place < n_cx[owner]
    first = np.flatnonzero(changed & (place % 2 == 0))
    _apply(runs, "mate", first, owner[first], off, first + 1)
    chosen = np.concatenate([ga.rng.random((3, lam)) < ga.probs[:, None] for ga, lam in zip(runs, lams.tolist())], axis=1)
    for j, (alias, _) in enumerate(UNARY):  # who mutates, inverts, rotates
        mask = chosen[j] & np.array([alias in ga.has for ga in runs])[owner]
        rows = np.flatnonzero(mask)
        _apply(runs, alias, rows, owner[rows], off)
        changed |= mask
    _repair(runs, off, spans, range(R))
    refined = _refine(runs, off, spans)
    new = np.flatnonzero(changed | refined)  # unchanged clones keep their parent's cost
    values = _evaluate(runs, off[new], np.searchsorted(new, starts))
    off_costs[new] = values
    _survive(runs, off, off_costs, spans, new, values, refined, starts, owner)


def _repair(runs: Sequence[GA], off: Array, spans: list[slice], which: Sequence[int]) -> None:
    """Each run's repair of its offspring (the gene ranges, or its problem's own), in place; one
    call when every run repairs alike into the same ranges."""
    which = list(which)
    if len(which) == len(runs) > 1 and runs[0].repair_key is not None and all(ga.repair_key == runs[0].repair_key for ga in runs):
        runs[0].toolbox.repair(off)
        return
    for i in which:
        runs[i].toolbox.repair(off[spans[i]])  # a view: repaired in place


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


def _refine(runs: Sequence[GA], off: Array, spans: list[slice]) -> NDArray[np.bool_]:
    """A share of each run's children takes the pseudo-inverse step (the paper's step 8);
    repaired. Returns which children took it."""
    refined = np.zeros(len(off), dtype=bool)
    rows, owner = [], []
    for i, ga in enumerate(runs):
        lam = spans[i].stop - spans[i].start
        n = round(ga.refine_conf.share * lam) if "refine" in ga.has else 0
        if n:
            rows.append(spans[i].start + ga.rng.choice(lam, size=n, replace=False))
            owner.append(np.full(n, i))
    if rows:
        t0 = time.perf_counter()
        index, who = np.concatenate(rows), np.concatenate(owner)
        _apply(runs, "refine", index, who, off)
        refined[index] = True
        refiners = np.unique(who).tolist()
        if len(runs) > 1:  # alone, the toolbox's refine is timed by the run's callback
            for i in refiners:
                runs[i].shared_s["refine_s"] += (time.perf_counter() - t0) / len(rows)
        _repair(runs, off, spans, refiners)
    return refined


def _evaluate(runs: Sequence[GA], X: Array, bounds: NDArray[np.intp]) -> Array:
    """The costs of the changed offspring ``X`` of all runs (run ``i``'s rows from
    ``bounds[i]`` to ``bounds[i + 1]``) in one call of the problem's cost (a run alone: its
    toolbox's ``evaluate``, which a callback may time)."""
    if len(runs) == 1:
        return runs[0].toolbox.evaluate(X) if len(X) else np.empty(0)
    if not len(X):
        return np.empty(0)
    t0 = time.perf_counter()
    values = runs[0].problem.costs(X)
    for a, b in itertools.pairwise(bounds):  # a run's one changed child: its cost as for one genome alone
        if b - a == 1:  # (np.einsum adds in another order for one genome than for many)
            values[a:b] = runs[0].problem.costs(X[a:b])
    spent = (time.perf_counter() - t0) / len(X)
    for ga, a, b in zip(runs, bounds[:-1], bounds[1:]):
        ga.shared_s["eval_s"] += spent * (b - a)
    return values


def _survive(runs: Sequence[GA], off: Array, off_costs: Array, spans: list[slice], new: NDArray[np.intp],
             values: Array, refined: NDArray[np.bool_], starts: NDArray[np.intp], owner: NDArray[np.intp]) -> None:  # fmt: skip
    """The rest of the generation for every run: count its evaluations, keep its survivors
    (runs with the same strategy and shapes at once), remember its best, decide whether it stops."""
    R = len(runs)
    evaluated = np.bincount(owner[new], minlength=R) + np.bincount(owner[refined], minlength=R)  # a step evaluates its residual once
    nonfinite = np.bincount(owner[new[~np.isfinite(values)]], minlength=R)
    groups: dict[tuple[Any, ...], list[int]] = {}
    for i, ga in enumerate(runs):
        lam, mu = spans[i].stop - spans[i].start, ga.pop_conf.mu
        strategy = ga.strategy if lam >= mu else Strategy.mu_plus_lambda
        groups.setdefault((strategy, ga.elite, lam, len(ga.pop), mu), []).append(i)
    for (strategy, elite, lam, _, mu), group in groups.items():
        Q = off[np.concatenate([np.arange(spans[i].start, spans[i].stop) for i in group])].reshape(len(group), lam, -1)
        Qc = np.concatenate([off_costs[spans[i]] for i in group]).reshape(len(group), lam)
        P, Pc = np.stack([runs[i].pop for i in group]), np.stack([runs[i].costs for i in group])
        genes, pool, keep = SURVIVE_TOGETHER[strategy](P, Pc, Q, Qc, mu, elite)
        pop = np.take_along_axis(genes, keep[:, :, None], axis=1)
        costs = np.take_along_axis(pool, keep, axis=1)
        best = np.argmin(np.where(np.isfinite(costs), costs, np.inf), axis=1)  # the first best: the current genome
        # the first best of all this generation saw, kept or not (an elite of mu keeps no child): the one offered
        seen = np.where(np.isfinite(pool), pool, np.inf)
        top = np.argmin(seen, axis=1)
        tops = seen[np.arange(len(group)), top].tolist()
        for g, i in enumerate(group):
            ga = runs[i]
            ga.nevals += int(evaluated[i])
            ga.n_nonfinite = int(nonfinite[i])
            ga.pop, ga.costs, ga.gen, ga._best = pop[g], costs[g], ga.gen + 1, int(best[g])
            if tops[g] < ga.best_cost:
                ga.best_x, ga.best_cost = np.array(genes[g, top[g]], dtype=float), tops[g]
            ga._update_stagnation()
            ga.stop_reason = ga._stop_reason()


Survival = tuple[Array, Array, NDArray[np.intp]]  # the pool's genes and costs, the survivors' indices in it


def _plus_together(P: Array, Pc: Array, Q: Array, Qc: Array, mu: int, elite: int) -> Survival:
    genes, pool = np.concatenate([P, Q], axis=1), np.concatenate([Pc, Qc], axis=1)
    return genes, pool, rank(pool)[:, :mu]


def _comma_together(P: Array, Pc: Array, Q: Array, Qc: Array, mu: int, elite: int) -> Survival:
    return Q, Qc, rank(Qc)[:, :mu]


def _generational_together(P: Array, Pc: Array, Q: Array, Qc: Array, mu: int, elite: int) -> Survival:
    genes, pool = np.concatenate([P, Q], axis=1), np.concatenate([Pc, Qc], axis=1)
    return genes, pool, np.concatenate([rank(Pc)[:, :elite], Pc.shape[1] + rank(Qc)[:, : mu - elite]], axis=1)


# The survival strategies, for one run or many at once: (genes, costs, indices of the survivors):
# (mu + lambda), the paper's step 9, the best mu of parents and offspring; (mu, lambda), the best mu
# of the offspring; generational, the offspring but for the ``elite`` best parents.
SURVIVE_TOGETHER = {Strategy.mu_plus_lambda: _plus_together, Strategy.mu_comma_lambda: _comma_together,
                    Strategy.generational: _generational_together}  # fmt: skip
