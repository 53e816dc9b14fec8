"""to_dh and DHTable against the independent DH chain of tests/dh_reference.py."""

import numpy as np
import pytest
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

from zrp_ga import kinematics, robots
from zrp_ga.dh import DHTable, to_dh
from zrp_ga.robot import ZRPRobot
from zrp_ga.robot_files import read_dh


def reference_fk(table: DHTable, q):
    """base @ (DH or MDH chain of tests/dh_reference.py) @ tool."""
    rows = dict(d=table.d, a=table.a, alpha=table.alpha, offset=table.theta, joint_types=table.joint_types)
    return table.base @ dh_fk(rows, q, modified=table.convention == "mdh") @ table.tool


def random_q(robot, rng, M=20):
    limits = robot.joint_limits
    return rng.uniform(limits[:, 0], limits[:, 1], size=(M, robot.n))


def random_arm(rng, types):
    """An arm with random axes and body vectors: no two axes parallel."""
    n = len(types)
    return ZRPRobot(
        u0=rng.normal(size=(n, 3)), b0=rng.uniform(-0.4, 0.4, size=(n + 1, 3)),
        R_h0=Rotation.random(random_state=int(rng.integers(1000))).as_matrix(), joint_types=types, normalize=True,
    )


@pytest.mark.parametrize("name", robots.names())
def test_to_dh_recovers_the_preset_tables(name, rng):
    robot, published = robots.get(name), read_dh(robots.path(name))
    table, mismatch = to_dh(robot)
    for field in ("a", "alpha", "d", "theta"):
        np.testing.assert_allclose(getattr(table, field), getattr(published, field), atol=1e-12, err_msg=field)
    np.testing.assert_allclose(table.base, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(table.tool, np.eye(4), atol=1e-12)
    assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12 and mismatch.notes == ()
    assert table.joint_names == robot.joint_names and np.array_equal(table.limits, robot.limits)
    for q in random_q(robot, rng, 5):
        np.testing.assert_allclose(table.forward(q), reference_fk(published, q), atol=1e-12)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("name", robots.names())
def test_table_forward_kinematics_equal_the_zrp_model(name, convention, rng):
    robot = robots.get(name)
    table, mismatch = to_dh(robot, convention)
    assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12
    q = random_q(robot, rng)
    R, p = kinematics.forward(robot, q)
    for m in range(len(q)):
        T = reference_fk(table, q[m])
        np.testing.assert_allclose(T[:3, :3], R[m], atol=1e-12)
        np.testing.assert_allclose(T[:3, 3], p[m], atol=1e-12)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("types", ["RRRRRR", "RPRRPR", "PRR"])
def test_general_axes_admit_dh_exactly(types, convention, rng):
    robot = random_arm(rng, types)
    table, mismatch = to_dh(robot, convention)
    assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12 and mismatch.notes == ()
    q = random_q(robot, rng, 10)
    R, p = kinematics.forward(robot, q)
    for m in range(len(q)):
        np.testing.assert_allclose(reference_fk(table, q[m])[:3, 3], p[m], atol=1e-12)
    np.testing.assert_allclose(kinematics.forward(table.to_robot(), q)[1], p, atol=1e-12)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_nearly_parallel_axes_leave_a_small_reported_mismatch(convention, rng):
    """A calibrated-like UR10: axes 2, 3, 4 (parallel by design) tilted by about 1e-5 rad."""
    ur10 = robots.get("ur10")
    robot = ur10.replace(u0=ur10.u0 + rng.normal(scale=1e-5, size=(6, 3)), normalize=True)
    table, mismatch = to_dh(robot, convention)
    assert 1e-8 < mismatch.position_m < 1e-4 and 1e-8 < mismatch.orientation_rad < 1e-4
    assert [note.split(" (")[0] for note in mismatch.notes] == ["joint 3", "joint 4"]
    assert "parallel within 0.001 rad" in mismatch.notes[0]
    # the reported mismatch is what an independent evaluation of the table finds
    q = random_q(robot, rng, 200)
    _, p = kinematics.forward(robot, q)
    errors = [np.linalg.norm(reference_fk(table, qm)[:3, 3] - pm) for qm, pm in zip(q, p)]
    assert 0.3 * mismatch.position_m < max(errors) < 3 * mismatch.position_m
    # lengths stay those of the arm (d = 0 for the parallel pairs), not kilometres
    assert np.abs(table.d).max() < 0.2


def test_parallel_tol_zero_gives_the_exact_but_far_away_common_normals(rng):
    ur10 = robots.get("ur10")
    robot = ur10.replace(u0=ur10.u0 + rng.normal(scale=1e-3, size=(6, 3)), normalize=True)
    table, mismatch = to_dh(robot, parallel_tol=0.0)
    assert mismatch.position_m < 1e-9 and mismatch.notes == ()
    assert np.abs(table.d).max() > 10.0  # the price: common normals metres away


def test_unknown_convention_is_refused():
    with pytest.raises(ValueError, match="convention: 'craig', expected one of dh, mdh"):
        to_dh(robots.get("puma560"), "craig")
