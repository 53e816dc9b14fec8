"""Forward kinematics of the ZRP model, Eq. (1-5, 14) of the ZRP calibration paper.

    R_i = R_{i-1} R(q_i, u0_i),   R_h = R_n R_h0,
    p   = sum_{i=1}^{n+1} R_{i-1} b0_i + sum_{prismatic i} q_i R_{i-1} u0_i

:func:`forward_reference` is these lines in numpy, one pose at a time: the readable reference
and the oracle of the tests. The compiled code evaluates a whole population of parameter sets
(P, ...) over all poses (M, n) in one call: :func:`forward` and :func:`forward_batch` for the
hand poses, :func:`residual_sums` and :func:`residual_sums_unchecked` for the pose costs of a
population (the GA's fitness), which never store anything of size (P, M).

The hand poses are evaluated from the tail, ``p = b~0_1 + R(q_1)(b~0_2 + R(q_2)(... + R(q_n)
b0_{n+1}))`` with ``b~0_i = b0_i + q_i u0_i`` for a prismatic joint, so that each joint rotates
four vectors (the position and the three columns of ``R_h0``) by Rodrigues' formula
``R(q, u) v = cos q v + sin q (u x v) + (1 - cos q)(u . v) u`` instead of multiplying matrices;
``cos q``, ``sin q`` of a pose are computed once for the whole population, and the population is
the innermost axis of the compiled loops, so each joint's update compiles to SIMD code. numba
because no numpy formulation of the many tiny 3-vector updates came near (1.1 M pose
evaluations per second with numpy, 9 M with one compiled loop per parameter set and pose).
Small problems, where compiling does not pay, run the same operations in numpy
(:mod:`zrp_ga.model._numpy_kernels`, the same bits) until :func:`zrp_ga.core.compiled.call`
switches to the compiled kernels; the kernels are in :mod:`zrp_ga.model._kernels`, imported
(with numba) only then.

The pose costs have three kernels (``kernel=``, see :mod:`zrp_ga.model._kernels` and
experiments/README.md, section f, for their speeds; ranges of three runs):

- ``"rodrigues"`` (default): the arithmetic above, operation for operation: bit-identical to
  zrp_ga 0.1 and to :func:`forward_batch`, 1.3-1.4 x the speed of 0.1's kernel;
- ``"matrix"``: float64, the rotation accumulated from the base as a 3x3 matrix (594 instead of
  828 flops per 6-joint pose) with fused multiply-add: 2.2-2.5 x; costs differ from
  ``"rodrigues"`` in the last bits (relative 2e-14 to 3e-14 on the GA's costs);
- ``"float32"``: the matrix form in float32, the residuals and their sums in float64:
  3.6-4.0 x; its costs carry errors of a few 1e-7 m (or rad) per pose, enough to rank a GA
  population, not for least squares or the pseudo-inverse step near convergence.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core import compiled
from zrp_ga.model import _numpy_kernels, so3
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


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
    H = np.broadcast_to(R_h0, (P, 3, 3)).transpose(1, 2, 0)
    return _kernel_array(u0.transpose(1, 2, 0)), _kernel_array(b0.transpose(1, 2, 0)), _kernel_array(H)


def _kernel_array(a: ArrayLike, dtype: type = np.float64) -> NDArray:
    """``a`` as a C-ordered, writable array of ``dtype``, copied only if it is not one already:
    numba compiles a kernel anew for each layout and for read-only arrays (a robot's arrays,
    broadcast views), a few seconds each."""
    a = np.ascontiguousarray(a, dtype=dtype)
    return a if a.flags.writeable else a.copy()


def joint_terms(q: Array, prismatic: ArrayLike | None) -> tuple[Array, Array, Array]:
    """The kernels' per-pose numbers (M, n) each: cos q and sin q of the revolute joints (1 and 0
    for a prismatic one) and q of the prismatic joints (0 for a revolute one)."""
    n = q.shape[1]
    pri = np.zeros(n, dtype=bool) if prismatic is None else np.asarray(prismatic, dtype=bool)
    if pri.shape != (n,):
        raise ValueError(f"prismatic: expected shape ({n},), got {pri.shape}")
    return np.where(pri, 1.0, np.cos(q)), np.where(pri, 0.0, np.sin(q)), np.where(pri, q, 0.0)


def joint_terms_lanes(q: Array, dq: Array, prismatic: ArrayLike | None) -> tuple[Array, Array, Array]:
    """:func:`joint_terms` of joint values that differ per parameter set: ``q`` (M, n) plus the
    offsets ``dq`` (M, n, P) (non-geometric terms, :mod:`zrp_ga.model.terms`; revolute joints
    only, prismatic offsets must be 0): cos and sin (M, n, P), t (M, n)."""
    n = q.shape[1]
    pri = np.zeros(n, dtype=bool) if prismatic is None else np.asarray(prismatic, dtype=bool)
    a = q[:, :, None] + dq
    return (np.where(pri[None, :, None], 1.0, np.cos(a)), np.where(pri[None, :, None], 0.0, np.sin(a)),
            np.where(pri, q, 0.0))  # fmt: skip


def forward_batch(
    u0: ArrayLike, b0: ArrayLike, R_h0: ArrayLike, q: ArrayLike, prismatic: ArrayLike | None = None, dq: ArrayLike | None = None
) -> tuple[Array, Array]:
    """Hand poses of P parameter sets at M poses, in one call of a kernel (compiled, or its
    numpy twin for small problems: the same numbers).

    u0 (P, n, 3), b0 (P, n+1, 3), R_h0 (3, 3) or (P, 3, 3), q (M, n) (rad for revolute, m for
    prismatic joints), prismatic (n,) bool. Returns R (P, M, 3, 3) and p (P, M, 3), m.
    Axes need not be unit vectors: the formula is Eq. (6-8) as written. ``dq`` (M, n, P): each
    parameter set's own joint offsets (non-geometric terms), added to q.
    """
    U, B, H = _population(u0, b0, R_h0)
    n, P = U.shape[0], U.shape[2]
    q = np.atleast_2d(check_q(q, n))
    R = np.empty((P, q.shape[0], 3, 3))
    p = np.empty((P, q.shape[0], 3))
    if dq is None:
        c, s, t = (_kernel_array(a) for a in joint_terms(q, prismatic))
    else:
        dq = np.asarray(dq, dtype=float)
        if dq.shape != (q.shape[0], n, P):
            raise ValueError(f"dq: expected shape ({q.shape[0]}, {n}, {P}), got {dq.shape}")
        c, s, t = (_kernel_array(a) for a in joint_terms_lanes(q, dq, prismatic))

    def compiled_call():
        from zrp_ga.model import _kernels

        (_kernels.forward_kernel if dq is None else _kernels.forward_kernel_lanes)(U, B, H, c, s, t, R, p)

    compiled.call("forward", P * q.shape[0] * max(n, 1), compiled_call, lambda: _numpy_kernels.forward(U, B, H, c, s, t, R, p))
    return R, p


def residual_sums(
    u0: ArrayLike,
    b0: ArrayLike,
    R_h0: ArrayLike,
    q: ArrayLike,
    p_meas: ArrayLike,
    R_meas: ArrayLike | None = None,
    prismatic: ArrayLike | None = None,
    kernel: str = "rodrigues",
    threads: int | None = 1,
) -> Array:
    """Sums of squared pose errors of P parameter sets over M measured poses, (P, 2).

    Column 0: sum over poses of ``|dr|^2`` (rad^2), ``dr = vee(skew(R_meas R^T))`` (0 when
    ``R_meas`` is None: position-only data); column 1: sum of ``|p_meas - p|^2`` (m^2).
    Nothing of size (P, M) is stored, so the population's cost costs no memory traffic.
    ``kernel`` and ``threads``: see :func:`residual_sums_unchecked`.
    """
    U, B, H = _population(u0, b0, R_h0)
    n = U.shape[0]
    q = np.atleast_2d(check_q(q, n))
    M = q.shape[0]
    p_meas = np.ascontiguousarray(p_meas, dtype=float)
    if p_meas.shape != (M, 3):
        raise ValueError(f"p_meas: expected shape ({M}, 3), got {p_meas.shape}")
    if R_meas is not None:
        R_meas = np.ascontiguousarray(R_meas, dtype=float)
        if R_meas.shape != (M, 3, 3):
            raise ValueError(f"R_meas: expected shape ({M}, 3, 3), got {R_meas.shape}")
    return residual_sums_unchecked(U, B, H, joint_terms(q, prismatic), p_meas, R_meas, kernel=kernel, threads=threads).T


KERNELS = ("rodrigues", "matrix", "float32")
AUTO_THREADS_MIN_EVALS = 20_000  # threads=None: one thread below this many pose evaluations per call


def residual_sums_unchecked(
    U: Array, B: Array, H: Array, terms: tuple[Array, Array, Array], p_meas: Array, R_meas: Array | None,
    weights: Array | None = None, kernel: str = "rodrigues", threads: int | None = 1,
) -> Array:
    """:func:`residual_sums` for callers that hold the kernels' layout already (the GA's fitness):
    U (n, 3, P), B (n+1, 3, P), H (3, 3, P), ``terms = joint_terms(q, prismatic)``, p_meas (M, 3),
    R_meas (M, 3, 3) or None, ``weights`` (M, 3) on the position errors (ones if None); their
    shapes checked (:func:`check_layout`), nothing else. Returns (2, P): the sums of |dr|^2
    (rad^2) and of |weights * dp|^2 (m^2).

    ``kernel``: ``"rodrigues"`` (bit-identical to :func:`forward_batch` and to zrp_ga 0.1),
    ``"matrix"`` (float64, about twice as fast, last bits differ) or ``"float32"`` (for ranking a
    population only); see the module docstring. ``threads``: how many threads share the
    population (in chunks of ``_kernels.LANES``); None picks 2 (or the usable cores) from
    ``AUTO_THREADS_MIN_EVALS`` pose evaluations per call on, else 1. Threads pay only on a
    machine with an idle core and at least a few tenths of a millisecond of work per call; under
    a parallel sweep (``hydra/launcher=joblib``) keep 1. The result does not depend on ``threads``.
    """
    if kernel not in KERNELS:
        raise ValueError(f"kernel: unknown kernel {kernel!r}; known: {', '.join(KERNELS)}")
    U, B, H, p_meas = (_kernel_array(a) for a in (U, B, H, p_meas))
    P, M = U.shape[2], p_meas.shape[0]
    use_rot = R_meas is not None
    R = _kernel_array(R_meas) if R_meas is not None else np.zeros((M, 3, 3))
    wp = np.ones((M, 3)) if weights is None else _kernel_array(weights)
    c, s, t = (_kernel_array(a) for a in terms)
    check_layout(U, B, H, c, s, t, p_meas, wp, R)
    out = np.empty((2, P))
    if c.ndim == 3:  # joint angles per parameter set (terms): the Rodrigues form only
        args = (U, B, H, c, s, t, p_meas, wp, R, use_rot, out)
        compiled.call("residual", P * M * U.shape[0], lambda: _run_chunks("residual_rodrigues_lanes", args, P, M, threads),
                      lambda: _numpy_kernels.residual_rodrigues(*args))  # fmt: skip
    elif kernel == "rodrigues":
        args = (U, B, H, c, s, t, p_meas, wp, R, use_rot, out)
        compiled.call("residual", P * M * U.shape[0], lambda: _run_chunks("residual_rodrigues", args, P, M, threads),
                      lambda: _numpy_kernels.residual_rodrigues(*args))  # fmt: skip
    else:  # the matrix forms are compiled only (fused multiply-add has no numpy twin)
        ft = np.float32 if kernel == "float32" else np.float64
        c, s, v, t = (a.astype(ft) for a in (c, s, 1.0 - c, t))
        _run_chunks("residual_matrix", (U, B, H, c, s, v, t, p_meas, wp, R, use_rot, out), P, M, threads)
    return out


def check_layout(U: Array, B: Array, H: Array, c: Array, s: Array, t: Array, p_meas: Array, wp: Array, R: Array) -> None:
    """ValueError unless the kernels' arrays have the shapes they index: U (n, 3, P) with n >= 1,
    B (n+1, 3, P), H (3, 3, P), c, s, t (M, n), p_meas and wp (M, 3), R (M, 3, 3). The compiled
    kernels check no index (numba does not), so a wrong shape here would read or write past an
    array's end."""
    n, P = U.shape[0], U.shape[-1]
    M = c.shape[0] if c.ndim in (2, 3) else -1
    cs = (M, n) if c.ndim == 2 else (M, n, P)  # (M, n, P): each parameter set's own angles
    expected = {"U": (U, (n, 3, P)), "B": (B, (n + 1, 3, P)), "H": (H, (3, 3, P)), "c": (c, cs), "s": (s, cs),
                "t": (t, (M, n)), "p_meas": (p_meas, (M, 3)), "weights": (wp, (M, 3)), "R_meas": (R, (M, 3, 3))}  # fmt: skip
    if U.ndim != 3 or n < 1:
        raise ValueError(f"U: expected shape (n, 3, P) with n >= 1, got {U.shape}")
    for name, (a, shape) in expected.items():
        if a.shape != shape:
            raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")


