"""Non-geometric terms (zrp_ga.model.terms): each number against an independent answer: the
gravity torques of a planar 2-link arm by hand and of a 6R arm as the derivative of its potential
energy (central differences), harmonics through a plain Rodrigues chain written here, the term
columns of the Jacobian against differences of the residual, LM recovering planted terms, the
compiled and numpy kernels bit for bit, and the robot file's round trip."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from zrp_ga.io import presets
from zrp_ga.model import _kernels, _numpy_kernels, kinematics, terms
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.problems.least_squares import levenberg_marquardt

G = 9.80665


def planar(L1=0.7, L2=0.5, m1=3.0, m2=2.0, payload=(1.5, (0.1, 0.0, 0.0))):
    """Two joints about +y, links along x at q = 0 (a vertical plane), point masses at the link
    middles, a payload 0.1 m beyond the end point along the hand's x."""
    robot = ZRPRobot(u0=[[0, 1, 0], [0, 1, 0]], b0=[[0, 0, 0], [L1, 0, 0], [L2, 0, 0]])
    mass = terms.MassModel([m1, m2], [[L1 / 2, 0, 0], [L2 / 2, 0, 0]], payload[0], payload[1])
    return robot.replace(mass=mass)


def test_gravity_torques_of_a_planar_two_link_arm_by_hand():
    L1, L2, m1, m2, mp, d = 0.7, 0.5, 3.0, 2.0, 1.5, 0.1
    robot = planar(L1, L2, m1, m2, (mp, (d, 0, 0)))
    q = np.array([[0.3, -0.8], [0.0, 0.0], [1.2, 0.4], [-2.0, 2.5]])
    # turning about +y by q takes x to (cos q, 0, -sin q): the lever arm of a weight is its x
    c1, c12 = np.cos(q[:, 0]), np.cos(q.sum(axis=1))
    tau2 = G * (m2 * L2 / 2 * c12 + mp * (L2 + d) * c12)
    tau1 = G * (m1 * L1 / 2 * c1 + m2 * (L1 * c1 + L2 / 2 * c12) + mp * (L1 * c1 + (L2 + d) * c12))
    np.testing.assert_allclose(terms.gravity_torques(robot, q), np.column_stack([tau1, tau2]), rtol=1e-12, atol=1e-12)


def _arm6(seed=0):
    rng = np.random.default_rng(seed)
    robot = presets.get("puma560")
    mass = terms.MassModel(rng.uniform(1, 10, 6), rng.normal(0, 0.2, (6, 3)), 4.0, rng.normal(0, 0.1, 3))
    return robot.replace(mass=mass), rng


