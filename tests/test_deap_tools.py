"""The ZRP cost and zrp_ga's operators in an ordinary DEAP script (zrp_ga.operators.deap_tools,
experiments/deap_example.py)."""

import importlib.util
import inspect
import random
from pathlib import Path

import numpy as np
import pytest
from deap import algorithms, base

from zrp_ga import robots
from zrp_ga.operators import crossover, deap_tools, mutation, refine, selection
from zrp_ga.problems import simulated

ROOT = Path(__file__).resolve().parents[1]


def test_batched_map_equals_one_evaluation_per_individual(rng):
    problem = simulated.build(robots.get("puma560"), seed=1, n_poses=4, cost="nonlinear").problem
    evaluate = deap_tools.evaluator(problem)
    pop = [deap_tools.Individual(x) for x in rng.uniform(problem.lower, problem.upper, size=(7, problem.lower.size))]
    pop[3][0] = np.nan  # a broken genome gets the worst fitness, not an error
    batched = np.array(deap_tools.batched_map(problem)(evaluate, pop))
    one_by_one = np.array(list(map(evaluate, pop)))  # the compiled loop differs in the last bit between P = 1 and 7
    np.testing.assert_allclose(batched, one_by_one, rtol=1e-14)
    assert batched[3, 0] == np.finfo(float).max
    assert deap_tools.batched_map(problem)(len, pop) == [problem.lower.size] * 7  # other functions: the builtin map


def test_zrp_operators_registered_as_they_are_fail_on_deap_individuals(rng):
    tb = base.Toolbox()
    tb.register("mate", crossover.two_point, rng=rng)
    with pytest.raises(AttributeError, match="ndim"):  # what for_deap is for
        tb.mate(deap_tools.Individual([0.0] * 4), deap_tools.Individual([1.0] * 4))


@pytest.mark.parametrize("op, params", [(crossover.sbx, {"eta": 5.0}), (crossover.two_point, {})])
def test_for_deap_crossover_changes_the_lists_as_the_operator_changes_arrays(op, params):
    K, low, up = 8, -np.ones(8), np.ones(8)
    kw = {"low": low, "up": up, **params} if op is crossover.sbx else params
    a0, b0 = np.random.default_rng(1).uniform(low, up, size=(2, K))
    A, B = a0[None].copy(), b0[None].copy()
    op(A, B, rng=np.random.default_rng(5), **kw)  # the operator on arrays, the same draws
    a, b = deap_tools.Individual(a0.tolist()), deap_tools.Individual(b0.tolist())
    out = deap_tools.for_deap(op, np.random.default_rng(5), **kw)(a, b)
    assert out[0] is a and out[1] is b and type(a) is deap_tools.Individual  # in place, still DEAP's lists
    assert a == A[0].tolist() and b == B[0].tolist() and a != a0.tolist()


def test_for_deap_selection_picks_individuals_by_their_costs():
    pop = [deap_tools.Individual([float(i)]) for i in range(6)]
    for ind, cost in zip(pop, [5.0, 0.5, 3.0, np.nan, 2.0, 4.0]):
        ind.fitness.values = (cost,)
    chosen = deap_tools.for_deap(selection.tournament, np.random.default_rng(0), size=6)(pop, 40)
    assert all(any(ind is p for p in pop) for ind in chosen)  # the individuals themselves
    # a tournament of 6 drawn with replacement from 6: the cheapest entrant wins, NaN counts as the worst
    entrants = np.random.default_rng(0).integers(0, 6, size=(40, 6))
    costs = np.array([5.0, 0.5, 3.0, np.inf, 2.0, 4.0])
    assert [pop.index(ind) for ind in chosen] == entrants[np.arange(40), np.argmin(costs[entrants], axis=1)].tolist()


def test_zrp_operators_and_the_step_run_inside_deaps_ea_mu_plus_lambda_on_lists():
    problem = simulated.build(robots.get("puma560"), seed=2, n_poses=6, cost="nonlinear").problem
    low, up = problem.lower, problem.upper
    rng = np.random.default_rng(3)
    random.seed(3)
    tb = base.Toolbox()
    tb.register("evaluate", deap_tools.evaluator(problem))
    tb.register("map", deap_tools.batched_map(problem))
    tb.register("select", deap_tools.for_deap(selection.tournament, rng, size=3))
    tb.register("mate", deap_tools.for_deap(crossover.sbx, rng, low=low, up=up, eta=10.0))
    tb.register("mutate", deap_tools.for_deap(mutation.polynomial, rng, low=low, up=up, eta=20.0, indpb=0.3))
    step = deap_tools.for_deap(refine.pinv, rng, problem=problem)
    steps = []
    tb.decorate("mutate", deap_tools.sometimes(lambda ind: steps.append(1) or step(ind), 0.5, rng), deap_tools.within(low, up))
    pop = [deap_tools.Individual(x.tolist()) for x in rng.uniform(low, up, size=(12, low.size))]
    first = min(tb.evaluate(ind)[0] for ind in pop)
    pop, log = algorithms.eaMuPlusLambda(pop, tb, mu=12, lambda_=12, cxpb=0.5, mutpb=0.5, ngen=4, verbose=False)
    assert steps  # the pseudo-inverse step ran inside DEAP's loop
    assert all(type(ind) is deap_tools.Individual and len(ind) == low.size for ind in pop)
    X = np.array(pop)
    assert np.all((low <= X) & (up >= X))
    costs = problem.costs(X)
    np.testing.assert_allclose([ind.fitness.values[0] for ind in pop], costs, rtol=1e-12)  # fitness is the cost
    assert costs.min() < first


def test_the_deap_example_reaches_the_floor_with_zrp_operators_and_the_step():
    spec = importlib.util.spec_from_file_location("deap_example", ROOT / "experiments" / "deap_example.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    tb = example.toolbox_for(simulated.build(robots.get("puma560"), seed=0, n_poses=4).problem, np.random.default_rng(0))
    assert inspect.unwrap(tb.mate) is crossover.two_point and inspect.unwrap(tb.mutate) is mutation.gaussian  # not DEAP's
    out = example.main(["--generations", "10"])
    assert out["best"] == pytest.approx(out["floor"], rel=1e-6)  # LM's least-squares floor: no lower cost exists
    assert [row["gen"] for row in out["log"]] == list(range(11))
