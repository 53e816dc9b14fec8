"""The ZRP error model: pose errors, the error Jacobian (Eq. 21-27) and identifiability.

Parameter errors are ordered as in the paper, ``de = [du0_1 .. du0_n, db0_2 .. db0_{n+1}]``
(6n values); :func:`pose_jacobians` can append the base point ``db0_1`` and a small rotation
``dphi_h`` of the hand orientation (``R_h0 <- exp([dphi_h]x) R_h0``).

Identifiability (docs/model.md). Sliding the point chosen on axis i along ``u_i``
changes ``b0_i`` and ``b0_{i+1}`` by opposite amounts and leaves every pose unchanged. With
``b0_1`` fixed this gives n - 1 null directions of the stacked Jacobian of a 6R arm under
full-pose measurements, whatever the number of poses: for the PUMA 560 the rank is
36 - 5 = 31 (tests/test_error_model.py checks it over 30 random poses). Under position-only
measurements an axis that passes through the measured point can tilt unseen: the PUMA 560's
end point is its wrist centre, on axes 4, 5 and 6, so the two tilts of each of u0_4, u0_5,
u0_6 that keep unit length are lost too and the rank drops to 36 - 5 - 6 = 25 (also checked).
A prismatic joint's axis has no fixed point at all: its point can shift in any direction, two
more null directions per prismatic joint. :func:`identifiability` names all of these.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core import compiled as compiled_code
from zrp_ga.model import _numpy_kernels, so3
from zrp_ga.model.kinematics import check_q
from zrp_ga.model.layout import Layout, parameter_names, slides  # noqa: F401 (parameter_names: the Jacobian's columns, named here as before)
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


def pose_error(R_meas: ArrayLike, p_meas: ArrayLike, R: ArrayLike, p: ArrayLike, exact: bool = False) -> tuple[Array, Array]:
    """Measured minus modelled pose: ``dr`` (..., 3) rad and ``dp = p_meas - p`` (..., 3) m.

    ``dr = vee(skew(R_meas R^T))``, the first-order orientation error of Eq. (11-13); with
    ``exact=True`` the rotation vector ``log(R_meas R^T)`` instead, for errors that are not small.
    """
    W = np.asarray(R_meas, dtype=float) @ np.swapaxes(np.asarray(R, dtype=float), -1, -2)
    dr = so3.log(W) if exact else so3.vee(W)
    return dr, np.asarray(p_meas, dtype=float) - np.asarray(p, dtype=float)


def pose_jacobians(robot: ZRPRobot, q: ArrayLike, base: bool = False, hand: bool = False) -> Array:
    """Jacobians of ``[dr; dp]`` with respect to the parameter errors at M poses, (M, 6, K).

    K = 6n (+3 with ``base``, +3 with ``hand``), columns as :func:`parameter_names`.
    Blocks of Eq. (25-27), vectorised over poses (indices 0-based below):

    - J1 joint i, column k: ``vee(R_{i} R_k(q_i) R(q_i)^T R_{i}^T)`` (0 for a prismatic joint);
    - J3 joint i: ``R_{i} [R_x E_i, R_y E_i, R_z E_i]`` (``q_i R_{i}`` for a prismatic joint);
    - J4 joint i (for ``db0`` of the next point): ``R_{i+1}``;

    where ``R_i`` is the product of the first i joint rotations and ``E_i`` the tail sum
    ``E_i = b~0_{i+1} + R(q_{i+1}) E_{i+1}``, ``E_{n-1} = b0_n``.
    """
    q = np.atleast_2d(check_q(q, robot.n))
    return jacobian_arrays(robot.u0, robot.b0, robot.prismatic, q, base, hand)


def jacobian_arrays(
    u0: Array, b0: Array, prism: NDArray[np.bool_], q: Array, base: bool = False, hand: bool = False, compiled: bool = True
) -> Array:
    """:func:`pose_jacobians` on raw arrays, u0 (n, 3) not necessarily unit, b0 (n+1, 3), prism
    (n,), q (M, n); shapes checked, values not. The kernel ``jacobian_kernel`` of
    :mod:`zrp_ga.model._kernels` computes the 6n columns pose by pose (compiled, or its numpy twin
    for small problems, the same bits: :func:`zrp_ga.core.compiled.call`);
    :func:`jacobian_reference` (``compiled=False``) is the same in readable numpy, equal to
    round-off (the tests hold them together)."""
    if not compiled:
        return jacobian_reference(u0, b0, prism, q, base, hand)
    q = np.ascontiguousarray(q, dtype=float)
    u0, b0 = np.ascontiguousarray(u0, dtype=float), np.ascontiguousarray(b0, dtype=float)
    prism = np.ascontiguousarray(prism, dtype=np.bool_)
    M, n = q.shape
    if n < 1 or u0.shape != (n, 3) or b0.shape != (n + 1, 3) or prism.shape != (n,):
        raise ValueError(f"jacobian_arrays: expected u0 ({n}, 3), b0 ({n + 1}, 3), prism ({n},) for q {q.shape}, "
                         f"got {u0.shape}, {b0.shape}, {prism.shape}")  # fmt: skip
    J = np.zeros((M, 6, 6 * n + 3 * base + 3 * hand))
    Rn = np.empty((M, 3, 3))
    c, s = np.cos(q), np.sin(q)

    def kernel():
        from zrp_ga.model import _kernels

        _kernels.jacobian_kernel(u0, b0, prism, c, s, q, J, Rn)

    compiled_code.call("jacobian", M * n * n, kernel, lambda: _numpy_kernels.jacobian(u0, b0, prism, c, s, q, J, Rn))
    col = 6 * n
    if base:
        J[:, 3:6, col : col + 3] = np.eye(3)
        col += 3
    if hand:
        J[:, 0:3, col : col + 3] = Rn
    return J


def jacobian_reference(u0: Array, b0: Array, prism: NDArray[np.bool_], q: Array, base: bool = False, hand: bool = False) -> Array:
    """:func:`jacobian_arrays` in readable, vectorised numpy (Eq. 21-27 as written)."""
    M, n = q.shape
    rev = (~prism).astype(float)
    Rot = np.where(prism[:, None, None], np.eye(3), so3.rodrigues(q, u0))  # (M, n, 3, 3)
    dRot = so3.rodrigues_derivatives(q, u0) * rev[:, None, None, None]  # (M, n, 3, 3, 3)
    Rprev = np.empty((M, n + 1, 3, 3))
    Rprev[:, 0] = np.eye(3)
    for i in range(n):
        Rprev[:, i + 1] = Rprev[:, i] @ Rot[:, i]
    bt = np.broadcast_to(b0, (M, n + 1, 3)).copy()
    bt[:, :n] += np.where(prism, q, 0.0)[..., None] * u0
    E = np.empty((M, n, 3))
    E[:, n - 1] = bt[:, n]
    for i in range(n - 2, -1, -1):
        E[:, i] = bt[:, i + 1] + np.einsum("mab,mb->ma", Rot[:, i + 1], E[:, i + 1])

    K = 6 * n + 3 * base + 3 * hand
    J = np.zeros((M, 6, K))
    # dR_k R^T, rotated into the world: (M, n, 3[k], 3, 3)
    W = Rprev[:, :n, None] @ dRot @ np.swapaxes(Rot, -1, -2)[:, :, None] @ np.swapaxes(Rprev[:, :n, None], -1, -2)
    J1 = so3.vee(W)  # (M, n, 3[k], 3[row])
    J3 = np.einsum("miab,mikbc,mic->mika", Rprev[:, :n], dRot, E)  # (M, n, k, row)
    J3 = np.where(prism[None, :, None, None], q[:, :, None, None] * np.swapaxes(Rprev[:, :n], -1, -2), J3)
    J[:, 0:3, : 3 * n] = np.transpose(J1, (0, 3, 1, 2)).reshape(M, 3, 3 * n)
    J[:, 3:6, : 3 * n] = np.transpose(J3, (0, 3, 1, 2)).reshape(M, 3, 3 * n)
    J[:, 3:6, 3 * n : 6 * n] = np.transpose(Rprev[:, 1:], (0, 2, 1, 3)).reshape(M, 3, 3 * n)
    col = 6 * n
    if base:
        J[:, 3:6, col : col + 3] = np.eye(3)
        col += 3
    if hand:
        J[:, 0:3, col : col + 3] = Rprev[:, n]
    return J


def unit_rows(robot: ZRPRobot, n_params: int | None = None) -> Array:
    """The unit-length rows of Eq. (19-20), ``u0_i^T du0_i = 0``: (n, K), K = 6n by default."""
    n = robot.n
    U = np.zeros((n, n_params or 6 * n))
    for i in range(n):
        U[i, 3 * i : 3 * i + 3] = robot.u0[i]
    return U


def error_jacobian(
    robot: ZRPRobot, q: ArrayLike, position_only: bool = False, base: bool = False, hand: bool = False
) -> Array:
    """The error Jacobian of Eq. (21-27): rows ``[dr; dp]`` of every pose, then the n unit rows.

    q (n,) gives (6 + n, 6n); q (M, n) gives the stacked (6M + n, 6n); with
    ``position_only`` only the ``dp`` rows are kept: (3M + n, 6n). ``base``/``hand`` append
    columns for ``db0_1`` and the hand orientation (see :func:`pose_jacobians`).

    >>> from zrp_ga.io import presets
    >>> error_jacobian(presets.get("puma560"), np.zeros(6)).shape
    (12, 36)
    """
    Jp = pose_jacobians(robot, q, base=base, hand=hand)
    if position_only:
        Jp = Jp[:, 3:]
    rows = Jp.reshape(-1, Jp.shape[-1])
    return np.vstack([rows, unit_rows(robot, Jp.shape[-1])])


@dataclasses.dataclass(frozen=True)
class IdentifiabilityReport:
    """Rank, singular values and the unobservable directions of a stacked error Jacobian.

    ``condition_number`` is ``s_max / s_min`` over the identifiable part (the ``rank``
    largest singular values); the whole matrix's condition number is infinite when
    ``rank < n_params``.
    """

    rank: int
    n_params: int
    singular_values: Array
    condition_number: float
    null_directions: list[str]

    @property
    def deficiency(self) -> int:
        return self.n_params - self.rank

    def __str__(self) -> str:
        lines = [
            f"rank {self.rank} of {self.n_params} parameters "
            f"(condition number of the identifiable part {self.condition_number:.3g})"
        ]
        lines += [f"  unidentifiable: {d}" for d in self.null_directions]
        return "\n".join(lines)


def _known_null_directions(robot: ZRPRobot, names: list[str]) -> list[tuple[str, Array]]:
    """Directions (K,) of the genome that the geometry of ``robot`` says measurements may not
    see, with their labels: the slide of the point on axis i along it (a prismatic joint's axis
    also across it), and the two tilts of an axis through the end point about that point. Only
    directions within the genome's (free) genes ``names``."""
    K = len(names)
    index = {name: k for k, name in enumerate(names)}
    has = lambda stem: all(f"{stem}{c}" in index for c in "xyz")
    cols = lambda stem: [index[f"{stem}{c}"] for c in "xyz"]
    candidates: list[tuple[str, Array]] = []
    for i in range(1, robot.n + 1):
        a, b = f"b0_{i}", f"b0_{i + 1}"
        if has(a) and has(b):
            v = np.zeros(K)
            v[cols(a)] = robot.u0[i - 1]
            v[cols(b)] = -robot.u0[i - 1]
            candidates.append((f"b0_{i}/b0_{i + 1} slide along u0_{i}", v / np.sqrt(2)))
            if robot.joint_types[i - 1] == "P":
                for c, e in zip("xyz", np.eye(3)):
                    v = np.zeros(K)
                    v[cols(a)], v[cols(b)] = e, -e
                    label = f"b0_{i}/b0_{i + 1} shift along {c} (prismatic joint {i}: its axis has no fixed point)"
                    candidates.append((label, v / np.sqrt(2)))
        # Axis i through the end point e: it can tilt about e unseen by position data. Tilting
        # u0_i by t moves its point c_i by -L t (L = (e - c_i) . u0_i) to keep e on the axis.
        c_i = robot.b0[:i].sum(axis=0)
        arm = robot.b0.sum(axis=0) - c_i
        L = arm @ robot.u0[i - 1]
        through = np.linalg.norm(arm - L * robot.u0[i - 1]) < 1e-9
        if through and has(f"u0_{i}") and has(b) and (has(a) or L == 0.0):
            for t in np.linalg.svd(robot.u0[i - 1][None])[2][1:]:  # two tilts normal to u0_i
                v = np.zeros(K)
                v[cols(f"u0_{i}")] = t
                if has(a):
                    v[cols(a)] -= L * t
                v[cols(b)] += L * t
                label = f"u0_{i} tilts about the end point (axis {i} passes through it)"
                candidates.append((label, v / np.linalg.norm(v)))
    return candidates


