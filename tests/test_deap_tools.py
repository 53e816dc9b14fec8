"""The ZRP cost in an ordinary DEAP script (zrp_ga.deap_tools, experiments/deap_example.py)."""

import importlib.util
from pathlib import Path

import numpy as np

from zrp_ga import deap_tools, robots
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
    assert deap_tools.batched_map(problem)(len, pop) == [36] * 7  # other functions: the builtin map


def test_the_deap_example_runs_deaps_own_algorithm():
    spec = importlib.util.spec_from_file_location("deap_example", ROOT / "experiments" / "deap_example.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    out = example.main(["--generations", "6"])
    assert out["floor"] < out["best"] < out["log"][0]["best"]  # improved, not below the least-squares floor
    assert [row["gen"] for row in out["log"]] == list(range(7))
