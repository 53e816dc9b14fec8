"""The compiled kernels behind :mod:`zrp_ga.model.kinematics` and :mod:`zrp_ga.model.error_model`:
the squared pose errors of a population summed over the poses (:func:`residual_rodrigues`,
:func:`residual_matrix`), the hand poses of a population (:func:`forward_kernel`) and the pose
Jacobians (:func:`jacobian_kernel`). This module imports numba and is imported only when a
compiled kernel is called (:func:`zrp_ga.core.compiled.call`); :mod:`zrp_ga.model._numpy_kernels`
computes the same numbers without compiling (all but :func:`residual_matrix`).

Every kernel indexes only within the shapes stated in its docstring; the callers check them
(:func:`zrp_ga.model.kinematics.check_layout`, :func:`zrp_ga.model.error_model.jacobian_arrays`).

Layout: the population is the last axis, U (n, 3, P), B (n+1, 3, P), H (3, 3, P) for the axes,
body vectors and hand orientations of P parameter sets; per pose and joint the numbers
c = cos q, s = sin q (1, 0 for a prismatic joint, so that its rotation is exactly the
identity), v = 1 - c and t = q for a prismatic joint, else 0 (:func:`kinematics.joint_terms`).

The population is cut into chunks of ``LANES`` parameter sets. Each chunk is copied ("packed")
into local buffers whose rows are ``LANES`` long, a compile-time constant, and every loop over
the lanes of a chunk is the innermost loop. With the row length known, LLVM proves the rows of a
buffer apart and vectorises those loops (SIMD over parameter sets, the pose's numbers fixed);
with the row length read at run time it needed more run-time alias checks than it allows and left
the loops scalar. A chunk's buffers (about 16 kB for a 6-joint arm in float64) stay in L1 across
all poses. Two more things keep the loops vectorised: the helpers are inlined into one function
(``inline="always"``), and no loop counts down (``range(n - 1, -1, -1)`` around the lane loop
left it scalar).

The state of one pose, X (12, LANES): rows 0-2 the position p, row ``3 + 3j + k`` the element
``R_h[k, j]``. Two ways to fill it, Eq. (1-5, 14) both:

- ``rodrigues``, from the tail: ``p = b~0_1 + R(q_1)(b~0_2 + ... R(q_n) b0_{n+1})`` and
  ``R_h = R(q_1)(... R(q_n) R_h0)``, rotating four vectors per joint by Rodrigues' vector formula.
  The same operations in the same order as the kernel of zrp_ga 0.1: bit-identical results.
  129 flops per joint.
- ``matrix``, from the base: ``p += R_{i-1} b~0_i``, ``R_i = R_{i-1} R(q_i, u0_i)``, then
  ``p += R_n b0_{n+1}``, ``R_h = R_n R_h0``. 21 flops for R(q_i, u0_i), 45 for the product,
  24 for the position: 90 per joint, the first joint 27 (R_0 = I), 63 at the end. Compiled with
  fused multiply-add (``fastmath={"contract"}``): results differ from ``rodrigues`` in the last
  bits. Its arithmetic type is that of the joint terms passed in: float64, or float32 for the
  ranking kernel (the pose residuals and their sums are float64 in both).

The residual of a pose (54 flops) is the same code for both: ``|dr|^2`` with
``dr = vee((W - W^T) / 2)``, ``W = R_meas R_h^T``, and ``|wp * (p_meas - p)|^2``.
"""

from __future__ import annotations

import numpy as np

from zrp_ga.core.compiled import jit

LANES = 32  # parameter sets per chunk: the row length of the packed buffers


@jit(inline="always")
def _pack(A, p0, w, Ab):  # pragma: no cover - compiled
    """Lanes p0 .. p0 + w of A (rows, P) into the chunk buffer Ab (rows, LANES)."""
    for r in range(A.shape[0]):
        row, packed = A[r, p0 : p0 + w], Ab[r]
        for p in range(w):
            packed[p] = row[p]


@jit(inline="always")
def _chunk(U, B, H, p0, w, Ub, Bb, Hb):  # pragma: no cover - compiled
    """Pack lanes p0 .. p0 + w of U, B, H (C order) into Ub (n, 3, LANES), Bb (n+1, 3, LANES),
    Hb (3, 3, LANES)."""
    n, P = U.shape[0], U.shape[2]
    _pack(U.reshape(3 * n, P), p0, w, Ub.reshape(3 * n, LANES))
    _pack(B.reshape(3 * n + 3, P), p0, w, Bb.reshape(3 * n + 3, LANES))
    _pack(H.reshape(9, P), p0, w, Hb.reshape(9, LANES))


