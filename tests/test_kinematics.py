import numpy as np
import pytest

from dh_reference import dh_fk
from zrp_ga import kinematics, robots
from zrp_ga.robot import ZRPRobot
from zrp_ga.robot_files import read_dh


@pytest.mark.parametrize("name", robots.names())
def test_forward_matches_independent_dh_chain(name, rng):
    robot, dh = robots.get(name), read_dh(robots.path(name))
    table = dict(d=dh.d, a=dh.a, alpha=dh.alpha, offset=dh.theta, joint_types=dh.joint_types)
    Q = rng.uniform(-np.pi, np.pi, size=(25, robot.n))
    Q[:, robot.prismatic] = rng.uniform(0.3, 1.2, size=(25, robot.prismatic.sum()))
    R, p = kinematics.forward(robot, Q)
    for m, q in enumerate(Q):
        T = dh_fk(table, q)
        np.testing.assert_allclose(R[m], T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p[m], T[:3, 3], atol=1e-12)


def test_modified_dh_matches_independent_chain(rng):
    table = dict(
        d=[0.3, 0.1, -0.2, 0.4, 0.0], a=[0.0, 0.05, 0.35, 0.0, 0.1],
        alpha=[0.0, np.pi / 2, 0.1, -np.pi / 2, np.pi / 2], offset=[0.1, 0.0, 0.2, 0.0, -0.3], joint_types="RRPRR",
    )
    robot = ZRPRobot.from_mdh(**table)
    for q in rng.uniform(-2, 2, size=(10, 5)):
        R, p = kinematics.forward(robot, q)
        T = dh_fk(table, q, modified=True)
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p, T[:3, 3], atol=1e-12)


def test_puma_wrist_centre_at_zero():
    R, p = kinematics.forward(robots.get("puma560"), np.zeros(6))
    np.testing.assert_allclose(p, [0.4521, -0.15005, 1.10363], atol=1e-12)
    np.testing.assert_allclose(R, np.eye(3), atol=1e-12)


def test_batch_over_population_equals_each_robot(rng):
    base = robots.get("stanford")
    P, M = 7, 11
    u0 = base.u0 + rng.normal(scale=0.01, size=(P, 6, 3))
    u0 /= np.linalg.norm(u0, axis=-1, keepdims=True)
    b0 = base.b0 + rng.normal(scale=0.01, size=(P, 7, 3))
    q = rng.uniform(-1, 1, size=(M, 6))
    R, p = kinematics.forward_batch(u0, b0, base.R_h0, q, base.prismatic)
    assert R.shape == (P, M, 3, 3) and p.shape == (P, M, 3)
    for k in range(P):
        robot_k = base.replace(u0=u0[k], b0=b0[k])
        Rk, pk = kinematics.forward(robot_k, q)
        np.testing.assert_allclose(R[k], Rk, atol=1e-14)
        np.testing.assert_allclose(p[k], pk, atol=1e-14)


def test_residual_sums_by_hand(rng):
    robot = robots.get("ur10")
    P, M = 4, 9
    u0 = robot.u0 + rng.normal(scale=0.02, size=(P, 6, 3))
    b0 = robot.b0 + rng.normal(scale=0.02, size=(P, 7, 3))
    q = rng.uniform(-3, 3, size=(M, 6))
    R_meas, p_meas = kinematics.forward(robot, q)
    R, p = kinematics.forward_batch(u0, b0, robot.R_h0, q)
    W = R_meas[None] @ np.swapaxes(R, -1, -2)
    dr = 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], -1)
    expected = np.stack([(dr**2).sum(axis=(1, 2)), ((p_meas - p) ** 2).sum(axis=(1, 2))], -1)
    got = kinematics.residual_sums(u0, b0, robot.R_h0, q, p_meas, R_meas)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    got = kinematics.residual_sums(u0, b0, robot.R_h0, q, p_meas)  # position only
    np.testing.assert_allclose(got[:, 0], 0.0)
    np.testing.assert_allclose(got[:, 1], expected[:, 1], rtol=1e-12)


@pytest.mark.parametrize(
    "q, message",
    [(np.zeros(5), r"q: expected shape \(6,\) or \(M, 6\)"), (np.zeros((2, 3, 6)), "q: expected shape"),
     ([0, 0, np.nan, 0, 0, 0], r"q: NaN or inf at index \(2,\)")],
)
def test_forward_refuses_bad_q(q, message):
    with pytest.raises(ValueError, match=message):
        kinematics.forward(robots.get("puma560"), q)