def test_gravity_torque_is_minus_the_derivative_of_the_potential_energy():
    robot, rng = _arm6()
    mass = robot.mass

    def potential(q):  # V = -sum m g . x over the link centres and the payload
        axes, points, rots, p = terms.frames(robot, q[None])
        x = points[0] + np.einsum("nab,nb->na", rots[0], mass.centres)
        xp = p[0] + rots[0, -1] @ robot.R_h0 @ mass.payload_com
        return -(mass.masses @ (x @ mass.gravity)) - mass.payload_mass * xp @ mass.gravity

    for q in rng.uniform(-2, 2, (3, 6)):
        h = 1e-6
        fd = np.array([-(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(6)])
        np.testing.assert_allclose(terms.gravity_torques(robot, q), fd, rtol=1e-6, atol=1e-7)


def test_compliance_deflection_turns_the_joint_by_c_times_its_torque():
    robot, rng = _arm6(1)
    spec = terms.TermSpec(compliance=(2, 3))
    arm = robot.replace(terms=terms.Terms(spec, [2e-5, -1e-5]))
    q = rng.uniform(-1, 1, (5, 6))
    tau = terms.gravity_torques(robot, q)
    expected = q.copy()
    expected[:, 1] += 2e-5 * tau[:, 1]
    expected[:, 2] += -1e-5 * tau[:, 2]
    np.testing.assert_allclose(terms.effective(arm, q), expected, rtol=0, atol=1e-15)
    # the hand moves as the geometric arm at the deflected joints
    R, p = kinematics.forward(arm, q)
    R0, p0 = kinematics.forward(robot, expected)
    np.testing.assert_allclose(p, p0, atol=1e-15)
    np.testing.assert_allclose(R, R0, atol=1e-15)


def _plain_chain(u0, b0, R_h0, q):
    """Eq. (1-5) with scipy's rotations, one pose at a time (revolute joints)."""
    R, p = np.eye(3), np.zeros(3)
    for i in range(len(q)):
        p = p + R @ b0[i]
        R = R @ Rotation.from_rotvec(q[i] * np.asarray(u0[i])).as_matrix()
    return R @ R_h0, p + R @ b0[-1]


def test_harmonics_match_a_plain_chain_with_the_offsets_added():
    robot = presets.get("ur10")
    spec = terms.TermSpec(harmonics=(1, 4), order=2)
    # names: harmonic_1_sin1, _cos1, _sin2, _cos2, then joint 4's
    v = np.array([1e-3, -2e-3, 5e-4, 3e-4, -7e-4, 1e-3, 2e-4, -4e-4])
    arm = robot.replace(terms=terms.Terms(spec, v))
    rng = np.random.default_rng(3)
    for q in rng.uniform(-3, 3, (4, 6)):
        qe = q.copy()
        qe[0] += v[0] * np.sin(q[0]) + v[1] * np.cos(q[0]) + v[2] * np.sin(2 * q[0]) + v[3] * np.cos(2 * q[0])
        qe[3] += v[4] * np.sin(q[3]) + v[5] * np.cos(q[3]) + v[6] * np.sin(2 * q[3]) + v[7] * np.cos(2 * q[3])
        R0, p0 = _plain_chain(robot.u0, robot.b0, robot.R_h0, qe)
        R, p = kinematics.forward(arm, q)
        np.testing.assert_allclose(p, p0, atol=1e-13)
        np.testing.assert_allclose(R, R0, atol=1e-13)


SPEC = terms.TermSpec((2, 3), (1,), 1)


def _problem(seed=0, spec=SPEC, M=40, noise=0.0):
    robot, rng = _arm6(seed)
    layout = Layout(6, base=True, hand=True, terms=spec)
    x = np.concatenate([rng.normal(0, 3e-4, layout.size - spec.size), np.zeros(spec.size)])
    x[-spec.size :] = [3e-5, -2e-5, 1e-3, -5e-4][: spec.size]
    true = layout.robot(robot, x)
    q = rng.uniform(-1.5, 1.5, (M, 6))
    # the data as the fit models them: the torques on the nominal arm at the commanded angles
    qe = q + terms.offsets(spec, 6, terms.features(spec, robot, q), x[-spec.size :])
    R, p = kinematics.forward(true.geometric, qe)
    p = p + rng.normal(0, noise, p.shape)
    K = layout.size
    return CalibrationProblem(robot, Measurements(q, p, R), layout, -np.ones(K), np.ones(K), cost="nonlinear"), x, true


def test_term_columns_of_the_jacobian_match_central_differences():
    problem, x, _ = _problem()
    x0 = 0.5 * x
    J = problem.jacobian(x0)
    h = 1e-7
    for k in range(problem.layout.size - 4, problem.layout.size):  # the term genes
        e = np.zeros_like(x0)
        e[k] = h * (1e-2 if k == problem.layout.size - 4 else 1)
        fd = -(problem.residual(x0 + e) - problem.residual(x0 - e)) / (2 * e[k])
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max())


def test_lm_recovers_planted_compliance_and_harmonics():
    problem, x, _ = _problem(seed=2, M=60, noise=1e-6)
    fit = levenberg_marquardt(problem)
    got = fit.x[-4:]
    np.testing.assert_allclose(got, x[-4:], rtol=0.02)
    # and without terms the same data fit far worse
    geo = CalibrationProblem(problem.nominal, problem.data, Layout(6, base=True, hand=True), -np.ones(42), np.ones(42), cost="nonlinear")
    assert levenberg_marquardt(geo).cost > 20 * fit.cost