@jit(inline="always")
def _rotate(c, s, v, ux, uy, uz, x, y, z):  # pragma: no cover - compiled
    """R(q, u) (x, y, z) = c x + s (u x x) + v (u . x) u, Rodrigues' formula on a vector (30 flops)."""
    d = (ux * x + uy * y + uz * z) * v
    return (c * x + s * (uy * z - uz * y) + d * ux,
            c * y + s * (uz * x - ux * z) + d * uy,
            c * z + s * (ux * y - uy * x) + d * uz)


@jit(inline="always")
def _chain_rodrigues(Ub, Bb, Hb, c, s, t, X, w):  # pragma: no cover - compiled
    """X of one pose from the tail, float64; c, s, t (n,) of the pose. 129 flops per joint."""
    n = Ub.shape[0]
    for p in range(w):
        for k in range(3):
            X[k, p] = Bb[n, k, p]
            for j in range(3):
                X[3 + 3 * j + k, p] = Hb[k, j, p]
    for j in range(n):
        i = n - 1 - j  # not range(n - 1, -1, -1): the lane loop inside it stayed scalar
        ci, si, ti = c[i], s[i], t[i]
        vi = 1.0 - ci
        u, b = Ub[i], Bb[i]
        for p in range(w):
            ux, uy, uz = u[0, p], u[1, p], u[2, p]
            X[0, p], X[1, p], X[2, p] = _rotate(ci, si, vi, ux, uy, uz, X[0, p], X[1, p], X[2, p])
            X[3, p], X[4, p], X[5, p] = _rotate(ci, si, vi, ux, uy, uz, X[3, p], X[4, p], X[5, p])
            X[6, p], X[7, p], X[8, p] = _rotate(ci, si, vi, ux, uy, uz, X[6, p], X[7, p], X[8, p])
            X[9, p], X[10, p], X[11, p] = _rotate(ci, si, vi, ux, uy, uz, X[9, p], X[10, p], X[11, p])
            X[0, p] += b[0, p] + ti * ux
            X[1, p] += b[1, p] + ti * uy
            X[2, p] += b[2, p] + ti * uz


@jit(inline="always")
def _rotation(c, s, v, ux, uy, uz):  # pragma: no cover - compiled
    """R(q, u) = v u u^T + c I + s [u]x, Eq. (6-8) (diagonal ``v (u_k^2 - 1) + 1 = v u_k^2 + c``); 21 flops."""
    vx, vy, vz = v * ux, v * uy, v * uz
    sx, sy, sz = s * ux, s * uy, s * uz
    xy, xz, yz = vx * uy, vx * uz, vy * uz
    return (vx * ux + c, xy - sz, xz + sy,
            xy + sz, vy * uy + c, yz - sx,
            xz - sy, yz + sx, vz * uz + c)


