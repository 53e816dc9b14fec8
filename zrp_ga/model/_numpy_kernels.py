"""The compiled kernels of :mod:`zrp_ga.model._kernels` in numpy, operation for operation, for
problems too small to pay for compiling (:func:`zrp_ga.core.compiled.call` chooses).

Every number is computed by the same IEEE operations, in the same order, as in the compiled
kernel it stands for (numba compiles those without ``fastmath``: no fused multiply-add, no
reordering), only vectorised over the poses and the population instead of looped: the results
are bit for bit those of the compiled kernels (tests/test_kernels.py checks it on random arms,
prismatic joints and NaN genes included). Sums over poses are running sums in pose order
(``np.cumsum``, never ``np.sum``'s pairwise order). Written by hand rather than with
``np.matmul`` or ``np.einsum`` because those add in another order (or fused).

Layouts as in :mod:`zrp_ga.model._kernels`: U (n, 3, P), B (n+1, 3, P), H (3, 3, P); per pose
and joint c = cos q, s = sin q (1, 0 for a prismatic joint) and t = q for a prismatic joint
(else 0), (M, n) each. The state of the poses, X (4, 3, M, P): ``X[0]`` the positions p,
``X[1 + j]`` column j of R_h (the compiled kernels' rows ``3v + k`` are ``X[v, k]``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def chain(U: Array, B: Array, H: Array, c: Array, s: Array, t: Array) -> Array:
    """X (4, 3, M, P) of every pose and parameter set from the tail, Eq. (1-5, 14): each joint
    rotates the four vectors by Rodrigues' formula and adds its body vector (129 flops per joint,
    as ``_kernels._chain_rodrigues`` and ``_kernels._forward_chain``). c, s (M, n), or (M, n, P)
    when every parameter set turns its joints by its own angles (the ``_lanes`` kernels: joint
    offsets of non-geometric terms, :mod:`zrp_ga.model.terms`)."""
    n, P, M = U.shape[0], U.shape[2], c.shape[0]
    X = np.empty((4, 3, M, P))
    X[0] = B[n][:, None, :]
    X[1:] = np.swapaxes(H, 0, 1)[:, :, None, :]  # X[1 + j, k] = R_h0[k, j]
    for i in range(n - 1, -1, -1):
        ti = t[:, i, None]  # (M, 1)
        if c.ndim == 3:  # per parameter set (joint offsets of terms): (M, P)
            ci, si = c[:, i], s[:, i]
        else:
            ci, si = c[:, i, None], s[:, i, None]  # (M, 1)
        vi = 1.0 - ci
        ux, uy, uz = U[i, 0], U[i, 1], U[i, 2]  # (P,)
        x, y, z = X[:, 0], X[:, 1], X[:, 2]  # (4, M, P)
        d = (ux * x + uy * y + uz * z) * vi
        X = np.stack([ci * x + si * (uy * z - uz * y) + d * ux,
                      ci * y + si * (uz * x - ux * z) + d * uy,
                      ci * z + si * (ux * y - uy * x) + d * uz], axis=1)  # fmt: skip
        X[0] = X[0] + (B[i][:, None, :] + ti[None] * U[i][:, None, :])
    return X


def forward(U: Array, B: Array, H: Array, c: Array, s: Array, t: Array, R_out: Array, p_out: Array) -> None:
    """``_kernels.forward_kernel``: hand orientations R_out (P, M, 3, 3) and positions p_out (P, M, 3)."""
    X = chain(U, B, H, c, s, t)
    p_out[:] = np.transpose(X[0], (2, 1, 0))
    R_out[:] = np.transpose(X[1:], (3, 2, 1, 0))  # R_out[p, m, k, j] = X[1 + j, k, m, p]


def _running_sum(a: Array) -> Array:
    """Sum over the poses (axis 0) in pose order, as the compiled loop adds them; 0 for no pose."""
    return np.cumsum(a, axis=0)[-1] if len(a) else np.zeros(a.shape[1:])


def residual_rodrigues(U, B, H, c, s, t, p_meas, wp, R_meas, use_rot, out) -> None:
    """``_kernels.residual_rodrigues`` for the whole population: out (2, P), the sums over the
    M poses of |dr|^2 (rad^2) and |wp * dp|^2 (m^2)."""
    X = chain(U, B, H, c, s, t)
    e = (p_meas.T[:, :, None] - X[0]) * wp.T[:, :, None]  # (3, M, P)
    out[1] = _running_sum(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    if not use_rot:
        out[0] = 0.0
        return
    Rm = R_meas[:, :, :, None]  # (M, 3, 3, 1)

    def w(a, b):  # (R_meas R_h^T)[a, b] = sum_k R_meas[a, k] R_h[b, k], R_h[b, k] = X[1 + k, b]
        return Rm[:, a, 0] * X[1, b] + Rm[:, a, 1] * X[2, b] + Rm[:, a, 2] * X[3, b]

    dx = 0.5 * (w(2, 1) - w(1, 2))
    dy = 0.5 * (w(0, 2) - w(2, 0))
    dz = 0.5 * (w(1, 0) - w(0, 1))
    out[0] = _running_sum(dx * dx + dy * dy + dz * dz)


def _matmul(A: Array, B: Array) -> Array:
    """A @ B of (M, 3, 3) stacks, each element summed left to right as ``_kernels._jac_matmul``."""
    return A[:, :, 0, None] * B[:, None, 0, :] + A[:, :, 1, None] * B[:, None, 1, :] + A[:, :, 2, None] * B[:, None, 2, :]


def _rotation(u: Array, c: Array, s: Array, prismatic: bool) -> Array:
    """``_kernels._jac_rotation`` for the M poses of one joint: (M, 3, 3)."""
    out = np.empty((len(c), 3, 3))
    if prismatic:
        out[:] = np.eye(3)
        return out
    v = 1.0 - c
    for a in range(3):
        for b in range(3):
            out[:, a, b] = v * u[a] * u[b] + (c if a == b else 0.0)
    out[:, 0, 1] -= s * u[2]
    out[:, 0, 2] += s * u[1]
    out[:, 1, 0] += s * u[2]
    out[:, 1, 2] -= s * u[0]
    out[:, 2, 0] -= s * u[1]
    out[:, 2, 1] += s * u[0]
    return out


def _rotation_derivative(u: Array, c: Array, s: Array, k: int) -> Array:
    """``_kernels._jac_rotation_derivative`` for the M poses of one joint: dR/du_k (M, 3, 3)."""
    v = 1.0 - c
    out = np.zeros((len(c), 3, 3))
    for b in range(3):
        out[:, k, b] += v * u[b]
        out[:, b, k] += v * u[b]
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    out[:, k2, k1] += s
    out[:, k1, k2] -= s
    return out


def _tail_sums(u0: Array, b0: Array, prism, q: Array, Rot: Array) -> Array:
    """E (n, M, 3): E_{n-1} = b0_n, E_i = b~0_{i+1} + R(q_{i+1}) E_{i+1}, as ``_kernels.jacobian_kernel``."""
    M, n = q.shape
    E = np.empty((n, M, 3))
    E[n - 1] = b0[n]
    for i in range(n - 2, -1, -1):
        t = q[:, i + 1] if prism[i + 1] else np.zeros(M)
        for a in range(3):
            e = b0[i + 1, a] + t * u0[i + 1, a]
            for b in range(3):
                e = e + Rot[i + 1, :, a, b] * E[i + 1, :, b]
            E[i, :, a] = e
    return E


def jacobian(u0: Array, b0: Array, prism, c: Array, s: Array, q: Array, J: Array, Rn: Array) -> None:
    """``_kernels.jacobian_kernel`` vectorised over the poses: columns 0 .. 6n-1 of J (M, 6, K)
    (zeros on entry) and R_n (M, 3, 3); c, s = cos q, sin q (M, n)."""
    M, n = q.shape
    Rot = np.stack([_rotation(u0[i], c[:, i], s[:, i], prism[i]) for i in range(n)])  # (n, M, 3, 3)
    Rp = np.empty((n + 1, M, 3, 3))
    Rp[0] = np.eye(3)
    for i in range(n):
        Rp[i + 1] = _matmul(Rp[i], Rot[i])
    E = _tail_sums(u0, b0, prism, q, Rot)
    for i in range(n):
        for k in range(3):
            col = 3 * i + k
            if prism[i]:
                J[:, 3:6, col] = q[:, i, None] * Rp[i, :, :, k]
                continue
            A = _matmul(Rp[i], _rotation_derivative(u0[i], c[:, i], s[:, i], k))  # R_{i-1} dR_k
            J[:, 3:6, col] = A[:, :, 0] * E[i, :, None, 0] + A[:, :, 1] * E[i, :, None, 1] + A[:, :, 2] * E[i, :, None, 2]
            R1 = Rp[i + 1]  # W = A (R_{i-1} R_i)^T
            W = A[:, :, None, 0] * R1[:, None, :, 0] + A[:, :, None, 1] * R1[:, None, :, 1] + A[:, :, None, 2] * R1[:, None, :, 2]
            J[:, 0, col] = 0.5 * (W[:, 2, 1] - W[:, 1, 2])
            J[:, 1, col] = 0.5 * (W[:, 0, 2] - W[:, 2, 0])
            J[:, 2, col] = 0.5 * (W[:, 1, 0] - W[:, 0, 1])
        J[:, 3:6, 3 * n + 3 * i : 3 * n + 3 * i + 3] = Rp[i + 1]
    Rn[:] = Rp[n]