@pytest.mark.parametrize("P", [1, 31, 33])
def test_compiled_and_numpy_kernels_agree_with_joint_angles_per_genome(P):
    rng = np.random.default_rng(P)
    n, M = 6, 7
    u0 = rng.normal(size=(P, n, 3))
    u0 /= np.linalg.norm(u0, axis=-1, keepdims=True)
    b0 = rng.normal(scale=0.3, size=(P, n + 1, 3))
    U, B, H = kinematics._population(u0, b0, np.eye(3))
    q = rng.uniform(-3, 3, (M, n))
    dq = rng.normal(0, 1e-2, (M, n, P))
    c, s, t = (np.ascontiguousarray(a) for a in kinematics.joint_terms_lanes(q, dq, None))
    p_meas, wp = rng.normal(size=(M, 3)), rng.uniform(0.5, 2, (M, 3))
    R_meas = np.ascontiguousarray(Rotation.random(M, random_state=P).as_matrix())
    outs = {}
    for name in ("compiled", "numpy"):
        R, p, out = np.empty((P, M, 3, 3)), np.empty((P, M, 3)), np.empty((2, P))
        args = (U, B, H, c, s, t, p_meas, wp, R_meas, True, out)
        if name == "compiled":
            _kernels.forward_kernel_lanes(U, B, H, c, s, t, R, p)
            _kernels.residual_rodrigues_lanes(*args, 0, -(-P // _kernels.LANES))
        else:
            _numpy_kernels.forward(U, B, H, c, s, t, R, p)
            _numpy_kernels.residual_rodrigues(*args)
        outs[name] = (R, p, out)
    for a, b in zip(outs["compiled"], outs["numpy"]):
        np.testing.assert_array_equal(a, b)
    # and each genome's pose is the one-genome kernel's at its own angles
    for k in (0, P - 1):
        Rk, pk = kinematics.forward_batch(u0[k : k + 1], b0[k : k + 1], np.eye(3), q + dq[:, :, k])
        np.testing.assert_allclose(outs["numpy"][1][k], pk[0], atol=1e-14)


def test_population_costs_equal_the_residual_norm_of_each_genome():
    problem, x, _ = _problem(seed=4)
    X = x + np.random.default_rng(0).normal(0, 1e-4, (5, x.size))
    costs = problem.costs(X)
    np.testing.assert_allclose(costs, [np.linalg.norm(problem.residual(xk)) for xk in X], rtol=1e-10)


def test_robot_file_round_trip_carries_terms_and_mass(tmp_path):
    _, _, true = _problem(seed=5)
    path = tmp_path / "arm.yaml"
    true.to_yaml(path)
    back = ZRPRobot.from_yaml(path)
    assert back.terms.spec == true.terms.spec
    np.testing.assert_array_equal(back.terms.values, true.terms.values)
    np.testing.assert_array_equal(back.mass.masses, true.mass.masses)
    q = np.random.default_rng(1).uniform(-1, 1, (4, 6))
    np.testing.assert_array_equal(kinematics.forward(back, q)[1], kinematics.forward(true, q)[1])
    from zrp_ga.io.robot_files import read_robot

    np.testing.assert_array_equal(read_robot(path).terms.values, true.terms.values)


def test_exports_write_the_geometric_part_and_say_so(tmp_path, caplog):
    from zrp_ga.io.robot_files import read_robot, write_robot_files

    _, _, true = _problem(seed=6)
    with caplog.at_level("INFO", logger="zrp_ga"):
        paths = write_robot_files(true, tmp_path)
    assert "geometric part" in caplog.text
    assert "geometric part" in paths["urdf"].read_text() and "geometric part" in paths["dh"].read_text()
    urdf = read_robot(paths["urdf"])
    assert urdf.terms is None
    q = np.random.default_rng(2).uniform(-1, 1, (3, 6))
    np.testing.assert_allclose(kinematics.forward(urdf, q)[1], kinematics.forward(true.geometric, q)[1], atol=1e-9)
    assert read_robot(paths["zrp"]).terms is not None


@pytest.mark.parametrize("value, message", [
    ({"compliance": [7]}, "joint 7 is not a joint"),
    ({"compliance": "2"}, "list of joint numbers"),
    ({"harmonics": {"order": 0, "joints": [1]}}, "order"),
    ({"stiffness": [2]}, "unknown key 'stiffness'"),
    ({"payload": {"mass": 3}}, "acts through joint compliance"),
    ({"compliance": [0]}, "compliance: joint 0 is not a joint of puma560"),
    ({"harmonics": [7]}, "harmonics: joint 7 is not a joint of puma560"),
    ({"harmonics": {"order": -1, "joints": [1]}}, r"harmonics.order: must be an integer 1..10, got -1"),
    ({"compliance": [2, 3], "payload": {"mass": -5, "com": [0, 0, 0.1]}}, "payload: mass must be >= 0 kg"),
    ({"compliance": [2.5]}, r"compliance: expected joint numbers \(1-based integers\), got 2.5"),
    ({"compliance": {"joint": 2}}, r"compliance: expected a list of joint numbers \(1-based\), got \{'joint': 2\}"),
    ({"harmonics": {"order": 1, "joints": {"joint": 2}}}, r"harmonics.joints: expected a list of joint numbers"),
    ([2, 3], "problem.terms: expected a mapping"),
    ({"compliance": [2, 2]}, "compliance: joint 2 named twice"),
    ({"harmonics": [1, 3, 1]}, "harmonics: joint 1 named twice"),
    ({"harmonics": {"order": 2}}, "harmonics.joints: no joint named"),
])  # fmt: skip
def test_bad_terms_settings_are_one_line_naming_the_key(value, message):
    from zrp_ga.problems import with_terms

    class C:
        terms = value

    with pytest.raises(ValueError, match=message) as info:
        with_terms(C(), Layout(6), presets.get("puma560"))
    assert "problem.terms" in str(info.value) and "\n" not in str(info.value)


PLANAR_URDF = """<?xml version="1.0"?>
<robot name="planar">
  <link name="base"><inertial><mass value="50"/><origin xyz="0 0 0.1"/></inertial></link>
  <link name="upper"><inertial><mass value="3.0"/><origin xyz="0.35 0 0"/></inertial></link>
  <link name="fore"><inertial><mass value="2.0"/><origin xyz="0.25 0 0"/></inertial></link>
  <link name="tool"><inertial><mass value="1.5"/><origin xyz="0.1 0 0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="0" velocity="0"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.7 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="0" velocity="0"/></joint>
  <joint name="flange" type="fixed"><parent link="fore"/><child link="tool"/><origin xyz="0.5 0 0"/></joint>
</robot>
"""


def test_urdf_inertials_give_the_mass_model_and_the_hand_torques(tmp_path):
    from zrp_ga.io.robot_files import read_robot

    path = tmp_path / "planar.urdf"
    path.write_text(PLANAR_URDF)
    robot = read_robot(path)
    assert robot.mass is not None and "URDF inertials" in robot.mass.source
    # the base's 50 kg moves with no joint; the tool's 1.5 kg at 0.1 m beyond the end point rides on the elbow
    L1, L2, m1, m2, mt, d = 0.7, 0.5, 3.0, 2.0, 1.5, 0.1
    q = np.array([[0.3, -0.8], [1.2, 0.4]])
    c1, c12 = np.cos(q[:, 0]), np.cos(q.sum(axis=1))
    tau2 = G * (m2 * L2 / 2 * c12 + mt * (L2 + d) * c12)
    tau1 = G * (m1 * L1 / 2 * c1 + m2 * (L1 * c1 + L2 / 2 * c12) + mt * (L1 * c1 + (L2 + d) * c12))
    np.testing.assert_allclose(terms.gravity_torques(robot, q), np.column_stack([tau1, tau2]), rtol=1e-12)


def test_calibrate_takes_terms_and_every_file_names_them(tmp_path):
    import json

    import pandas as pd

    import zrp_ga

    cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm",
                           terms={"compliance": [2, 3], "harmonics": {"order": 1, "joints": [1]}}, out=tmp_path)  # fmt: skip
    names = ["compliance_2", "compliance_3", "harmonic_1_sin1", "harmonic_1_cos1"]
    assert cal.robot.terms.spec.names == names and cal.task.layout.names[-4:] == names
    params = pd.read_csv(tmp_path / "best_params.csv")
    rows = params.set_index("joint").loc[names]
    assert rows["term_unit"].tolist() == ["rad/(N m)", "rad/(N m)", "rad", "rad"]
    np.testing.assert_allclose(rows["term_value"], cal.robot.terms.values)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["problem"]["terms"]["names"] == names and "generic" in summary["problem"]["terms"]["mass_model"]
    assert [summary["terms"][k]["value"] for k in names] == cal.robot.terms.values.tolist()
    back = ZRPRobot.from_yaml(tmp_path / "calibrated_robot.yaml")
    np.testing.assert_array_equal(back.terms.values, cal.robot.terms.values)
    assert "geometric part" in (tmp_path / "calibrated_robot.urdf").read_text()
    unc = json.loads((tmp_path / "uncertainty.json").read_text())
    assert unc["layout"]["terms"] == {"compliance": [2, 3], "harmonics": {"order": 1, "joints": [1]}}


@pytest.mark.slow
def test_the_population_optimisers_carry_the_term_genes():
    import zrp_ga

    for algorithm in ("ga", "cmaes"):
        cal = zrp_ga.calibrate("puma560", problem={"n_poses": 20, "cost": "nonlinear"}, algorithm=algorithm,
                               population={"mu": 8, "lambda_": 8, "generations": 3}, terms={"compliance": [2]})  # fmt: skip
        assert cal.task.layout.names[-1] == "compliance_2"
        assert np.isfinite(cal.summary["final_cost"]) and cal.robot.terms is not None


def test_pose_selection_refuses_terms_in_one_line():
    from zrp_ga.problems import selection

    with pytest.raises(ValueError, match="problem.terms: pose selection chooses poses for the geometric model"):
        selection.build(presets.get("puma560"), terms={"compliance": [2]})


def test_uncertainty_jacobians_carry_the_terms_against_differences():
    from zrp_ga.model import metrics, uncertainty

    problem, x, _ = _problem(seed=7)
    layout, nominal = problem.layout, problem.nominal
    q = problem.data.q[:6]
    data = Measurements(q, np.zeros((6, 3)))
    J = uncertainty.pose_jacobians(layout, nominal, x, q)
    for k in [0, 20, *range(layout.size - 4, layout.size)]:  # an axis gene, a body gene, the terms
        h = 1e-7 * (1e-2 if layout.full_names[k].startswith("compliance") else 1)
        e = np.zeros_like(x)
        e[k] = h
        fd = (metrics.predicted_positions(layout, nominal, x + e, data)[0] - metrics.predicted_positions(layout, nominal, x - e, data)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, 3:, k], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_compensation_solves_on_the_full_model():
    from zrp_ga.compensation import ik

    _, _, true = _problem(seed=8)
    q0 = np.array([0.2, -0.4, 0.5, 0.1, 0.6, -0.2])
    R, p, J = ik.forward_jacobian(true, q0)
    h = 1e-6
    fd = np.stack([(kinematics.forward(true, q0 + h * e)[1] - kinematics.forward(true, q0 - h * e)[1]) / (2 * h) for e in np.eye(6)], axis=1)
    np.testing.assert_allclose(J[3:], fd, atol=1e-8)
    np.testing.assert_allclose(p, kinematics.forward(true, q0)[1], atol=1e-15)
    target = kinematics.forward(true, q0 + 0.05)[1]
    s = ik.solve(true, target, None, q0)
    assert s.reached and np.linalg.norm(kinematics.forward(true, s.q)[1] - target) < 1e-9
    assert np.linalg.norm(kinematics.forward(true.geometric, s.q)[1] - target) > 1e-5  # the terms matter here
