"""Forward kinematics of the ZRP model, Eq. (1-5, 14) of the ZRP calibration paper.

    R_i = R_{i-1} R(q_i, u0_i),   R_h = R_n R_h0,
    p   = sum_{i=1}^{n+1} R_{i-1} b0_i + sum_{prismatic i} q_i R_{i-1} u0_i

is evaluated from the tail, ``p = b~0_1 + R(q_1)(b~0_2 + R(q_2)(... + R(q_n) b0_{n+1}))`` with
``b~0_i = b0_i + q_i u0_i`` for a prismatic joint, so that each joint rotates four vectors (the
position and the three columns of ``R_h0``) by Rodrigues' formula
``R(q, u) v = cos q v + sin q (u x v) + (1 - cos q)(u . v) u`` instead of multiplying
matrices. The loops are compiled with numba: a whole population of parameter sets (P, ...)
over all poses (M, n) is one call, and ``cos q``, ``sin q`` of a pose are computed once for
the whole population. The population is the innermost axis of the compiled loops, so each
joint's update runs over all parameter sets with the same ``cos q``, ``sin q`` and compiles to
SIMD code. numba because no numpy formulation of the many tiny 3-vector updates came near
(1.1 M pose evaluations per second with numpy, 9 M with one compiled loop per parameter set and
pose, 34 M with the population innermost and no branch, in trials on the machine of the README; see
experiments/bench_kinematics.py).
"""

from __future__ import annotations

import numpy as np
from zrp_ga._numba import jit
from numpy.typing import ArrayLike, NDArray

from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


@jit
def _chain(U, B, H, c, s, t, X):  # pragma: no cover - compiled
    """All P parameter sets at one pose, in place: X (12, P), rows 0-2 the position p, rows
    3 + 3j .. 5 + 3j column j of R_h. U (n, 3, P), B (n+1, 3, P), H (3, 3, P): the population
    is the innermost axis, so each loop below runs over it with the pose's numbers fixed and
    compiles to SIMD code. Per joint: c, s = cos q, sin q (1, 0 for a prismatic joint, so that
    its rotation is exactly the identity) and t = q for a prismatic joint, else 0. No branch:
    one in the joint loop cost a factor 3 (the loops stopped vectorising)."""
    n, P = U.shape[0], U.shape[2]
    for p in range(P):
        for k in range(3):
            X[k, p] = B[n, k, p]
            for j in range(3):
                X[3 + 3 * j + k, p] = H[k, j, p]
    for i in range(n - 1, -1, -1):
        Ux, Uy, Uz = U[i, 0], U[i, 1], U[i, 2]
        ci, si = c[i], s[i]
        vi = 1.0 - ci
        for v in range(4):
            Xx, Xy, Xz = X[3 * v], X[3 * v + 1], X[3 * v + 2]
            for p in range(P):
                ux, uy, uz = Ux[p], Uy[p], Uz[p]
                x, y, z = Xx[p], Xy[p], Xz[p]
                d = (ux * x + uy * y + uz * z) * vi
                Xx[p] = ci * x + si * (uy * z - uz * y) + d * ux
                Xy[p] = ci * y + si * (uz * x - ux * z) + d * uy
                Xz[p] = ci * z + si * (ux * y - uy * x) + d * uz
        ti = t[i]
        for k in range(3):
            Bk, Uk, Xk = B[i, k], U[i, k], X[k]
            for p in range(P):
                Xk[p] += Bk[p] + ti * Uk[p]


@jit
def _forward_kernel(U, B, H, c, s, t, R_out, p_out):  # pragma: no cover
    X = np.empty((12, U.shape[2]))
    for m in range(c.shape[0]):
        _chain(U, B, H, c[m], s[m], t[m], X)
        for p in range(U.shape[2]):
            for k in range(3):
                p_out[p, m, k] = X[k, p]
                for j in range(3):
                    R_out[p, m, k, j] = X[3 + 3 * j + k, p]


