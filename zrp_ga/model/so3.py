"""Rotations in the form the ZRP calibration paper writes them.

Rodrigues' formula as Eq. (6-8) of the paper, ``R = V A + S B + I``, its derivative with
respect to the components of the (not necessarily unit) axis, Eq. (9-10), and the small
helpers around it: skew, vee, the rotation-vector logarithm and URDF's roll-pitch-yaw angles.

Shapes: ``R3`` is ``(..., 3)``, ``SO3`` is ``(..., 3, 3)``; angles in rad.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

R3 = NDArray[np.float64]  # (..., 3)
SO3 = NDArray[np.float64]  # (..., 3, 3)

_E = np.eye(3)
ROTATION_TOL = 1e-6  # |R^T R - I| (largest element) and |det R - 1| a rotation matrix given to the program may have


def skew(v: ArrayLike) -> SO3:
    """Skew matrix ``[v]x`` so that ``skew(v) @ w == cross(v, w)``; ``v`` of shape (..., 3).

    >>> skew([1.0, 2.0, 3.0]) @ np.array([0.0, 0.0, 1.0])
    array([ 2., -1.,  0.])
    """
    v = np.asarray(v, dtype=float)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)


def vee(W: ArrayLike) -> R3:
    """Vector of the skew part of ``W`` (..., 3, 3): ``vee((W - W^T) / 2)``, elements (3,2), (1,3), (2,1).

    Taking the skew part first makes the result immune to round-off in a nearly skew ``W``
    (docs/model.md, section 2).

    >>> vee(skew([0.1, -0.2, 0.3]))
    array([ 0.1, -0.2,  0.3])
    """
    W = np.asarray(W, dtype=float)
    return 0.5 * np.stack(
        [W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], -1
    )


def rodrigues(q: ArrayLike, u: ArrayLike) -> SO3:
    """Rotation by ``q`` (rad) about axis ``u``: ``R = V A + S B + I``, Eq. (6-8).

    ``V = 1 - cos q``, ``S = sin q``, ``A = u u^T - I``, ``B = [u]x``. ``q`` broadcasts against
    the leading shape of ``u`` (..., 3). For a unit ``u`` this is a proper rotation.

    >>> np.round(rodrigues(np.pi / 2, [0.0, 0.0, 1.0]) @ [1.0, 0.0, 0.0], 12)
    array([0., 1., 0.])
    """
    u = np.asarray(u, dtype=float)
    q = np.asarray(q, dtype=float)[..., None, None]
    A = u[..., :, None] * u[..., None, :] - _E
    return (1.0 - np.cos(q)) * A + np.sin(q) * skew(u) + _E


def rodrigues_derivatives(q: ArrayLike, u: ArrayLike) -> NDArray[np.float64]:
    """``dR/du_x, dR/du_y, dR/du_z`` of :func:`rodrigues`, Eq. (9-10), shape (..., 3, 3, 3).

    ``R_k = V (e_k u^T + u e_k^T) + S [e_k]x``; index ``[..., k, :, :]`` is ``R_k``.
    """
    u = np.asarray(u, dtype=float)
    q = np.asarray(q, dtype=float)[..., None, None, None]
    eu = _E[:, :, None] * u[..., None, None, :]  # e_k u^T, (..., 3, 3, 3)
    return (1.0 - np.cos(q)) * (eu + np.swapaxes(eu, -1, -2)) + np.sin(q) * skew(_E)


def log(R: ArrayLike) -> R3:
    """Rotation vector (axis times angle, rad) of the rotation matrices ``R`` (..., 3, 3).

    >>> np.round(log(rodrigues(0.3, [0.0, 1.0, 0.0])), 12)
    array([0. , 0.3, 0. ])
    """
    R = np.asarray(R, dtype=float)
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(R.shape[:-1])


def left_jacobian(phi: ArrayLike) -> SO3:
    """Left Jacobian of SO(3) at the rotation vector ``phi`` (3,): ``exp([phi + d]x) =
    exp([J_l d]x) exp([phi]x)`` to first order in ``d``.

    >>> np.allclose(left_jacobian(np.zeros(3)), np.eye(3))
    True
    """
    phi = np.asarray(phi, dtype=float)
    t = np.linalg.norm(phi)
    K = skew(phi)
    if t < 1e-8:
        return _E + 0.5 * K + K @ K / 6.0
    return _E + (1.0 - np.cos(t)) / t**2 * K + (t - np.sin(t)) / t**3 * K @ K


def rpy(R: ArrayLike) -> R3:
    """Roll, pitch, yaw (3,), rad, of a rotation (3, 3), URDF's ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    Exact to round-off everywhere, also next to pitch = +-90 degrees, where scipy's ``as_euler``
    loses up to 1e-8 (its gimbal-lock branch): yaw first from the first column, then pitch and roll
    from ``Rz(-yaw) R = Ry(pitch) Rx(roll)``, whose entries are well conditioned.

    >>> np.round(rpy(Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix()), 12)
    array([0.1, 0.2, 0.3])
    """
    R = np.asarray(R, dtype=float)
    yaw = np.arctan2(R[1, 0], R[0, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    M = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ R
    return np.array([np.arctan2(-M[1, 2], M[1, 1]), np.arctan2(-M[2, 0], M[0, 0]), yaw]) + 0.0  # no -0.0


def check_rotations(R: ArrayLike, what: str, where: tuple[str, ...] | None = None) -> None:
    """ValueError naming ``what`` (and ``where[k]``, the first bad one) unless every ``R[k]``
    (M, 3, 3) is a rotation: ``R^T R = I`` (largest element) and ``det R = 1`` within
    :data:`ROTATION_TOL`, finite.

    >>> check_rotations(np.stack([np.eye(3), np.diag([1.0, 1.0, -1.0])]), "orientations", ("row 0", "row 1"))
    Traceback (most recent call last):
    ...
    ValueError: orientations, row 1: not a rotation matrix (a mirror (det R = -1))
    """
    R = np.asarray(R, dtype=float)
    with np.errstate(invalid="ignore"):  # NaN in a matrix: refused below, not warned about
        off = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
        det = np.linalg.det(R)
    bad = np.flatnonzero(~(off <= ROTATION_TOL) | ~(np.abs(det - 1.0) <= ROTATION_TOL))  # NaN: not a rotation
    if bad.size:
        k = int(bad[0])
        at = f", {where[k]}" if where is not None else f" [{k}]" if len(R) > 1 else ""
        why = ("NaN or inf in it" if not np.isfinite(R[k]).all() else "a mirror (det R = -1)" if det[k] < 0
               else f"R^T R differs from I by {off[k]:.3g}, det R = {det[k]:.6g}; the tolerance is {ROTATION_TOL:g}")
        raise ValueError(f"{what}{at}: not a rotation matrix ({why})")
