"""The genetic algorithm of the ZRP calibration paper (Section 6), on DEAP, a generation at a time.

The operators chosen by the config are registered in a DEAP toolbox (``select``, ``mate``,
``mutate``, ``invert``, ``rotate``, ``repair``, ``refine``, ``evaluate``) and applied to a whole
generation at once: the population is a (mu, K) array and its costs a (mu,) vector, so that a
generation is a handful of numpy calls and one vectorised evaluation. A generation reads like
DEAP's ``eaMuPlusLambda`` (:meth:`GA.step`); survival strategies are the small functions below.
"""

from __future__ import annotations

import random

import numpy as np
from numpy.typing import NDArray

from zrp_ga import operators
from zrp_ga.algorithms import Algorithm, Array, Result
from zrp_ga.config import ConfigError, PopulationConf, RefineConf, Repair, SelectionConf, Strategy, VariationConf, section
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
        tb.register("select", operators.build(self.selection.op, "selection.op", "selection", rng))
        families = [("mate", "crossover")] + list(UNARY)
        for alias, key in families:
            v = self.variation[key]
            op = operators.build(v.op, f"{key}.op", key, rng, **context) if v.prob > 0 else None
            if op is not None:
                tb.register(alias, op)
        if self.refine_conf.share > 0 and self.refine_conf.op is not None:
            tb.register("refine", operators.build(self.refine_conf.op, "refine.op", "refine", rng, **context))
        if isinstance(problem, Repairing):
            tb.register("repair", problem.repair, rng=rng)
        else:
            tb.register("repair", repair, low=problem.lower, up=problem.upper, method=self.repair)
        self.probs = np.array([self.variation[key].prob if hasattr(tb, alias) else 0.0 for alias, key in UNARY])

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
        """One generation, the paper's steps 5-9 in the shape of DEAP's ``eaMuPlusLambda``."""
        tb, lam = self.toolbox, self._offspring_count()
        parents = tb.select(self.costs, lam)
        offspring, off_costs = self.pop[parents], self.costs[parents]  # fancy indexing copies: the clones
        changed = self._vary(offspring)
        refined = self._refine(offspring)
        new = np.flatnonzero(changed | refined)  # unchanged clones keep their parent's cost
        values = tb.evaluate(offspring[new]) if new.size else np.empty(0)
        off_costs[new] = values
        self.nevals += new.size + int(refined.sum())  # a pseudo-inverse step evaluates its residual once
        self.n_nonfinite = values.size - int(np.isfinite(values).sum())
        survive = SURVIVAL[self.strategy if lam >= self.pop_conf.mu else Strategy.mu_plus_lambda]
        self.pop, self.costs = survive(self.pop, self.costs, offspring, off_costs, self.pop_conf.mu, self.elite)
        self.gen += 1
        self.offer(self.pop, self.costs)
        self._update_stagnation()
        self.stop_reason = self._stop_reason()

    def _vary(self, off: Array) -> NDArray[np.bool_]:
        """Crossover of the first pairs with ``crossover.prob`` (parents come in random order),
        then mutation, inversion and rotation of each child with their probabilities; genes
        repaired into their ranges. In place; returns which children changed."""
        tb, rng, lam = self.toolbox, self.rng, len(off)
        changed = np.zeros(lam, dtype=bool)
        if hasattr(tb, "mate"):
            n_cx = 2 * rng.binomial(lam // 2, self.variation["crossover"].prob)
            if n_cx:
                tb.mate(off[0:n_cx:2], off[1:n_cx:2])  # strided views: the pairs change in place
                changed[:n_cx] = True
        chosen = rng.random((3, lam)) < self.probs[:, None]  # who mutates, inverts, rotates
        for (alias, _), mask in zip(UNARY, chosen):
            if hasattr(tb, alias) and mask.any():
                block = off[mask]
                getattr(tb, alias)(block)
                off[mask] = block
                changed |= mask
        tb.repair(off)
        return changed

    def _refine(self, off: Array) -> NDArray[np.bool_]:
        """A share of the children takes the pseudo-inverse step (the paper's step 8); repaired."""
        refined = np.zeros(len(off), dtype=bool)
        n = round(self.refine_conf.share * len(off)) if hasattr(self.toolbox, "refine") else 0
        if n:
            chosen = self.rng.choice(len(off), size=n, replace=False)
            block = off[chosen]
            self.toolbox.refine(block)
            off[chosen] = block
            self.toolbox.repair(off)
            refined[chosen] = True
        return refined

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
            rng=self.rng.bit_generator.state, random=random.getstate(), wall_s=self.elapsed(),
        )  # fmt: skip

    def restore(self, state: dict) -> None:
        self.pop, self.costs = np.asarray(state["pop"], dtype=float), np.asarray(state["costs"], dtype=float)
        self.initial = (np.asarray(state["initial_x"]), np.asarray(state["initial_costs"]))
        self.best_x, self.best_cost = np.asarray(state["best_x"], dtype=float), float(state["best_cost"])
        for key in ("gen", "nevals", "n_nonfinite", "since_improved"):
            setattr(self, key, int(state[key]))
        self.best_seen = float(state["best_seen"])
        self.rng.bit_generator.state = state["rng"]
        random.setstate(state["random"])
        self._t0 -= float(state["wall_s"])
        self.stop_reason = self._stop_reason()