@jit(inline="always")
def _chain_matrix(Ub, Bb, Hb, c, s, v, t, X, w):  # pragma: no cover - compiled
    """X of one pose from the base; c, s, v, t (n,) of the pose, in the arithmetic type. While
    accumulating, row ``3 + 3a + b`` holds R_{i}[a, b]; the last step writes R_h in X's layout."""
    n = Ub.shape[0]
    u, b = Ub[0], Bb[0]
    c0, s0, v0, t0 = c[0], s[0], v[0], t[0]
    for p in range(w):  # R_1 = R(q_1, u0_1), p = b~0_1: 27 flops
        ux, uy, uz = u[0, p], u[1, p], u[2, p]
        X[0, p], X[1, p], X[2, p] = b[0, p] + t0 * ux, b[1, p] + t0 * uy, b[2, p] + t0 * uz
        (X[3, p], X[4, p], X[5, p], X[6, p], X[7, p], X[8, p],
         X[9, p], X[10, p], X[11, p]) = _rotation(c0, s0, v0, ux, uy, uz)
    for i in range(1, n):  # 90 flops per joint
        ci, si, vi, ti = c[i], s[i], v[i], t[i]
        u, b = Ub[i], Bb[i]
        for p in range(w):
            ux, uy, uz = u[0, p], u[1, p], u[2, p]
            bx, by, bz = b[0, p] + ti * ux, b[1, p] + ti * uy, b[2, p] + ti * uz
            q00, q01, q02, q10, q11, q12, q20, q21, q22 = _rotation(ci, si, vi, ux, uy, uz)
            for a in range(3):
                r0, r1, r2 = X[3 + 3 * a, p], X[4 + 3 * a, p], X[5 + 3 * a, p]
                X[a, p] += r0 * bx + r1 * by + r2 * bz
                X[3 + 3 * a, p] = r0 * q00 + r1 * q10 + r2 * q20
                X[4 + 3 * a, p] = r0 * q01 + r1 * q11 + r2 * q21
                X[5 + 3 * a, p] = r0 * q02 + r1 * q12 + r2 * q22
    b = Bb[n]
    for p in range(w):  # p += R_n b0_{n+1}, R_h = R_n R_h0: 63 flops
        r00, r01, r02 = X[3, p], X[4, p], X[5, p]
        r10, r11, r12 = X[6, p], X[7, p], X[8, p]
        r20, r21, r22 = X[9, p], X[10, p], X[11, p]
        bx, by, bz = b[0, p], b[1, p], b[2, p]
        X[0, p] += r00 * bx + r01 * by + r02 * bz
        X[1, p] += r10 * bx + r11 * by + r12 * bz
        X[2, p] += r20 * bx + r21 * by + r22 * bz
        for j in range(3):  # column j of R_h = R_n (column j of R_h0), into rows 3 + 3j .. 5 + 3j
            h0, h1, h2 = Hb[0, j, p], Hb[1, j, p], Hb[2, j, p]
            X[3 + 3 * j, p] = r00 * h0 + r01 * h1 + r02 * h2
            X[4 + 3 * j, p] = r10 * h0 + r11 * h1 + r12 * h2
            X[5 + 3 * j, p] = r20 * h0 + r21 * h1 + r22 * h2


@jit(inline="always")
def _accumulate_residual(X, pm, wp, Rm, use_rot, acc, w):  # pragma: no cover - compiled
    """acc[0] += |dr|^2, acc[1] += |wp * (pm - p)|^2 of one pose (float64 whatever X's type); 54 flops."""
    for p in range(w):
        ex = (pm[0] - X[0, p]) * wp[0]
        ey = (pm[1] - X[1, p]) * wp[1]
        ez = (pm[2] - X[2, p]) * wp[2]
        acc[1, p] += ex * ex + ey * ey + ez * ez
    if use_rot:
        # W = R_meas R_h^T, R_h[b, k] = X[3 + 3k + b]; dr = vee((W - W^T) / 2)
        for p in range(w):
            w21 = Rm[2, 0] * X[4, p] + Rm[2, 1] * X[7, p] + Rm[2, 2] * X[10, p]
            w12 = Rm[1, 0] * X[5, p] + Rm[1, 1] * X[8, p] + Rm[1, 2] * X[11, p]
            w02 = Rm[0, 0] * X[5, p] + Rm[0, 1] * X[8, p] + Rm[0, 2] * X[11, p]
            w20 = Rm[2, 0] * X[3, p] + Rm[2, 1] * X[6, p] + Rm[2, 2] * X[9, p]
            w10 = Rm[1, 0] * X[3, p] + Rm[1, 1] * X[6, p] + Rm[1, 2] * X[9, p]
            w01 = Rm[0, 0] * X[4, p] + Rm[0, 1] * X[7, p] + Rm[0, 2] * X[10, p]
            dx = 0.5 * (w21 - w12)
            dy = 0.5 * (w02 - w20)
            dz = 0.5 * (w10 - w01)
            acc[0, p] += dx * dx + dy * dy + dz * dz


