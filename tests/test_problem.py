import numpy as np
import pytest

from zrp_ga import robots
from zrp_ga.model import error_model, kinematics, metrics
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.simulation import simulate
from zrp_ga.operators.refine import step


def _problem(rng, cost="nonlinear", noise=True, n_poses=20, robot="puma560", **kw):
    arm = robots.get(robot)
    layout = Layout(arm.n, **kw)
    sim = simulate(arm, layout, rng, n_poses=n_poses, n_validation=30, joint_noise=1e-3 if noise else 0.0)
    half = np.r_[np.full(3 * arm.n, 0.02), np.full(layout.size - 3 * arm.n, 1e-3)]
    return CalibrationProblem(arm, sim.calibration, layout, -half, half, cost=cost), sim


def _judge(prob, sim):
    q = np.vstack([sim.calibration.q, sim.validation.q])
    projector = metrics.identifiable_projector(prob.nominal, prob.layout, q, sim.calibration.position_only)
    return metrics.Judge(prob.layout, prob.nominal, sim.validation, sim.true_x, projector)


@pytest.mark.parametrize("robot", ["puma560", "stanford"])
@pytest.mark.parametrize("extra", [{}, {"base": True, "hand": True}])
def test_nonlinear_cost_is_zero_at_the_truth_without_noise(rng, robot, extra):
    prob, sim = _problem(rng, noise=False, robot=robot, **extra)
    judge = _judge(prob, sim)
    assert prob.costs(sim.true_x)[0] < 1e-12
    rms, vmax = judge.validation_errors(sim.true_x)
    assert rms[0] < 1e-12 and vmax[0] < 1e-12
    assert prob.costs(np.zeros(prob.layout.size))[0] > 1e-4
    assert judge.param_error(sim.true_x)[0] < 1e-15
    assert judge.param_error(np.zeros(prob.layout.size))[0] > 1e-4


def test_linear_cost_equals_nonlinear_to_first_order(rng):
    """For small errors (true errors and trial errors alike) the two residuals differ at second order."""
    arm = robots.get("puma560")
    layout = Layout(6)

    def pair(scale):
        sim = simulate(arm, layout, np.random.default_rng(5), n_poses=5, axis_error=scale, body_error=scale, joint_noise=0.0)
        kw = dict(nominal=arm, data=sim.calibration, layout=layout, lower=-1.0, upper=1.0)
        return CalibrationProblem(cost="linear", **kw), CalibrationProblem(cost="nonlinear", **kw)

    d = rng.normal(size=36)
    d[:18] -= (d[:18].reshape(6, 3) * arm.u0).sum(1).repeat(3) * arm.u0.ravel()  # tangent: keeps unit length

    def gap(scale):
        lin, non = pair(scale)
        size = np.abs(lin.residual(scale * d)).max()
        return np.abs(lin.residual(scale * d) - non.residual(scale * d)).max(), size

    (g1, s1), (g2, _) = gap(1e-4), gap(1e-5)
    assert g1 < 1e-3 * s1
    assert 50 < g1 / g2 < 200  # the difference is second order


def test_jacobian_matches_finite_differences_of_the_residual(rng):
    prob, sim = _problem(rng, n_poses=4, base=True, hand=True)
    de, h = sim.true_x * 0.7, 1e-7
    J = prob.jacobian(de)
    fd = np.stack([(prob.residual(de + h * e) - prob.residual(de - h * e)) / (2 * h) for e in np.eye(de.size)], 1)
    np.testing.assert_allclose(-J, fd, atol=1e-6 * np.abs(J).max())


def test_costs_of_a_population_by_hand(rng):
    prob, _ = _problem(rng, n_poses=6)
    P = rng.uniform(prob.lower, prob.upper, size=(5, 36))
    expected = [np.linalg.norm(prob.residual(p)) for p in P]
    np.testing.assert_allclose(prob.costs(P), expected, rtol=1e-12)
    rms = CalibrationProblem(prob.nominal, prob.data, prob.layout, prob.lower, prob.upper, cost="nonlinear", norm="rms")
    np.testing.assert_allclose(rms.costs(P), np.array(expected) / np.sqrt(6 * 6 + 6), rtol=1e-12)