def identifiability(
    J: ArrayLike, names: list[str], robot: ZRPRobot | None = None, rtol: float | None = None, max_listed: int = 4
) -> IdentifiabilityReport:
    """Identifiability report of a stacked Jacobian ``J`` (rows, K) with column ``names``.

    The rank uses numpy's default tolerance ``s_max * max(J.shape) * eps`` unless ``rtol``
    (relative to ``s_max``) is given. Null directions are named: first the slides of the point
    on an axis along that axis (``"b0_3/b0_4 slide along u0_3"``, needs ``robot``), then single
    parameters with no effect (``"u0_6x has no effect"``), then what is left as its leading
    parameters (``"combination of 0.71 b0_5z, -0.71 b0_7z"``), at most ``max_listed`` of them.
    """
    J = np.asarray(J, dtype=float)
    K = J.shape[1]
    if len(names) != K:
        raise ValueError(f"names: {len(names)} names for {K} Jacobian columns")
    _, s, Vt = np.linalg.svd(J, full_matrices=J.shape[0] < K)  # Vt (K, K) either way; no (rows, rows) U
    tol = s[0] * (rtol if rtol is not None else max(J.shape) * np.finfo(float).eps)
    rank = int(np.sum(s > tol))
    N = Vt[rank:].T  # (K, d) orthonormal null basis
    candidates = _known_null_directions(robot, names) if robot is not None else []
    candidates += [(f"{name} has no effect", e) for e, name in zip(np.eye(K), names)]  # rows of one (K, K): not K of them
    named, basis = [], np.zeros((K, 0))
    for label, v in candidates:
        if N.shape[1] == basis.shape[1]:
            break
        in_null = np.linalg.norm(v - N @ (N.T @ v)) < 1e-6
        new = np.linalg.norm(v - basis @ (basis.T @ v)) > 1e-6 if basis.size else True
        if in_null and new:
            named.append(label)
            basis = np.linalg.qr(np.column_stack([basis, v]))[0]
    rest = N - basis @ (basis.T @ N)
    U, sv, _ = np.linalg.svd(rest, full_matrices=False)
    rest_dirs = U[:, sv > 1e-6].T
    for v in rest_dirs[:max_listed]:
        top = np.argsort(-np.abs(v))[:4]
        parts = [f"{v[k]:+.2f} {names[k]}" for k in top if abs(v[k]) > 0.05]
        named.append("combination of " + ", ".join(parts))
    if len(rest_dirs) > max_listed:
        named.append(f"... and {len(rest_dirs) - max_listed} more combinations: too few measurements for the parameters")
    cond = float(s[0] / s[rank - 1]) if rank else float("inf")
    return IdentifiabilityReport(rank, K, s, cond, named)


