import numpy as np
from scipy.spatial.transform import Rotation

from zrp_ga.model import so3


def test_rodrigues_matches_scipy(rng):
    u = rng.normal(size=(20, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    q = rng.uniform(-np.pi, np.pi, 20)
    expected = Rotation.from_rotvec(u * q[:, None]).as_matrix()
    np.testing.assert_allclose(so3.rodrigues(q, u), expected, atol=1e-14)


def test_rodrigues_derivatives_match_finite_differences(rng):
    u = rng.normal(size=3)  # any axis: Eq. (9-10) differentiate the formula as written
    q, h = 0.7, 1e-6
    dR = so3.rodrigues_derivatives(q, u)
    for k in range(3):
        e = np.eye(3)[k] * h
        fd = (so3.rodrigues(q, u + e) - so3.rodrigues(q, u - e)) / (2 * h)
        np.testing.assert_allclose(dR[k], fd, atol=1e-9)


def test_skew_vee_and_log(rng):
    v, w = rng.normal(size=(2, 3))
    np.testing.assert_allclose(so3.skew(v) @ w, np.cross(v, w), atol=1e-15)
    np.testing.assert_allclose(so3.vee(so3.skew(v)), v)
    rv = rng.normal(size=(5, 3))
    rv *= 2.5 / np.linalg.norm(rv, axis=1, keepdims=True)
    np.testing.assert_allclose(so3.log(Rotation.from_rotvec(rv).as_matrix()), rv, atol=1e-12)


def test_left_jacobian_matches_finite_differences(rng):
    phi, d, h = rng.normal(size=3), rng.normal(size=3), 1e-6
    R = Rotation.from_rotvec
    W = (R(phi + h * d).as_matrix() - R(phi - h * d).as_matrix()) / (2 * h) @ R(phi).as_matrix().T
    np.testing.assert_allclose(so3.vee(W), so3.left_jacobian(phi) @ d, atol=1e-8)


def test_rpy_rebuilds_the_rotation_also_at_gimbal_lock(rng):
    angles = [rng.uniform(-np.pi, np.pi, 3) for _ in range(50)]
    for pitch in (np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-9, -np.pi / 2 + 3e-8, np.pi / 2 - 1e-6, 0.0):
        angles.append([0.3, pitch, -1.2])
    for a in angles:
        R = Rotation.from_euler("xyz", a).as_matrix()  # URDF's R = Rz(yaw) Ry(pitch) Rx(roll)
        np.testing.assert_allclose(Rotation.from_euler("xyz", so3.rpy(R)).as_matrix(), R, atol=2e-15)