def test_pinv_step_solves_the_linear_problem_and_stays_in_range(rng):
    prob, _ = _problem(rng, cost="linear", n_poses=1)
    de = rng.uniform(prob.lower, prob.upper) * 0.5
    new = step(prob, de, rcond=1e-9)
    assert prob.costs(new)[0] < 1e-6 * prob.costs(de)[0]
    assert np.all((new >= prob.lower) & (new <= prob.upper))


def test_canonical_keeps_every_pose(rng):
    prob, sim = _problem(rng, n_poses=8)
    de = sim.true_x.copy()
    axis = prob.nominal.u0[1] + de[3:6]
    axis /= np.linalg.norm(axis)
    de[18:21] += 0.3 * axis  # slide the point on axis 2 far along its (true) axis
    de[21:24] -= 0.3 * axis
    assert prob.costs(de)[0] == pytest.approx(prob.costs(sim.true_x)[0], rel=1e-9)
    c = error_model.canonical(prob.layout, prob.nominal, de)
    assert np.abs(c[18:]).max() < 2e-3
    np.testing.assert_allclose(prob.costs(c), prob.costs(de), rtol=1e-9)


def test_nan_genes_give_nan_cost_not_an_error(rng):
    prob, _ = _problem(rng, n_poses=3)
    P = np.zeros((3, 36))
    P[1, 0] = np.nan
    P[2, :3] = -prob.nominal.u0[0]  # an axis of length zero
    c = prob.costs(P)
    assert np.isfinite(c[0]) and not np.isfinite(c[1]) and not np.isfinite(c[2])


def test_measurements_refuse_bad_shapes():
    with pytest.raises(ValueError, match=r"measurements.p: expected shape \(2, 3\)"):
        Measurements(q=np.zeros((2, 6)), p=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="measurements.p: NaN or inf"):
        Measurements(q=np.zeros((1, 6)), p=[[0, np.nan, 0]])


def test_simulated_measurements_follow_the_true_robot(rng):
    arm = robots.get("ur10")
    sim = simulate(arm, Layout(6), rng, n_poses=4, joint_noise=0.0)
    R, p = kinematics.forward(sim.truth, sim.calibration.q)
    np.testing.assert_allclose(sim.calibration.p, p)
    assert np.abs(sim.true_x[18:]).max() <= 5e-4 and np.abs(sim.true_x[:18]).max() < 0.011


def test_position_weights_scale_the_position_rows(rng):
    arm = robots.get("ur10")
    sim = simulate(arm, Layout(6), rng, n_poses=7, joint_noise=0.0)
    w = rng.uniform(0.5, 2.0, size=(7, 3))
    data = Measurements(q=sim.calibration.q, p=sim.calibration.p, weights=w)
    prob = CalibrationProblem(arm, data, Layout(6), -0.02, 0.02, cost="nonlinear")
    de = rng.uniform(-0.005, 0.005, size=(4, 36))
    for g, cost in zip(de, prob.costs(de)):
        u0 = arm.u0 + g[:18].reshape(6, 3)
        unit = u0 / np.linalg.norm(u0, axis=1, keepdims=True)
        b0 = arm.b0.copy()
        b0[1:] += g[18:].reshape(6, 3)
        _, p = kinematics.forward(arm.replace(u0=unit, b0=b0), data.q)
        rows = np.concatenate([((data.p - p) * w).ravel(), -0.5 * (np.sum(u0**2, axis=1) - 1)])
        assert cost == pytest.approx(np.linalg.norm(rows), rel=1e-12)
        np.testing.assert_allclose(prob.residual(g), rows, atol=1e-15)


# --- the Problem protocol: a required part, optional parts declared (zrp_ga.core.problem) ---
class Sphere:
    """A problem with the required part only: ranges, names, a vectorised cost (minimum at 0.3)."""

    def __init__(self, K=7):
        self.lower, self.upper, self.names = -np.ones(K), np.ones(K), [f"g{k}" for k in range(K)]

    def costs(self, X):
        return np.sqrt(np.sum((np.atleast_2d(X) - 0.3) ** 2, axis=1))


