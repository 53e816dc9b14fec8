import numpy as np
import pytest
from deap import creator

from zrp_ga import ga, robots
from zrp_ga.operators import crossover, inversion, mutation, rotation, selection
from zrp_ga.problem import CalibrationProblem, Layout, simulate


@pytest.fixture
def problem():
    arm = robots.get("puma560")
    layout = Layout(6)
    sim = simulate(arm, layout, np.random.default_rng(1), n_poses=10, n_validation=20)
    half = np.r_[np.full(18, 0.02), np.full(18, 1e-3)]
    return CalibrationProblem(arm, sim.calibration, layout, -half, half, sim.validation, cost="nonlinear", true_de=sim.true_de)


def _toolbox(problem, rng):
    return ga.build_toolbox(problem, rng, crossover.two_point, mutation.gaussian, inversion.block, rotation.segment,
                            selection.tournament)


@pytest.mark.parametrize("strategy", ga.STRATEGIES)
def test_a_short_run_lowers_the_cost(problem, strategy):
    rng = np.random.default_rng(0)
    settings = ga.GASettings(mu=30, lambda_=40, generations=15, strategy=strategy, elite=2)
    rows = []
    result = ga.evolve(problem, _toolbox(problem, rng), settings, rng, lambda row, b, c: rows.append(row))
    assert len(rows) == 16 and rows[0]["gen"] == 0
    assert result.best_cost < 0.8 * rows[0]["best"]
    assert result.best_cost == pytest.approx(problem.costs(result.best)[0])
    assert np.all((result.best >= problem.lower) & (result.best <= problem.upper))
    if strategy == "mu_plus_lambda":  # parents compete with children: the best never gets worse
        assert all(b["best"] <= a["best"] for a, b in zip(rows, rows[1:]))
    assert isinstance(result.hall_of_fame[0], creator.ZRPIndividual)
    assert result.hall_of_fame[0].fitness.values[0] == pytest.approx(min(r["best"] for r in rows))


def test_pinv_refinement_reaches_the_least_squares_floor(problem):
    from scipy.optimize import least_squares

    floor = least_squares(problem.residual, np.zeros(36), jac=lambda x: -problem.jacobian(x), method="lm").x
    rng = np.random.default_rng(0)
    settings = ga.GASettings(mu=20, lambda_=20, generations=10, refine_share=0.2)
    result = ga.evolve(problem, _toolbox(problem, rng), settings, rng)
    assert result.best_cost <= 1.001 * problem.costs(floor)[0]


def test_stops_on_evaluations_target_and_stagnation(problem):
    rng = np.random.default_rng(0)
    tb = _toolbox(problem, rng)
    r = ga.evolve(problem, tb, ga.GASettings(mu=10, lambda_=10, generations=None, max_evals=95), rng)
    assert r.stop_reason == "max_evals" and r.nevals <= 95
    r = ga.evolve(problem, tb, ga.GASettings(mu=10, lambda_=10, generations=500, target_cost=1.0), rng)
    assert r.stop_reason == "target_cost" and r.best_cost <= 1.0
    r = ga.evolve(problem, tb, ga.GASettings(mu=10, lambda_=10, generations=500, stagnation=3, p_cx=0, p_mut=0,
                                             p_inv=0, p_rot=0), rng)
    assert r.stop_reason == "stagnation" and r.logbook[-1]["gen"] == 3


def test_nan_costs_get_the_worst_fitness_and_are_counted(problem):
    rng = np.random.default_rng(0)
    tb = _toolbox(problem, rng)
    honest = tb.evaluate
    tb.register("evaluate", lambda G: np.where(G[:, 0] > 0.01, np.nan, honest(G)))
    rows = []
    result = ga.evolve(problem, tb, ga.GASettings(mu=20, lambda_=20, generations=5), rng, lambda r, b, c: rows.append(r))
    assert sum(r["n_nonfinite"] for r in rows) > 0
    assert np.isfinite(result.best_cost) and result.best[0] <= 0.01
    assert all(np.isfinite(r["best"]) for r in rows)


@pytest.mark.parametrize(
    "kwargs, message",
    [(dict(p_cx=1.5), r"p_cx: probability 1.5 is outside \[0, 1\]"), (dict(mu=0), "population.mu: must be at least 1"),
     (dict(strategy="steady"), "unknown 'steady'"), (dict(generations=None), "set generations or max_evals")],
)
def test_bad_settings_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ga.GASettings(**kwargs)
