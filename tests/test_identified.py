"""The identified subspace, the noise, outliers, the robust cost, the covariance, predicted
errors and coverage (zrp_ga.model.subspace, uncertainty, coverage; zrp_ga.problems.identify,
robust, assessment), each against an independent answer: a planted singular value
decomposition, scipy's linprog and least_squares, finite differences of the forward kinematics,
a closed-form straight-line covariance, Monte-Carlo sampling, brute-force distances."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import subspace_angles
from scipy.optimize import least_squares, linprog
from scipy.stats import ortho_group

from zrp_ga.core.schema import Cost, Loss, Outliers, SimulatedConf
from zrp_ga.core.schema import Subspace as Choice
from zrp_ga.io import presets
from zrp_ga.model import coverage, kinematics, simulation, so3, subspace, uncertainty
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.problems import identify
from zrp_ga.problems.least_squares import levenberg_marquardt
from zrp_ga.problems.robust import RobustProblem


def planted(rng, p, s, rows=12):
    """A Jacobian (rows, K) whose prior-scaled, unit-noise SVD is U diag(s) V^T, and V."""
    K = len(p)
    V = ortho_group.rvs(K, random_state=rng.integers(1 << 31))
    U = ortho_group.rvs(rows, random_state=rng.integers(1 << 31))[:, :K]
    return U @ np.diag(s) @ V.T / p[None, :], V


# --- the subspace -------------------------------------------------------------------------------------
def test_identified_directions_are_those_whose_standard_error_is_small(rng):
    p = np.array([1.0, 2.0, 0.5, 1.0, 3.0])
    s = np.array([100.0, 10.0, 2.5, 1.5, 0.0])  # standard errors 0.01, 0.1, 0.4 | 0.67, inf
    J, V = planted(rng, p, 2.0 * s)  # rows with noise 2: whitened, the singular values s
    sub = subspace.identify(J, np.zeros((0, 5)), p, np.full(len(J), 2.0), max_se=0.5)
    assert sub.rank == 3 and sub.exact_rank == 4
    assert np.max(subspace_angles(sub.basis, p[:, None] * V[:, :3])) < 1e-9  # span(diag(p) V_r)
    assert np.allclose(sub.dual @ sub.basis, np.eye(3), atol=1e-12)
    assert np.allclose(sub.dual @ (p[:, None] * V[:, 3:]), 0.0, atol=1e-12)  # what is dropped projects to nominal
    assert np.allclose(sub.standard_errors[:3], 1 / s[:3])
    unwhitened = subspace.identify(J, np.zeros((0, 5)), p, None)
    assert unwhitened.rank == 4  # without a noise estimate only the exact null direction goes


def test_axes_turn_and_never_stretch(rng):
    """A Jacobian that sees an axis' stretch (as the paper's linear model does) still leaves it
    out: the unit rows are constraints, not data."""
    p = np.full(6, 0.01)
    J = rng.normal(size=(20, 6))
    u = np.array([0.0, 0.6, 0.8])
    unit = np.zeros((1, 6))
    unit[0, :3] = u
    sub = subspace.identify(J, unit, p, np.full(20, 1e-3))
    assert sub.rank == 5 and np.allclose(unit @ sub.basis, 0.0, atol=1e-12)


def test_gene_ranges_are_the_boxs_projection_capped(rng):
    p = np.array([0.01, 0.02, 0.001, 0.003])
    J, _ = planted(rng, p, np.array([50.0, 20.0, 5.0, 0.0]), rows=8)
    sub = subspace.identify(J, np.zeros((0, 4)), p, np.ones(8))
    scale = 2.0
    box = [(-scale * q, scale * q) for q in p]
    biggest = np.array([-linprog(-g, bounds=box).fun for g in sub.dual])  # max of z_k = G_k x over the box
    assert np.allclose(subspace.half_widths(sub, scale, least=np.inf), biggest, rtol=1e-7)
    half = subspace.half_widths(sub, scale)  # no wider than a uniform gene of the projection's variance
    assert np.all(half <= biggest + 1e-15) and np.allclose(half, np.minimum(biggest, scale * sub.scale))
    G = sub.dual / sub.scale[:, None]  # the projection in expected errors: a uniform box's has variance scale^2 / 3
    assert np.allclose(np.sum((G * p[None] * scale) ** 2, axis=1) / 3, (scale**2) / 3)
    assert np.allclose(subspace.half_widths(sub, 1.0), sub.scale * np.minimum(biggest / scale / sub.scale, np.sqrt(3)))


def test_a_restricted_layout_maps_genomes_both_ways(rng):
    layout = Layout(6, base=True, fixed=("b0_1x",))
    K = layout.size
    p = rng.uniform(0.001, 0.01, K)
    J, _ = planted(rng, p, np.concatenate([np.linspace(40, 5, K - 6), np.zeros(6)]), rows=60)
    sub = subspace.identify(J, np.zeros((0, K)), p, np.ones(60))
    r = subspace.restricted(layout, sub)
    z = rng.normal(scale=1e-5, size=r.size)
    x = r.expand(z)
    assert x[layout.full_names.index("b0_1x")] == 0.0  # the mask holds
    assert np.allclose(r.restrict(x), z, rtol=1e-9, atol=0) and np.allclose(layout.restrict(x), sub.basis @ z, rtol=1e-9, atol=0)


# --- noise, outliers, the robust cost -----------------------------------------------------------------
def tracker_problem(seed: int, M: int = 60, noise_m: float = 5e-5, **kw):
    """A simulated PUMA 560 measured by a tracker (positions, Gaussian noise) and its problem."""
    robot = presets.get("puma560")
    layout = Layout(6)
    rng = np.random.default_rng(seed)
    sim = simulation.simulate(robot, layout, rng, n_poses=M, n_validation=100, axis_error=0.002, body_error=0.001,
                              joint_noise=0.0, position_noise=noise_m, position_only=True)  # fmt: skip
    half = np.where(np.arange(36) < 18, 0.004, 0.002)
    problem = CalibrationProblem(robot, kw.pop("data", sim.calibration), layout, -half, half, Cost.nonlinear)
    return robot, sim, problem, half / 2


def test_the_noise_estimate_recovers_a_known_noise():
    estimates = []
    for seed in range(4):
        _, _, problem, prior = tracker_problem(seed)
        x, _, _, rank = identify.first_fit(problem, prior)
        nz = identify.noise(problem, problem.residual(x)[:-6], rank)
        estimates.append(nz.sigma["position"])
    assert abs(np.mean(estimates) / 5e-5 - 1) < 0.1


def with_outliers(seed: int, rows=(5, 27, 44), size_m=5e-3):
    robot, sim, _, _ = tracker_problem(seed)
    rng = np.random.default_rng(99)
    p = sim.calibration.p.copy()
    d = rng.normal(size=(len(rows), 3))
    p[list(rows)] += size_m * d / np.linalg.norm(d, axis=1, keepdims=True)
    return sim.calibration.__class__(sim.calibration.q, p, source="cal.csv", lines=np.arange(60) + 2)


def test_planted_outliers_are_named_by_line_and_the_robust_fit_ignores_them():
    bad = with_outliers(0)
    robot, sim, problem, prior = tracker_problem(0, data=bad)
    conf = lambda **k: SimulatedConf(**k)
    p_report, setup = identify.prepare(problem, prior, 2.0, conf(loss=Loss.soft_l1))
    assert sorted(o["line"] for o in setup.outliers) == [7, 29, 46] and all(4.0 < o["size_mm"] < 6.0 for o in setup.outliers)
    assert isinstance(p_report, RobustProblem)
    val = sim.validation

    def val_rms(prob) -> float:
        from zrp_ga.model import metrics

        x = levenberg_marquardt(prob).x
        return float(np.sqrt(np.mean(metrics.position_errors(prob.layout, robot, x, val) ** 2)))

    clean, _ = identify.prepare(tracker_problem(0)[2], prior, 2.0, conf())
    plain, _ = identify.prepare(problem, prior, 2.0, conf())
    dropped, s_drop = identify.prepare(problem, prior, 2.0, conf(outliers=Outliers.drop))
    assert s_drop.dropped and dropped.data.M == 57 and s_drop.change["points_dropped"] == 3
    assert val_rms(p_report) < 1.1 * val_rms(clean) < val_rms(plain)
    assert val_rms(dropped) < 1.1 * val_rms(clean)


def test_the_robust_cost_is_scipys():
    _, _, problem, _ = tracker_problem(1, data=with_outliers(1))
    robust = RobustProblem(**identify._fields(problem), loss="soft_l1", loss_scale=2e-4)
    fit = least_squares(robust.plain_residual, np.zeros(36), jac=lambda x: -robust.plain_jacobian(x), loss="soft_l1",
                        f_scale=2e-4, method="trf", x_scale=1e-3)  # fmt: skip
    X = np.vstack([fit.x, 0.5 * fit.x])
    assert np.allclose(robust.costs(X)[0] ** 2, 2 * fit.cost, rtol=1e-9)
    f = robust.plain_residual(X[1])  # scipy's loss by hand: soft_l1 rho(z) = 2 (sqrt(1 + z) - 1)
    assert np.isclose(robust.costs(X)[1] ** 2, np.sum(2 * 2e-4**2 * (np.sqrt(1 + (f / 2e-4) ** 2) - 1)), rtol=1e-12)


def test_levenberg_marquardt_fits_scipys_robust_loss():
    """On a robust problem, alone or restricted to directions (as identify's first fit is),
    levenberg_marquardt ends at scipy's robust optimum of the plain rows, not at the plain
    least-squares one, which the outliers pull away."""
    _, _, problem, _ = tracker_problem(1, data=with_outliers(1))
    robust = RobustProblem(**identify._fields(problem), loss="soft_l1", loss_scale=2e-4)
    ref = least_squares(robust.plain_residual, np.zeros(36), jac=lambda x: -robust.plain_jacobian(x), loss="soft_l1",
                        f_scale=2e-4, method="trf", x_scale=1e-3)  # fmt: skip
    assert robust.costs(levenberg_marquardt(problem).x)[0] ** 2 > 1.2 * 2 * ref.cost
    for fitted in (robust, identify._Within(robust, np.eye(36))):
        assert levenberg_marquardt(fitted).cost ** 2 <= 2 * ref.cost * (1 + 1e-6)


def test_the_pseudo_inverse_step_minimises_the_robust_cost():
    """Reweighted steps (the GA's pseudo-inverse step on a robust problem) end where scipy's
    loss does."""
    from zrp_ga.operators.refine import step

    _, _, problem, _ = tracker_problem(2, data=with_outliers(2))
    robust = RobustProblem(**identify._fields(problem), loss="huber", loss_scale=1.5e-4)
    robust.lower, robust.upper = -np.ones(36), np.ones(36)
    x, costs = np.zeros(36), []
    for _ in range(30):
        x = step(robust, x, 1e-9)
        costs.append(robust.costs(x)[0])
    assert np.all(np.diff(costs[2:]) <= 1e-12 * costs[0])  # (the model is not linear: the first steps may overshoot)
    fit = least_squares(robust.plain_residual, x, jac=lambda v: -robust.plain_jacobian(v), loss="huber", f_scale=1.5e-4, method="trf")
    assert robust.costs(x)[0] ** 2 <= 2 * fit.cost * (1 + 1e-6)


# --- covariance and predicted errors ------------------------------------------------------------------
def test_covariance_of_a_straight_line_fit():
    t = np.array([0.0, 1.0, 2.0, 4.0, 7.0])
    sigma = 0.3
    C = uncertainty.covariance(np.column_stack([np.ones_like(t), t]), np.full(t.size, sigma))
    Sxx = np.sum((t - t.mean()) ** 2)
    assert np.isclose(C[1, 1], sigma**2 / Sxx) and np.isclose(C[0, 0], sigma**2 * np.sum(t**2) / (t.size * Sxx))
    assert np.isclose(C[0, 1], -sigma**2 * t.mean() / Sxx)


def test_pose_jacobians_are_the_forward_kinematics_derivatives(rng):
    robot = presets.get("stanford").with_tool(np.array([0.02, 0.03, 0.1]))
    layout = Layout(6, base=True, hand=True, tools=((0.05, 0.0, 0.01),))
    x = rng.normal(scale=1e-3, size=layout.size)
    q = simulation.random_joints(robot, 4, rng)
    for tool in (0, 1):
        J = uncertainty.pose_jacobians(layout, robot, x, q, tool)
        for k in rng.choice(layout.size, 12, replace=False):
            e = np.zeros(layout.size)
            e[k] = 1e-6
            (Ra, pa), (Rb, pb) = (kinematics.forward(layout.robot(robot, x + d, tool=tool), q) for d in (e, -e))
            dr = so3.log(Ra @ np.swapaxes(Rb, 1, 2)) / 2e-6
            assert np.allclose(J[:, 3:, k], (pa - pb) / 2e-6, atol=1e-6) and np.allclose(J[:, :3, k], dr, atol=1e-6)


def test_predicted_error_radius_matches_sampled_arms(rng):
    robot = presets.get("puma560")
    layout = Layout(6)
    A = rng.normal(size=(36, 36)) * 2e-4
    cov = A @ A.T
    u = uncertainty.Uncertainty(layout, robot, np.zeros(36), A, np.zeros((36, 0)), 0.0)
    q = simulation.random_joints(robot, 3, rng)
    p0 = kinematics.forward(robot, q)[1]
    draws = rng.multivariate_normal(np.zeros(36), cov, size=4000)
    moved = np.array([kinematics.forward(layout.robot(robot, d), q)[1] - p0 for d in draws])
    sampled = np.sqrt(np.mean(np.sum(moved**2, axis=2), axis=0))
    assert np.allclose(u.predict(q)["position_m"], sampled, rtol=0.06)


def test_predicted_validation_rms_agrees_with_the_measured_one():
    ratios = []
    for seed in range(5):
        robot, sim, problem, prior = tracker_problem(10 + seed, M=40)
        problem, setup = identify.prepare(problem, prior, 2.0, SimulatedConf())
        z = levenberg_marquardt(problem).x
        unc = identify.uncertainty(problem, z, setup)
        from zrp_ga.model import metrics

        measured = np.sqrt(np.mean(metrics.position_errors(problem.layout, robot, z, sim.validation) ** 2))
        ratios.append(measured / unc.predicted_rms_m(sim.validation.q))
    assert 0.85 < np.mean(ratios) < 1.15


# --- coverage -------------------------------------------------------------------------------------------
def test_coverage_ranges_and_distances_by_brute_force(rng):
    q = rng.uniform(-1, 1, (40, 3))
    q[:, 2] = 0.5  # a held joint
    cov = coverage.Coverage(q)
    D = np.linalg.norm(q[:, None] - q[None], axis=2) + np.diag(np.full(40, np.inf))
    assert np.isclose(cov.gap, D.min(axis=1).max())
    targets = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.6], [3.0, 0.0, 0.5]])
    a = cov.assess(targets)
    nearest = np.linalg.norm(targets[:, None] - q[None], axis=2).min(axis=1)
    assert np.allclose(a.distance, nearest) and np.allclose(a.ratio, nearest / cov.gap)
    assert a.outside.tolist() == [False, True, True] and a.beyond[1].tolist() == [False, False, True]
    assert np.isclose(a.excess[2, 0], 3.0 - q[:, 0].max())


# --- the whole problem -----------------------------------------------------------------------------------
def test_held_joints_leave_the_unseen_combinations_at_nominal():
    """The issue's example (LM): positions only, joints 1 and 6 held; the default keeps the
    error anywhere near the nominal arm's while fitting the measured region to the noise."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent.parent / "experiments"))
    import held_joints

    import zrp_ga

    robot = held_joints.arm()
    cal, same, anywhere = held_joints.data(robot, 3)
    for val, check in ((same, lambda v: v["calibrated"] < 1.5 * np.sqrt(3) * held_joints.NOISE_M * 1e3),
                       (anywhere, lambda v: v["calibrated"] < 1.1 * v["nominal"])):  # fmt: skip
        s = zrp_ga.calibrate(robot, cal, validation=val, algorithm="lm").summary
        assert check(s["validation_rms_mm"]), s["validation_rms_mm"]
    full = zrp_ga.calibrate(robot, cal, validation=anywhere, algorithm="lm", problem={"subspace": "full"}).summary
    assert full["returned"] == "nominal"  # worse than nominal on validation: the nominal arm, with a warning saying so
    assert any("worse than the nominal one" in w and "returned instead" in w for w in full["warnings"])
    kept = zrp_ga.calibrate(robot, cal, validation=anywhere, algorithm="lm", problem={"subspace": "full", "if_worse": "keep"}).summary
    assert kept["validation_rms_mm"]["calibrated"] > 3 * kept["validation_rms_mm"]["nominal"]  # what the issue saw
    assert s["coverage"]["validation_is_extrapolation"] and s["identified"]["rank"] < s["identified"]["combinations"]
    assert any("slide along u0_1" in d for d in s["identified"]["dropped_combinations"])


@pytest.mark.parametrize("choice", [Choice.identified, Choice.full])
def test_the_genomes_floor(choice):
    """LM within the identified genome ends within 2% of the cost with every parameter free
    (the combinations it leaves at nominal fit noise, at most a few sigma^2 each); with
    ``subspace=full`` the genome is every parameter and the floor is the same."""
    robot, sim, problem, prior = tracker_problem(5)
    restricted, setup = identify.prepare(problem, prior, 2.0, SimulatedConf(subspace=choice))
    full = levenberg_marquardt(problem).cost
    own = levenberg_marquardt(restricted).cost
    if choice is Choice.full:
        assert restricted is problem and np.isclose(own, full, rtol=1e-9)
    else:
        assert restricted.layout.size == setup.subspace.rank < 30 and full * (1 - 1e-9) <= own < 1.02 * full


def test_the_instruments_deviations_are_the_noise_when_the_residual_agrees_with_them():
    _, sim, _, prior = tracker_problem(3)
    c = sim.calibration
    for stated, source in ((5e-5, "instrument"), (5e-6, "residual")):
        data = c.__class__(c.q, c.p, std=np.full((c.M, 3), stated))
        _, _, problem, _ = tracker_problem(3, data=data)
        x, _, _, rank = identify.first_fit(problem, prior)
        nz = identify.noise(problem, problem.residual(x)[:-6], rank)
        assert nz.source.startswith(source) and abs(nz.chi2_dof / (5e-5 / stated) ** 2 - 1) < 0.15
        expected = stated if source == "instrument" else nz.sigma["position"]
        assert np.allclose(nz.row_sigma, expected)


def test_huber_is_scipys_by_hand():
    """scipy's huber: rho(z) = z for z <= 1, 2 sqrt(z) - 1 beyond (continuous, with its slope,
    at z = 1); rho'(z) = 1, then 1 / sqrt(z)."""
    from zrp_ga.problems.robust import rho

    z = np.array([0.0, 0.25, 1.0, 1.0 + 1e-12, 4.0, 100.0])
    value, slope = rho(z, "huber")
    assert np.allclose(value, [0.0, 0.25, 1.0, 1.0, 3.0, 19.0], rtol=0, atol=1e-9)
    assert np.allclose(slope, [1.0, 1.0, 1.0, 1.0, 0.5, 0.1], rtol=0, atol=1e-9)


def test_the_total_predicted_error_adds_the_two_parts_in_quadrature(rng):
    """Identified and unidentified parts are independent: the total radius is sqrt(a^2 + b^2) of
    the two radii sampled here from their covariances (not their sum)."""
    robot = presets.get("puma560")
    layout = Layout(6)
    A, B = rng.normal(size=(36, 5)) * 2e-4, rng.normal(size=(36, 3)) * 3e-4
    u = uncertainty.Uncertainty(layout, robot, np.zeros(36), A, B, 0.0)
    q = simulation.random_joints(robot, 3, rng)
    p0 = kinematics.forward(robot, q)[1]
    draws = rng.standard_normal((4000, 5)) @ A.T + rng.standard_normal((4000, 3)) @ B.T  # both parts at once
    moved = np.array([kinematics.forward(layout.robot(robot, d), q)[1] - p0 for d in draws])
    sampled = np.sqrt(np.mean(np.sum(moved**2, axis=2), axis=0))
    assert np.allclose(u.predict(q)["position_total_m"], sampled, rtol=0.06)


def test_what_is_left_at_nominal_has_the_covariance_of_a_uniform_error_within_the_prior(rng):
    """The prior factor F of the dropped directions: F F^T is the covariance of an error uniform
    within +-p (p^2 / 3 per gene, sampled here) projected onto the directions the data leave at
    nominal, in the prior-scaled genome."""
    K = 8
    prior = rng.uniform(1e-4, 1e-3, K)
    J = rng.normal(size=(20, K))
    J[:, 5:] = 0.0  # the poses see genes 0..4 only
    S = subspace.identify(J, np.zeros((0, K)), prior, None)
    assert S.rank == 5
    X = rng.uniform(-1, 1, (200_000, K)) * prior  # uniform within +-p
    Wd = np.eye(K)[:, 5:]  # the dropped directions in the scaled genome: genes 5..7
    left = (X / prior) @ Wd @ Wd.T * prior
    F = S.prior_factor
    assert np.allclose(F @ F.T, np.cov(left.T), rtol=0, atol=0.02 * prior.max() ** 2 / 3)