def _usable_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


_POOLS: dict[int, ThreadPoolExecutor] = {}  # worker threads by pool size, made on first use
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_POOLS.clear)  # a forked child has none of the parent's threads


def _run_chunks(name: str, args: tuple, P: int, M: int, threads: int | None) -> None:
    """The compiled kernel ``_kernels.<name>(*args, k0, k1)`` over the population's chunks, split
    between ``threads`` threads (the kernels release the GIL); the calling thread takes the first
    share."""
    from zrp_ga.model import _kernels

    fn: Callable[..., None] = getattr(_kernels, name)
    chunks = -(-P // _kernels.LANES)
    if threads is None:
        threads = _usable_cores() if P * M >= AUTO_THREADS_MIN_EVALS else 1
    threads = max(1, min(int(threads), chunks))
    if threads == 1:
        fn(*args, 0, chunks)
        return
    if threads not in _POOLS:
        _POOLS[threads] = ThreadPoolExecutor(threads - 1, thread_name_prefix="zrp_ga-kernel")
    bounds = [chunks * j // threads for j in range(threads + 1)]
    futures = [_POOLS[threads].submit(fn, *args, bounds[j], bounds[j + 1]) for j in range(1, threads)]
    fn(*args, bounds[0], bounds[1])
    for f in futures:
        f.result()


def forward_reference(robot: ZRPRobot, q: ArrayLike) -> tuple[Array, Array]:
    """Eq. (1-5, 14) as written, in numpy: R_h (3, 3) and p (3,), m, at joint values q (n,)
    (or (M, n), giving (M, 3, 3) and (M, 3)). The readable reference of the compiled kernels.

    >>> from zrp_ga.io import presets
    >>> R, p = forward_reference(presets.get("puma560"), np.zeros(6))
    >>> np.round(p, 5)
    array([ 0.4521 , -0.15005,  1.10363])
    """
    q = check_q(q, robot.n)
    if q.ndim == 2:
        poses = [forward_reference(robot, q_m) for q_m in q]
        return np.array([R for R, _ in poses]), np.array([p for _, p in poses])
    R, p = np.eye(3), np.zeros(3)  # R_0 = I
    for i in range(robot.n):
        p = p + R @ robot.b0[i]  # b_i = R_{i-1} b0_i
        if robot.prismatic[i]:
            p = p + q[i] * (R @ robot.u0[i])  # q_i u_i, u_i = R_{i-1} u0_i
        else:
            R = R @ so3.rodrigues(q[i], robot.u0[i])  # R_i = R_{i-1} R(q_i, u0_i)
    return R @ robot.R_h0, p + R @ robot.b0[robot.n]  # R_h = R_n R_h0; b_{n+1} = R_n b0_{n+1}


def forward(robot: ZRPRobot, q: ArrayLike) -> tuple[Array, Array]:
    """Hand orientation and position of ``robot`` at joint values ``q`` (the full model: a robot
    carrying non-geometric terms turns its joints to :func:`zrp_ga.model.terms.effective`).

    q (n,) gives R (3, 3) and p (3,); q (M, n) gives R (M, 3, 3) and p (M, 3); metres.

    >>> from zrp_ga.io import presets
    >>> R, p = forward(presets.get("puma560"), np.zeros(6))
    >>> np.round(p, 5)
    array([ 0.4521 , -0.15005,  1.10363])
    """
    q = check_q(q, robot.n)
    if robot.terms is not None:  # the joint values the arm takes (compliance, harmonics)
        from zrp_ga.model import terms

        q = terms.effective(robot, q)
    R, p = forward_batch(robot.u0[None], robot.b0[None], robot.R_h0, q, robot.prismatic)
    if q.ndim == 1:
        return R[0, 0], p[0, 0]
    return R[0], p[0]
