import numpy as np
import pytest

from zrp_ga import robots
from zrp_ga.model import error_model, kinematics, so3
from zrp_ga.model.robot import ZRPRobot


@pytest.fixture(params=["numpy", "compiled"])
def path(request, monkeypatch):
    """Each kernel through its numpy twin and compiled (zrp_ga.core.compiled.call's two paths)."""
    monkeypatch.setenv("ZRP_GA_KERNELS", request.param)
    return request.param


def _random_arm(rng, types):
    n = len(types)
    u0 = rng.normal(size=(n, 3))
    return ZRPRobot(u0=u0, b0=rng.normal(scale=0.3, size=(n + 1, 3)), R_h0=so3.rodrigues(0.4, [0.6, 0.0, 0.8]),
                    joint_types=types, normalize=True)


def _fd_pose_jacobian(robot, q, base, hand, h=1e-6):
    """Central differences of forward() with respect to every parameter, written as [dr; dp]."""
    n = robot.n
    names = error_model.parameter_names(n, base, hand)
    R0, _ = kinematics.forward(robot, q)
    cols = []
    for name in names:
        def perturbed(t):
            u0, b0, R_h0 = robot.u0.copy(), robot.b0.copy(), robot.R_h0.copy()
            c = "xyz".index(name[-1])
            if name.startswith("u0_"):
                u0[int(name[3:-1]) - 1, c] += t
            elif name.startswith("b0_"):
                b0[int(name[3:-1]) - 1, c] += t
            else:
                R_h0 = so3.rodrigues(t, np.eye(3)[c]) @ R_h0
            R, p = kinematics.forward_batch(u0[None], b0[None], R_h0, q, robot.prismatic)
            return R[0], p[0]
        (Rp, pp), (Rm, pm) = perturbed(h), perturbed(-h)
        dR, dp = (Rp - Rm) / (2 * h), (pp - pm) / (2 * h)
        dr = so3.vee(dR @ np.swapaxes(R0, -1, -2))
        cols.append(np.concatenate([dr, dp], axis=-1))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("types", ["RRRRRR", "RRPRRR", "PRRPR"])
@pytest.mark.parametrize("extra", [(False, False), (True, True)])
def test_analytic_jacobian_matches_finite_differences(rng, types, extra, path):
    robot = _random_arm(rng, types)
    q = rng.uniform(-np.pi, np.pi, size=(8, robot.n))
    J = error_model.pose_jacobians(robot, q, *extra)
    fd = _fd_pose_jacobian(robot, q, *extra)
    assert np.max(np.abs(J - fd)) <= 1e-7 * np.max(np.abs(J))


def test_stacked_jacobian_layout(rng):
    robot = robots.get("stanford")
    q = rng.uniform(-1, 1, size=(4, 6))
    J = error_model.error_jacobian(robot, q)
    assert J.shape == (6 * 4 + 6, 36)
    np.testing.assert_array_equal(J[6:12], error_model.pose_jacobians(robot, q[1])[0])
    np.testing.assert_allclose(J[-5, 3:6], robot.u0[1])  # unit row of joint 2, Eq. (19-20)
    Jp = error_model.error_jacobian(robot, q, position_only=True)
    np.testing.assert_array_equal(Jp[:3], J[3:6])
    assert Jp.shape == (3 * 4 + 6, 36)


def test_linearised_error_predicts_pose_change_to_first_order(rng):
    robot = robots.get("puma560")
    q = rng.uniform(-np.pi, np.pi, size=(5, 6))
    R, p = kinematics.forward(robot, q)
    J = error_model.pose_jacobians(robot, q)
    direction = rng.normal(size=36)

    def misfit(scale):
        de = scale * direction
        u0 = robot.u0 + de[:18].reshape(6, 3)
        b0 = robot.b0.copy()
        b0[1:] += de[18:].reshape(6, 3)
        R1, p1 = kinematics.forward_batch(u0[None], b0[None], robot.R_h0, q)
        dr, dp = error_model.pose_error(R1[0], p1[0], R, p)
        return np.abs(np.concatenate([dr, dp], 1) - J @ de).max(), np.abs(J @ de).max()

    (e1, size1), (e2, _) = misfit(1e-4), misfit(1e-5)
    assert e1 < 1e-3 * size1
    assert 50 < e1 / e2 < 200  # the misfit is second order


def test_puma_rank_full_pose_and_position_only(rng):
    robot = robots.get("puma560")
    q = rng.uniform(-np.pi, np.pi, size=(30, 6))
    names = error_model.parameter_names(6)
    full = error_model.identifiability(error_model.error_jacobian(robot, q), names, robot)
    assert full.rank == 31
    assert [d for d in full.null_directions] == [f"b0_{i}/b0_{i + 1} slide along u0_{i}" for i in range(2, 7)]
    pos = error_model.identifiability(error_model.error_jacobian(robot, q, position_only=True), names, robot)
    assert pos.rank == 25
    assert sum("tilts about the end point" in d for d in pos.null_directions) == 6
    assert np.isfinite(full.condition_number) and full.condition_number > 1


def test_slide_direction_really_leaves_poses_unchanged(rng):
    robot = robots.get("puma560")
    b0 = robot.b0.copy()
    b0[2] += 0.05 * robot.u0[2]
    b0[3] -= 0.05 * robot.u0[2]
    q = rng.uniform(-np.pi, np.pi, size=(10, 6))
    np.testing.assert_allclose(kinematics.forward(robot.replace(b0=b0), q)[1], kinematics.forward(robot, q)[1], atol=1e-14)


@pytest.mark.parametrize("name", ["puma560", "ur10", "stanford"])
def test_compiled_jacobian_equals_the_numpy_reference(name, rng, path):
    """Also for axes that are not unit vectors (a genome's axes before normalisation)."""
    robot = robots.get(name)
    u0 = robot.u0 + rng.normal(scale=0.02, size=robot.u0.shape)
    q = rng.uniform(-3, 3, size=(40, robot.n))
    q[:, robot.prismatic] = rng.uniform(0.1, 0.5, size=(40, int(robot.prismatic.sum())))
    for base, hand in ((False, False), (True, True)):
        fast = error_model.jacobian_arrays(u0, robot.b0, robot.prismatic, q, base, hand)
        slow = error_model.jacobian_reference(u0, robot.b0, robot.prismatic, q, base, hand)
        np.testing.assert_allclose(fast, slow, atol=1e-13 * np.abs(slow).max())
