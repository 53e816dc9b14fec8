import random

import numpy as np
import pytest

from zrp_ga import config, robots
from zrp_ga.algorithms import Callback
from zrp_ga.algorithms.ga import GA
from zrp_ga.core import targets
from zrp_ga.core.schema import ConfigError
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.simulation import simulate


@pytest.fixture
def problem():
    arm = robots.get("puma560")
    layout = Layout(6)
    sim = simulate(arm, layout, np.random.default_rng(1), n_poses=10, n_validation=20)
    half = np.r_[np.full(18, 0.02), np.full(18, 1e-3)]
    return CalibrationProblem(arm, sim.calibration, layout, -half, half, cost="nonlinear")


def _ga(*overrides) -> GA:
    """The GA exactly as the command line builds it."""
    return targets.create(config.load(["inversion=block", *overrides]).algorithm, "algorithm")


class Rows(Callback):
    def __init__(self):
        self.rows = []

    def on_generation(self, algorithm, row):
        self.rows.append(dict(row))


@pytest.mark.parametrize("strategy", ["mu_plus_lambda", "mu_comma_lambda", "generational"])
def test_a_short_run_lowers_the_cost(problem, strategy):
    ga = _ga("refine=none", f"algorithm.strategy={strategy}", "algorithm.elite=2", "population.mu=30",
             "population.lambda_=40", "population.generations=15")  # fmt: skip
    rows = Rows()
    result = ga.run(problem, np.random.default_rng(0), [rows])
    assert [r["gen"] for r in rows.rows] == list(range(16))
    assert result.cost < 0.8 * rows.rows[0]["best"]
    assert result.cost == pytest.approx(problem.costs(result.x)[0], rel=1e-15)
    assert np.all((result.x >= problem.lower) & (result.x <= problem.upper))
    assert result.cost == min(r["best"] for r in rows.rows)  # the best ever, whatever the strategy kept
    if strategy == "mu_plus_lambda":  # parents compete with children: the best never gets worse
        assert all(b["best"] <= a["best"] for a, b in zip(rows.rows, rows.rows[1:]))
    assert rows.rows[-1]["nevals"] == result.nevals <= 30 + 15 * 40


def test_pinv_refinement_reaches_the_least_squares_floor(problem):
    from scipy.optimize import least_squares

    floor = least_squares(problem.residual, np.zeros(36), jac=lambda x: -problem.jacobian(x), method="lm").x
    result = _ga("refine.share=0.2", "population.generations=10").run(problem, np.random.default_rng(0))
    assert result.cost <= 1.001 * problem.costs(floor)[0]


def test_stops_on_evaluations_target_and_stagnation(problem):
    rng = np.random.default_rng(0)
    r = _ga("population.mu=10", "population.lambda_=10", "population.generations=null", "population.max_evals=95").run(problem, rng)
    assert r.stop_reason == "max_evals" and r.nevals == 95  # the last generation is cut to the budget
    r = _ga("population.mu=10", "population.lambda_=10", "population.generations=500", "algorithm.target_cost=1.0").run(problem, rng)
    assert r.stop_reason == "target_cost" and r.cost <= 1.0
    rows = Rows()
    r = _ga("population.mu=10", "population.lambda_=10", "population.generations=500", "algorithm.stagnation=3",
            "crossover=none", "mutation=none", "inversion=none", "rotation=none", "refine=none").run(problem, rng, [rows])  # fmt: skip
    assert r.stop_reason == "stagnation" and rows.rows[-1]["gen"] == 3


def test_nan_costs_get_the_worst_fitness_and_are_counted(problem):
    honest = problem.costs
    problem.costs = lambda G: np.where(np.atleast_2d(G)[:, 0] > 0.01, np.nan, honest(G))
    rows = Rows()
    result = _ga("population.generations=5", "refine=none").run(problem, np.random.default_rng(0), [rows])
    assert sum(r["n_nonfinite"] for r in rows.rows) > 0
    assert np.isfinite(result.cost) and result.x[0] <= 0.01
    assert all(np.isfinite(r["best"]) for r in rows.rows)


def test_state_and_restore_continue_exactly(problem):
    over = ["population.generations=12", "refine=none"]
    whole = Rows()
    _ga(*over).run(problem, np.random.default_rng(5), [whole])

    class Stop(Callback):
        def on_generation(self, algorithm, row):
            if algorithm.gen == 7:
                self.state = algorithm.state()
                raise KeyboardInterrupt

    stop = Stop()
    random.seed(0)
    with pytest.raises(KeyboardInterrupt):
        _ga(*over).run(problem, np.random.default_rng(5), [stop])
    random.seed(99)  # restore() brings back `random` too
    rest = Rows()
    _ga(*over).run(problem, np.random.default_rng(123), [rest], state=stop.state)
    assert [r["best"] for r in rest.rows] == [r["best"] for r in whole.rows[8:]]


@pytest.mark.parametrize(
    "overrides, message",
    [(["crossover.prob=1.5"], r"crossover.prob: must be a probability in \[0, 1\], got 1.5"),
     (["population.mu=0"], "population.mu: must be at least 1, got 0"),
     (["population.generations=null"], "population: set generations or max_evals"),
     (["population.generations=0"], "population.generations: must be at least 1"),
     (["population.max_evals=10", "population.generations=null"], "population.max_evals: must be more than the initial population"),
     (["algorithm.strategy=mu_comma_lambda", "population.lambda_=5"], "needs population.lambda_ >= mu"),
     (["algorithm.elite=50"], "algorithm.elite: must be in"),
     (["mutation.op.sigma=-0.1"], "mutation.op.sigma: must be a number > 0, got -0.1"),
     (["selection.op.size=0"], "selection.op.size: must be a whole number >= 1, got 0"),
     (["+crossover.op.etaa=3"], r"crossover.op: unknown parameter 'etaa' for zrp_ga.operators.crossover.two_point"),
     (["crossover.op._target_=zrp_ga.operators.crossover.nothing"], r"crossover.op._target_: cannot import")],
)
def test_bad_settings_are_refused_naming_the_key(overrides, message):
    with pytest.raises((ConfigError, ValueError), match=message):
        _ga(*overrides)


def test_any_deap_operator_by_its_dotted_name(problem):
    """DEAP's own operators, applied one individual at a time, run inside the batched GA."""
    ga = _ga("refine=none", "crossover.op._target_=deap.tools.cxBlend", "+crossover.op.alpha=0.5",
             "mutation.op._target_=deap.tools.mutPolynomialBounded", "~mutation.op.sigma", "+mutation.op.eta=20",
             "inversion=none", "rotation=none", "selection.op._target_=deap.tools.selTournament", "~selection.op.size",
             "+selection.op.tournsize=3", "population.generations=8")  # fmt: skip
    random.seed(0)
    rows = Rows()
    result = ga.run(problem, np.random.default_rng(0), [rows])
    assert result.cost < 0.8 * rows.rows[0]["best"]
    assert np.all((result.x >= problem.lower) & (result.x <= problem.upper))