def canonical(layout: Layout, nominal: ZRPRobot, x: ArrayLike) -> Array:
    """Gauge fixing: the genome ``x`` (K,) minus its components along the exact null directions
    of the model, the slide of each axis point along its own (normalised) axis and any shift of
    a prismatic joint's point. Every pose and every cost stays the same; body-vector errors
    become comparable between runs (LM, whose damping moves freely along these directions,
    otherwise reports metres). With fixed genes, the combinations of these directions that leave
    them alone (the points on two parallel axes slid together when the body vector between them
    is fixed). ``x`` may also be a full genome (the fixed genes included, a simulation's truth),
    returned full and fixed along the same directions."""
    x = np.asarray(x, dtype=float)
    full = layout.expand(x)
    whole = layout.unmasked
    u = layout.unpack(nominal, full).U[:, :, 0]
    S = slides(whole, nominal, u)
    if S.shape[1] and layout.is_masked:  # the combinations of slides within the genome's range (fixed genes alone)
        from scipy.linalg import null_space

        N = layout.matrix
        S = S @ null_space(S - N @ (N.T @ S))
    if S.shape[1]:
        Q = np.linalg.qr(S)[0]
        full -= Q @ (Q.T @ full)
    return full if x.shape[-1] == whole.size else layout.restrict(full)


def row_space_projector(J: ArrayLike) -> Array:
    """Orthogonal projector (K, K) onto the row space of ``J`` (rows, K): the parameter directions
    the poses behind ``J`` can see (numpy's default rank tolerance)."""
    J = np.asarray(J, dtype=float)
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    V = Vt[s > s[0] * max(J.shape) * np.finfo(float).eps]
    return V.T @ V