@jit(nogil=True)
def residual_rodrigues(U, B, H, c, s, t, p_meas, wp, R_meas, use_rot, out, k0, k1):  # pragma: no cover
    """out (2, P) for the lanes of chunks k0 .. k1 - 1: sums over the M poses of |dr|^2 (rad^2)
    and |wp * dp|^2 (m^2). c, s, t (M, n) float64, p_meas (M, 3), wp (M, 3), R_meas (M, 3, 3)."""
    n, P = U.shape[0], U.shape[2]
    Ub, Bb, Hb = np.empty((n, 3, LANES)), np.empty((n + 1, 3, LANES)), np.empty((3, 3, LANES))
    X, acc = np.empty((12, LANES)), np.empty((2, LANES))
    for k in range(k0, k1):
        p0 = k * LANES
        w = min(P - p0, LANES)
        _chunk(U, B, H, p0, w, Ub, Bb, Hb)
        for p in range(w):
            acc[0, p] = 0.0
            acc[1, p] = 0.0
        for m in range(c.shape[0]):
            _chain_rodrigues(Ub, Bb, Hb, c[m], s[m], t[m], X, w)
            _accumulate_residual(X, p_meas[m], wp[m], R_meas[m], use_rot, acc, w)
        out0, out1 = out[0, p0 : p0 + w], out[1, p0 : p0 + w]
        for p in range(w):
            out0[p], out1[p] = acc[0, p], acc[1, p]


@jit(nogil=True, fastmath={"contract"})
def residual_matrix(U, B, H, c, s, v, t, p_meas, wp, R_meas, use_rot, out, k0, k1):  # pragma: no cover
    """:func:`residual_rodrigues` by the matrix form, in the arithmetic type of c, s, v, t (M, n)
    (float32 or float64); the residuals and sums are float64."""
    n, P = U.shape[0], U.shape[2]
    ft = c.dtype  # the arithmetic type
    Ub, Bb, Hb = np.empty((n, 3, LANES), ft), np.empty((n + 1, 3, LANES), ft), np.empty((3, 3, LANES), ft)
    X, acc = np.empty((12, LANES), ft), np.empty((2, LANES))
    for k in range(k0, k1):
        p0 = k * LANES
        w = min(P - p0, LANES)
        _chunk(U, B, H, p0, w, Ub, Bb, Hb)
        for p in range(w):
            acc[0, p] = 0.0
            acc[1, p] = 0.0
        for m in range(c.shape[0]):
            _chain_matrix(Ub, Bb, Hb, c[m], s[m], v[m], t[m], X, w)
            _accumulate_residual(X, p_meas[m], wp[m], R_meas[m], use_rot, acc, w)
        out0, out1 = out[0, p0 : p0 + w], out[1, p0 : p0 + w]
        for p in range(w):
            out0[p], out1[p] = acc[0, p], acc[1, p]


# --- the hand poses of a population -------------------------------------------------------------
@jit
def _forward_chain(U, B, H, c, s, t, X):  # pragma: no cover - compiled
    """All P parameter sets at one pose, in place: X (12, P), rows 0-2 the position p, rows
    3 + 3j .. 5 + 3j column j of R_h. U (n, 3, P), B (n+1, 3, P), H (3, 3, P): the population
    is the innermost axis, so each loop below runs over it with the pose's numbers fixed and
    compiles to SIMD code. c, s, t (n,) of the pose. No branch: one in the joint loop cost a
    factor 3 (the loops stopped vectorising). zrp_ga 0.1's kernel, operation for operation."""
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
def forward_kernel(U, B, H, c, s, t, R_out, p_out):  # pragma: no cover - compiled
    """Hand orientations R_out (P, M, 3, 3) and positions p_out (P, M, 3) of P parameter sets
    at M poses; c, s, t (M, n)."""
    X = np.empty((12, U.shape[2]))
    for m in range(c.shape[0]):
        _forward_chain(U, B, H, c[m], s[m], t[m], X)
        for p in range(U.shape[2]):
            for k in range(3):
                p_out[p, m, k] = X[k, p]
                for j in range(3):
                    R_out[p, m, k, j] = X[3 + 3 * j + k, p]