def test_each_problem_kind_has_the_parts_it_declares(rng):
    from zrp_ga.core import problem as gp
    from zrp_ga.problems import protocol as pp
    from zrp_ga.problems.selection import SelectionProblem

    prob, _ = _problem(rng, n_poses=8)
    parts = (gp.Problem, gp.Sampling, gp.Repairing, gp.GeneBlocks, gp.LeastSquares, pp.Identifiable)
    has = lambda p: [isinstance(p, part) for part in parts]
    assert has(prob) == [True, False, False, True, True, True]
    assert prob.gene_blocks == [(0, 18), (18, 36)]  # the layout's blocks: axes, body vectors
    assert has(SelectionProblem(prob, k=3)) == [True, True, True, True, False, True]  # no Jacobian on subsets
    assert has(Sphere()) == [True, False, False, False, False, False]


def test_the_algorithms_run_a_problem_with_the_required_part_only():
    from zrp_ga import config
    from zrp_ga.algorithms.random_search import RandomSearch
    from zrp_ga.core import targets

    ga = targets.create(config.load(["refine=none", "inversion=block", "rotation=block", "population.mu=30",
                                         "population.lambda_=30", "population.generations=30"]).algorithm, "algorithm")  # fmt: skip
    result = ga.run(Sphere(), np.random.default_rng(0))  # one gene block, uniform start, clipped into the ranges
    assert result.cost < 0.5 * Sphere().costs(np.zeros(7))[0]  # well below the centre's cost (0.79)
    assert result.cost == pytest.approx(Sphere().costs(result.x)[0])
    search = RandomSearch(samples=50, batch=10).run(Sphere(), np.random.default_rng(0))
    assert search.nevals == 50 and np.all(np.abs(search.initial_x) <= 1.0)


def test_a_search_with_no_finite_cost_returns_no_genome():
    """Every genome's cost NaN (the model breaks everywhere): the GA and random search end with
    x None and cost inf (the run's summary then says the optimiser diverged), not an error."""
    from zrp_ga import config
    from zrp_ga.algorithms.random_search import RandomSearch
    from zrp_ga.core import targets

    class Broken(Sphere):
        def costs(self, X):
            return np.full(len(np.atleast_2d(X)), np.nan)

    ga = targets.create(config.load(["refine=none", "population.mu=6", "population.lambda_=6", "population.generations=2"]).algorithm,
                        "algorithm")  # fmt: skip
    for result in (ga.run(Broken(), np.random.default_rng(0)), RandomSearch(samples=20, batch=10).run(Broken(), np.random.default_rng(0))):
        assert result.x is None and result.cost == np.inf


def test_least_squares_and_the_step_need_a_jacobian():
    from zrp_ga import config
    from zrp_ga.algorithms.lm import LM
    from zrp_ga.core import targets
    from zrp_ga.core.schema import ConfigError

    with pytest.raises(ConfigError, match="Levenberg-Marquardt needs a residual and its Jacobian"):
        LM().run(Sphere(), np.random.default_rng(0))
    ga = targets.create(config.load([]).algorithm, "algorithm")  # refine=pinv by default
    with pytest.raises(ConfigError, match="refine: the pseudo-inverse step needs a calibration problem"):
        ga.run(Sphere(), np.random.default_rng(0))


def test_levenberg_marquardt_reaches_the_linear_least_squares_solution_and_keeps_the_best_seen(rng):
    from zrp_ga.problems.least_squares import levenberg_marquardt

    prob, _ = _problem(rng, cost="linear", n_poses=12)
    seen = []
    fit = levenberg_marquardt(prob, on_evaluation=lambda x, c, k: seen.append((k, float(c[0]))))
    solution = np.linalg.lstsq(prob.J_nominal, prob.y_nominal, rcond=None)[0]  # residual y - J x: minimised by lstsq
    assert prob.costs(fit.x)[0] == pytest.approx(prob.costs(solution)[0], rel=1e-9)
    assert [k for k, _ in seen] == list(range(fit.nevals + 1))  # the start (0), then each residual evaluation
    assert fit.cost == min(c for _, c in seen) and fit.initial_cost[0] == seen[0][1]