@jit
def _residual_kernel(U, B, H, c, s, t, p_meas, wp, R_meas, use_rot, out):  # pragma: no cover
    """out (2, P): sums over poses of |dr|^2 and |wp * dp|^2 (wp (M, 3): position weights)."""
    P = U.shape[2]
    X = np.empty((12, P))
    out[:, :] = 0.0
    for m in range(c.shape[0]):
        _chain(U, B, H, c[m], s[m], t[m], X)
        for p in range(P):
            ex = (p_meas[m, 0] - X[0, p]) * wp[m, 0]
            ey = (p_meas[m, 1] - X[1, p]) * wp[m, 1]
            ez = (p_meas[m, 2] - X[2, p]) * wp[m, 2]
            out[1, p] += ex * ex + ey * ey + ez * ez
        if use_rot:
            # W = R_meas R^T, R[b, k] = X[3 + 3k + b]; dr = vee((W - W^T) / 2)
            Rm = R_meas[m]
            for p in range(P):
                w21 = Rm[2, 0] * X[4, p] + Rm[2, 1] * X[7, p] + Rm[2, 2] * X[10, p]
                w12 = Rm[1, 0] * X[5, p] + Rm[1, 1] * X[8, p] + Rm[1, 2] * X[11, p]
                w02 = Rm[0, 0] * X[5, p] + Rm[0, 1] * X[8, p] + Rm[0, 2] * X[11, p]
                w20 = Rm[2, 0] * X[3, p] + Rm[2, 1] * X[6, p] + Rm[2, 2] * X[9, p]
                w10 = Rm[1, 0] * X[3, p] + Rm[1, 1] * X[6, p] + Rm[1, 2] * X[9, p]
                w01 = Rm[0, 0] * X[4, p] + Rm[0, 1] * X[7, p] + Rm[0, 2] * X[10, p]
                dx = 0.5 * (w21 - w12)
                dy = 0.5 * (w02 - w20)
                dz = 0.5 * (w10 - w01)
                out[0, p] += dx * dx + dy * dy + dz * dz


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
    """Checked parameters in the kernels' layout, population last: (n, 3, P), (n+1, 3, P), (3, 3, P)."""
    u0 = np.asarray(u0, dtype=float)
    b0 = np.asarray(b0, dtype=float)
    if u0.ndim != 3 or u0.shape[2] != 3:
        raise ValueError(f"u0: expected shape (P, n, 3), got {u0.shape}")
    P, n = u0.shape[:2]
    if b0.shape != (P, n + 1, 3):
        raise ValueError(f"b0: expected shape ({P}, {n + 1}, 3), got {b0.shape}")
    R_h0 = np.asarray(R_h0, dtype=float)
    if R_h0.shape not in ((3, 3), (P, 3, 3)):
        raise ValueError(f"R_h0: expected shape (3, 3) or ({P}, 3, 3), got {R_h0.shape}")
    H = np.ascontiguousarray(np.broadcast_to(R_h0, (P, 3, 3)).transpose(1, 2, 0))
    return np.ascontiguousarray(u0.transpose(1, 2, 0)), np.ascontiguousarray(b0.transpose(1, 2, 0)), H


def joint_terms(q: Array, prismatic: ArrayLike | None) -> tuple[Array, Array, Array]:
    """The kernels' per-pose numbers (M, n) each: cos q and sin q of the revolute joints (1 and 0
    for a prismatic one) and q of the prismatic joints (0 for a revolute one)."""
    n = q.shape[1]
    pri = np.zeros(n, dtype=bool) if prismatic is None else np.asarray(prismatic, dtype=bool)
    if pri.shape != (n,):
        raise ValueError(f"prismatic: expected shape ({n},), got {pri.shape}")
    return np.where(pri, 1.0, np.cos(q)), np.where(pri, 0.0, np.sin(q)), np.where(pri, q, 0.0)


def forward_batch(
    u0: ArrayLike, b0: ArrayLike, R_h0: ArrayLike, q: ArrayLike, prismatic: ArrayLike | None = None
) -> tuple[Array, Array]:
    """Hand poses of P parameter sets at M poses, in one compiled call.

    u0 (P, n, 3), b0 (P, n+1, 3), R_h0 (3, 3) or (P, 3, 3), q (M, n) (rad for revolute, m for
    prismatic joints), prismatic (n,) bool. Returns R (P, M, 3, 3) and p (P, M, 3), m.
    Axes need not be unit vectors: the formula is Eq. (6-8) as written.
    """
    U, B, H = _population(u0, b0, R_h0)
    n, P = U.shape[0], U.shape[2]
    q = np.atleast_2d(check_q(q, n))
    R = np.empty((P, q.shape[0], 3, 3))
    p = np.empty((P, q.shape[0], 3))
    _forward_kernel(U, B, H, *joint_terms(q, prismatic), R, p)
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
    U, B, H = _population(u0, b0, R_h0)
    n, P = U.shape[0], U.shape[2]
    q = np.atleast_2d(check_q(q, n))
    M = q.shape[0]
    p_meas = np.ascontiguousarray(p_meas, dtype=float)
    if p_meas.shape != (M, 3):
        raise ValueError(f"p_meas: expected shape ({M}, 3), got {p_meas.shape}")
    use_rot = R_meas is not None
    R_meas = np.zeros((M, 3, 3)) if R_meas is None else np.ascontiguousarray(R_meas, dtype=float)
    if R_meas.shape != (M, 3, 3):
        raise ValueError(f"R_meas: expected shape ({M}, 3, 3), got {R_meas.shape}")
    out = np.empty((2, P))
    _residual_kernel(U, B, H, *joint_terms(q, prismatic), p_meas, np.ones((M, 3)), R_meas, use_rot, out)
    return out.T


def residual_sums_unchecked(
    U: Array, B: Array, H: Array, terms: tuple[Array, Array, Array], p_meas: Array, R_meas: Array | None,
    weights: Array | None = None,
) -> Array:
    """:func:`residual_sums` for callers that hold the kernels' layout already (the GA's fitness):
    U (n, 3, P), B (n+1, 3, P), H (3, 3, P) contiguous, ``terms = joint_terms(q, prismatic)``,
    ``weights`` (M, 3) on the position errors (ones if None). No checks. Returns (2, P)."""
    out = np.empty((2, U.shape[2]))
    use_rot = R_meas is not None
    R = R_meas if use_rot else np.zeros((p_meas.shape[0], 3, 3))
    wp = np.ones(p_meas.shape) if weights is None else weights
    _residual_kernel(U, B, H, *terms, p_meas, wp, R, use_rot, out)
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