# --- the pose Jacobians ----------------------------------------------------------------------------
@jit
def jacobian_kernel(u0, b0, prism, c, s, q, J, Rn):  # pragma: no cover - compiled
    """Columns 0 .. 6n-1 of J (M, 6, K), K >= 6n, zeros on entry, and the hand rotation R_n
    (M, 3, 3), pose by pose: the rotations and their prefix products R_{i-1}, the tail sums E_i,
    then per joint i and axis component k the blocks of Eq. (25-27): J1 = vee(R_{i-1} dR_k R_i^T
    R_{i-1}^T), J3 = R_{i-1} dR_k E_i (q_i R_{i-1} e_k for a prismatic joint), J4 = R_i for the
    body vector after joint i. u0 (n, 3), b0 (n+1, 3), prism (n,), c, s = cos q, sin q and q
    (M, n). Loops over 3-vectors into preallocated arrays: small numpy temporaries made the
    compiled version no faster than the numpy reference."""
    M, n = q.shape
    Rot = np.empty((n, 3, 3))
    Rp = np.empty((n + 1, 3, 3))
    E = np.empty((n, 3))
    dR, A, W = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for m in range(M):
        for i in range(n):
            _jac_rotation(u0[i], c[m, i], s[m, i], prism[i], Rot[i])
        Rp[0] = np.eye(3)
        for i in range(n):
            _jac_matmul(Rp[i], Rot[i], Rp[i + 1])
        E[n - 1] = b0[n]
        for i in range(n - 2, -1, -1):
            t = q[m, i + 1] if prism[i + 1] else 0.0
            for a in range(3):
                E[i, a] = b0[i + 1, a] + t * u0[i + 1, a]
                for b in range(3):
                    E[i, a] += Rot[i + 1, a, b] * E[i + 1, b]
        for i in range(n):
            for k in range(3):
                col = 3 * i + k
                if prism[i]:
                    for a in range(3):
                        J[m, 3 + a, col] = q[m, i] * Rp[i, a, k]
                    continue
                _jac_rotation_derivative(u0[i], c[m, i], s[m, i], k, dR)
                _jac_matmul(Rp[i], dR, A)  # R_{i-1} dR_k
                for a in range(3):
                    J[m, 3 + a, col] = A[a, 0] * E[i, 0] + A[a, 1] * E[i, 1] + A[a, 2] * E[i, 2]
                    for b in range(3):  # W = A R_i^T R_{i-1}^T = A (R_{i-1} R_i)^T
                        W[a, b] = A[a, 0] * Rp[i + 1, b, 0] + A[a, 1] * Rp[i + 1, b, 1] + A[a, 2] * Rp[i + 1, b, 2]
                J[m, 0, col] = 0.5 * (W[2, 1] - W[1, 2])
                J[m, 1, col] = 0.5 * (W[0, 2] - W[2, 0])
                J[m, 2, col] = 0.5 * (W[1, 0] - W[0, 1])
            for a in range(3):
                for b in range(3):
                    J[m, 3 + a, 3 * n + 3 * i + b] = Rp[i + 1, a, b]
        Rn[m] = Rp[n]


@jit
def _jac_matmul(A, B, out):  # pragma: no cover - compiled
    for a in range(3):
        for b in range(3):
            out[a, b] = A[a, 0] * B[0, b] + A[a, 1] * B[1, b] + A[a, 2] * B[2, b]


@jit
def _jac_rotation(u, c, s, prismatic, out):  # pragma: no cover - compiled
    """Rodrigues' R(q, u) = V (u u^T - I) + S [u]x + I (Eq. 6-8) into out, c, s = cos q, sin q;
    I for a prismatic joint."""
    if prismatic:
        out[:] = np.eye(3)
        return
    v = 1.0 - c
    for a in range(3):
        for b in range(3):
            out[a, b] = v * u[a] * u[b] + (c if a == b else 0.0)
    out[0, 1] -= s * u[2]
    out[0, 2] += s * u[1]
    out[1, 0] += s * u[2]
    out[1, 2] -= s * u[0]
    out[2, 0] -= s * u[1]
    out[2, 1] += s * u[0]


@jit
def _jac_rotation_derivative(u, c, s, k, out):  # pragma: no cover - compiled
    """dR/du_k = V (e_k u^T + u e_k^T) + S [e_k]x (Eq. 9-10) into out, c, s = cos q, sin q."""
    v = 1.0 - c
    out[:] = 0.0
    for b in range(3):
        out[k, b] += v * u[b]
        out[b, k] += v * u[b]
    k1, k2 = (k + 1) % 3, (k + 2) % 3  # [e_k]x: +1 at (k2, k1), -1 at (k1, k2)
    out[k2, k1] += s
    out[k1, k2] -= s


