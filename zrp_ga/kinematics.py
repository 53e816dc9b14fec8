"""Forward kinematics of the ZRP model, Eq. (1-5, 14) of the ZRP calibration paper.

    R_i = R_{i-1} R(q_i, u0_i),   R_h = R_n R_h0,
    p   = sum_{i=1}^{n+1} R_{i-1} b0_i + sum_{prismatic i} q_i R_{i-1} u0_i

is evaluated from the tail, ``p = b~0_1 + R(q_1)(b~0_2 + R(q_2)(... + R(q_n) b0_{n+1}))`` with
``b~0_i = b0_i + q_i u0_i`` for a prismatic joint, so that each joint rotates four vectors (the
position and the three columns of ``R_h0``) by Rodrigues' formula
``R(q, u) v = cos q v + sin q (u x v) + (1 - cos q)(u . v) u`` instead of multiplying
matrices. The loops are compiled with numba: a whole population of parameter sets (P, ...)
over all poses (M, n) is one call, and ``cos q``, ``sin q`` of a pose are computed once for
the whole population. numba because no numpy formulation of the many tiny 3-vector updates
came near (1.1 M against 12 M pose evaluations per second in a first trial; see
experiments/bench_kinematics.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


@njit(cache=True)
def _chain(u0, b0, Rh0, prismatic, c, s, q, X):  # pragma: no cover - compiled
    """One parameter set at one pose: X[0] = p, X[1 + j] = column j of R_h (in place)."""
    n = u0.shape[0]
    for k in range(3):
        X[0, k] = b0[n, k]
        for j in range(3):
            X[1 + j, k] = Rh0[k, j]
    for i in range(n - 1, -1, -1):
        ux, uy, uz = u0[i, 0], u0[i, 1], u0[i, 2]
        if prismatic[i]:
            X[0, 0] += b0[i, 0] + q[i] * ux
            X[0, 1] += b0[i, 1] + q[i] * uy
            X[0, 2] += b0[i, 2] + q[i] * uz
            continue
        ci, si = c[i], s[i]
        vi = 1.0 - ci
        for k in range(4):
            x, y, z = X[k, 0], X[k, 1], X[k, 2]
            d = (ux * x + uy * y + uz * z) * vi
            X[k, 0] = ci * x + si * (uy * z - uz * y) + d * ux
            X[k, 1] = ci * y + si * (uz * x - ux * z) + d * uy
            X[k, 2] = ci * z + si * (ux * y - uy * x) + d * uz
        X[0, 0] += b0[i, 0]
        X[0, 1] += b0[i, 1]
        X[0, 2] += b0[i, 2]


@njit(cache=True)
def _forward_kernel(u0, b0, Rh0, prismatic, c, s, q, R_out, p_out):  # pragma: no cover
    X = np.empty((4, 3))
    for ip in range(u0.shape[0]):
        for m in range(q.shape[0]):
            _chain(u0[ip], b0[ip], Rh0[ip], prismatic, c[m], s[m], q[m], X)
            for k in range(3):
                p_out[ip, m, k] = X[0, k]
                for j in range(3):
                    R_out[ip, m, k, j] = X[1 + j, k]


@njit(cache=True)
def _residual_kernel(u0, b0, Rh0, prismatic, c, s, q, p_meas, R_meas, use_rot, out):  # pragma: no cover
    X = np.empty((4, 3))
    for ip in range(u0.shape[0]):
        sr = 0.0
        sp = 0.0
        for m in range(q.shape[0]):
            _chain(u0[ip], b0[ip], Rh0[ip], prismatic, c[m], s[m], q[m], X)
            for k in range(3):
                e = p_meas[m, k] - X[0, k]
                sp += e * e
            if use_rot:
                # W = R_meas R_model^T; dr = vee((W - W^T) / 2); R_model[b, k] = X[1 + k, b]
                Rm = R_meas[m]
                w21 = w12 = w02 = w20 = w10 = w01 = 0.0
                for k in range(3):
                    w21 += Rm[2, k] * X[1 + k, 1]
                    w12 += Rm[1, k] * X[1 + k, 2]
                    w02 += Rm[0, k] * X[1 + k, 2]
                    w20 += Rm[2, k] * X[1 + k, 0]
                    w10 += Rm[1, k] * X[1 + k, 0]
                    w01 += Rm[0, k] * X[1 + k, 1]
                dx = 0.5 * (w21 - w12)
                dy = 0.5 * (w02 - w20)
                dz = 0.5 * (w10 - w01)
                sr += dx * dx + dy * dy + dz * dz
        out[ip, 0] = sr
        out[ip, 1] = sp


def check_q(q: ArrayLike, n: int, name: str = "q") -> Array:
    """``q`` as a float array of shape (n,) or (M, n), finite; ValueError naming the problem."""
    q = np.asarray(q, dtype=float)
    if q.ndim not in (1, 2) or q.shape[-1] != n:
        raise ValueError(f"{name}: expected shape ({n},) or (M, {n}) joint values, got {q.shape}")
    bad = np.argwhere(~np.isfinite(q))
    if bad.size:
        raise ValueError(f"{name}: NaN or inf at index {tuple(int(i) for i in bad[0])}")
    return q


def _population(u0: ArrayLike, b0: ArrayLike, R_h0: ArrayLike) -> tuple[Array, Array, Array]:
    u0 = np.ascontiguousarray(u0, dtype=float)
    b0 = np.ascontiguousarray(b0, dtype=float)
    if u0.ndim != 3 or u0.shape[2] != 3:
        raise ValueError(f"u0: expected shape (P, n, 3), got {u0.shape}")
    P, n = u0.shape[:2]
    if b0.shape != (P, n + 1, 3):
        raise ValueError(f"b0: expected shape ({P}, {n + 1}, 3), got {b0.shape}")
    R_h0 = np.asarray(R_h0, dtype=float)
    if R_h0.shape not in ((3, 3), (P, 3, 3)):
        raise ValueError(f"R_h0: expected shape (3, 3) or ({P}, 3, 3), got {R_h0.shape}")
    return u0, b0, np.ascontiguousarray(np.broadcast_to(R_h0, (P, 3, 3)))


def _prismatic(prismatic: ArrayLike | None, n: int) -> NDArray[np.bool_]:
    out = np.zeros(n, dtype=bool) if prismatic is None else np.asarray(prismatic, dtype=bool)
    if out.shape != (n,):
        raise ValueError(f"prismatic: expected shape ({n},), got {out.shape}")
    return out


def forward_batch(
    u0: ArrayLike, b0: ArrayLike, R_h0: ArrayLike, q: ArrayLike, prismatic: ArrayLike | None = None
) -> tuple[Array, Array]:
    """Hand poses of P parameter sets at M poses, in one compiled call.

    u0 (P, n, 3), b0 (P, n+1, 3), R_h0 (3, 3) or (P, 3, 3), q (M, n) (rad for revolute, m for
    prismatic joints), prismatic (n,) bool. Returns R (P, M, 3, 3) and p (P, M, 3), m.
    Axes need not be unit vectors: the formula is Eq. (6-8) as written.
    """
    u0, b0, R_h0 = _population(u0, b0, R_h0)
    P, n = u0.shape[:2]
    q = np.atleast_2d(check_q(q, n))
    R = np.empty((P, q.shape[0], 3, 3))
    p = np.empty((P, q.shape[0], 3))
    _forward_kernel(u0, b0, R_h0, _prismatic(prismatic, n), np.cos(q), np.sin(q), q, R, p)
    return R, p


def residual_sums(
    u0: ArrayLike,
    b0: ArrayLike,
    R_h0: ArrayLike,
    q: ArrayLike,
    p_meas: ArrayLike,
    R_meas: ArrayLike | None = None,
    prismatic: ArrayLike | None = None,
) -> Array:
    """Sums of squared pose errors of P parameter sets over M measured poses, (P, 2).

    Column 0: sum over poses of ``|dr|^2`` (rad^2), ``dr = vee(skew(R_meas R^T))`` (0 when
    ``R_meas`` is None: position-only data); column 1: sum of ``|p_meas - p|^2`` (m^2).
    Nothing of size (P, M) is stored, so the population's cost costs no memory traffic.
    """
    u0, b0, R_h0 = _population(u0, b0, R_h0)
    P, n = u0.shape[:2]
    q = np.atleast_2d(check_q(q, n))
    M = q.shape[0]
    p_meas = np.ascontiguousarray(p_meas, dtype=float)
    if p_meas.shape != (M, 3):
        raise ValueError(f"p_meas: expected shape ({M}, 3), got {p_meas.shape}")
    use_rot = R_meas is not None
    R_meas = np.zeros((M, 3, 3)) if R_meas is None else np.ascontiguousarray(R_meas, dtype=float)
    if R_meas.shape != (M, 3, 3):
        raise ValueError(f"R_meas: expected shape ({M}, 3, 3), got {R_meas.shape}")
    out = np.empty((P, 2))
    _residual_kernel(
        u0, b0, R_h0, _prismatic(prismatic, n), np.cos(q), np.sin(q), q, p_meas, R_meas, use_rot, out
    )
    return out


def forward(robot: ZRPRobot, q: ArrayLike) -> tuple[Array, Array]:
    """Hand orientation and position of ``robot`` at joint values ``q``.

    q (n,) gives R (3, 3) and p (3,); q (M, n) gives R (M, 3, 3) and p (M, 3); metres.

    >>> from zrp_ga import robots
    >>> R, p = forward(robots.get("puma560"), np.zeros(6))
    >>> np.round(p, 5)
    array([ 0.4521 , -0.15005,  1.10363])
    """
    q = check_q(q, robot.n)
    R, p = forward_batch(robot.u0[None], robot.b0[None], robot.R_h0, q, robot.prismatic)
    if q.ndim == 1:
        return R[0, 0], p[0, 0]
    return R[0], p[0]