# --- joint angles per parameter set (non-geometric terms, zrp_ga.model.terms) ----------------------
@jit(inline="always")
def _chain_rodrigues_lanes(Ub, Bb, Hb, cb, sb, t, X, w):  # pragma: no cover - compiled
    """:func:`_chain_rodrigues` with cos and sin per lane, cb, sb (n, LANES) of the pose (the
    same operations in the same order)."""
    n = Ub.shape[0]
    for p in range(w):
        for k in range(3):
            X[k, p] = Bb[n, k, p]
            for j in range(3):
                X[3 + 3 * j + k, p] = Hb[k, j, p]
    for j in range(n):
        i = n - 1 - j
        ti = t[i]
        u, b, ci_, si_ = Ub[i], Bb[i], cb[i], sb[i]
        for p in range(w):
            ci, si = ci_[p], si_[p]
            vi = 1.0 - ci
            ux, uy, uz = u[0, p], u[1, p], u[2, p]
            X[0, p], X[1, p], X[2, p] = _rotate(ci, si, vi, ux, uy, uz, X[0, p], X[1, p], X[2, p])
            X[3, p], X[4, p], X[5, p] = _rotate(ci, si, vi, ux, uy, uz, X[3, p], X[4, p], X[5, p])
            X[6, p], X[7, p], X[8, p] = _rotate(ci, si, vi, ux, uy, uz, X[6, p], X[7, p], X[8, p])
            X[9, p], X[10, p], X[11, p] = _rotate(ci, si, vi, ux, uy, uz, X[9, p], X[10, p], X[11, p])
            X[0, p] += b[0, p] + ti * ux
            X[1, p] += b[1, p] + ti * uy
            X[2, p] += b[2, p] + ti * uz


@jit(nogil=True)
def residual_rodrigues_lanes(U, B, H, c, s, t, p_meas, wp, R_meas, use_rot, out, k0, k1):  # pragma: no cover
    """:func:`residual_rodrigues` with c, s (M, n, P): each parameter set's own joint angles; t (M, n)."""
    n, P = U.shape[0], U.shape[2]
    Ub, Bb, Hb = np.empty((n, 3, LANES)), np.empty((n + 1, 3, LANES)), np.empty((3, 3, LANES))
    cb, sb = np.empty((n, LANES)), np.empty((n, LANES))
    X, acc = np.empty((12, LANES)), np.empty((2, LANES))
    for k in range(k0, k1):
        p0 = k * LANES
        w = min(P - p0, LANES)
        _chunk(U, B, H, p0, w, Ub, Bb, Hb)
        for p in range(w):
            acc[0, p] = 0.0
            acc[1, p] = 0.0
        for m in range(c.shape[0]):
            _pack(c[m], p0, w, cb)
            _pack(s[m], p0, w, sb)
            _chain_rodrigues_lanes(Ub, Bb, Hb, cb, sb, t[m], X, w)
            _accumulate_residual(X, p_meas[m], wp[m], R_meas[m], use_rot, acc, w)
        out0, out1 = out[0, p0 : p0 + w], out[1, p0 : p0 + w]
        for p in range(w):
            out0[p], out1[p] = acc[0, p], acc[1, p]


@jit
def forward_kernel_lanes(U, B, H, c, s, t, R_out, p_out):  # pragma: no cover - compiled
    """:func:`forward_kernel` with c, s (M, n, P): each parameter set's own joint angles."""
    n, P = U.shape[0], U.shape[2]
    X = np.empty((12, P))
    for m in range(c.shape[0]):
        for p in range(P):
            for k in range(3):
                X[k, p] = B[n, k, p]
                for j in range(3):
                    X[3 + 3 * j + k, p] = H[k, j, p]
        for j in range(n):
            i = n - 1 - j
            ti = t[m, i]
            for p in range(P):
                ci, si = c[m, i, p], s[m, i, p]
                vi = 1.0 - ci
                ux, uy, uz = U[i, 0, p], U[i, 1, p], U[i, 2, p]
                for v in range(4):
                    X[3 * v, p], X[3 * v + 1, p], X[3 * v + 2, p] = _rotate(ci, si, vi, ux, uy, uz, X[3 * v, p], X[3 * v + 1, p],
                                                                            X[3 * v + 2, p])  # fmt: skip
                X[0, p] += B[i, 0, p] + ti * ux
                X[1, p] += B[i, 1, p] + ti * uy
                X[2, p] += B[i, 2, p] + ti * uz
        for p in range(P):
            for k in range(3):
                p_out[p, m, k] = X[k, p]
                for j in range(3):
                    R_out[p, m, k, j] = X[3 + 3 * j + k, p]
