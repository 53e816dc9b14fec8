"""How well a set of poses determines the parameters, before anything is measured: the scaled
error Jacobian of the identifiable parameters, its per-pose information blocks, and the
observability indices O1-O4 and A-optimality (docs/model.md, section 6).

The pipeline, for candidate poses c = 1..N:

1. ``J_c`` (r, K): the error Jacobian rows of pose c at the nominal parameters (r = 3 for
   positions, 6 for full poses; :func:`zrp_ga.model.error_model.pose_jacobians`), with the axes
   normalised as the model turns them (``(I - u u^T)`` on each ``du0``: stretching an axis
   changes nothing), orientation rows times ``orientation_weight`` (m per rad) and position
   rows times their weights, as the calibration's residual weights them.
2. Scaling: angle parameters (axis errors, the hand rotation) times a characteristic length
   ``L`` (m), so that every parameter is a length and every entry of ``J`` a ratio of lengths;
   the indices then do not change when metres become millimetres.
3. ``V`` (K, m): an orthonormal basis of the directions the candidates can see, the right
   singular vectors of the stacked ``[J_1; ...; J_N]`` with singular values above
   ``rcond * s_max``. The null directions (slides of the axis points, stretches of the axes)
   and directions seen far worse than the rest are left out; without this ``s_m = 0``.
4. ``J_c V`` (r, m): pose c's block, its information ``A_c = (J_c V)^T (J_c V)``. A subset S
   has ``G_S = sum_{c in S} A_c`` (+ ``ridge I``), whose eigenvalues are the squared singular
   values ``s_1 >= ... >= s_m`` of the stacked ``J_S V``.

>>> from zrp_ga.io import presets
>>> from zrp_ga.model.layout import Layout
>>> arm = presets.get("puma560")
>>> q = np.random.default_rng(0).uniform(-1, 1, (50, 6))
>>> rows = scaled_pose_rows(arm, q, Layout(6), length_m=characteristic_length(arm))
>>> V = identifiable_basis(rows)
>>> V.shape  # 36 parameters, 25 seen: 5 slides and 6 axis stretches are invisible
(36, 25)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model import error_model
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
INDICES = ("O1", "O2", "O3", "O4", "A")


def characteristic_length(robot: ZRPRobot) -> float:
    """The summed lengths of the body vectors from the point on axis 1 to the end point, m
    (an upper bound of the arm's reach; the default scale of angle parameters)."""
    return float(np.linalg.norm(robot.b0[1:], axis=1).sum())


def scaled_pose_rows(
    nominal: ZRPRobot,
    q: ArrayLike,
    layout: Layout,
    position_only: bool = False,
    length_m: float = 1.0,
    orientation_weight: float = 1.0,
    weights: ArrayLike | None = None,
) -> Array:
    """Scaled, weighted error Jacobian rows of M poses q (M, n): (M, 3, K) with
    ``position_only``, else (M, 6, K) (orientation rows first). ``weights`` (M, 3): the
    position rows' weights (None: 1). Columns as ``layout``; angle columns divided by
    ``length_m`` (parameters in metres), axes normalised at the nominal (unit) axes."""
    n = nominal.n
    J = error_model.pose_jacobians(nominal, q, base=layout.base, hand=layout.hand)
    u = nominal.u0
    normalise = np.eye(3) - u[:, :, None] * u[:, None, :]  # (n, 3, 3), d(u/|u|)/du at |u| = 1
    Ju = J[..., : 3 * n].reshape(J.shape[:2] + (n, 3))
    J[..., : 3 * n] = np.einsum("mrik,ikl->mril", Ju, normalise).reshape(J.shape[:2] + (3 * n,))
    J[..., : 3 * n] /= length_m
    if layout.hand:
        J[..., layout.blocks["hand"]] /= length_m
    J[:, :3] *= orientation_weight
    if weights is not None:
        J[:, 3:] *= np.asarray(weights, dtype=float)[:, :, None]
    J = layout.columns(J)  # the genome's columns (a layout without tools: K = 6n + base + hand)
    return J[:, 3:] if position_only else J


def identifiable_basis(rows: ArrayLike, rcond: float = 1e-4) -> Array:
    """Orthonormal basis (K, m) of the parameter directions the stacked ``rows`` (M, r, K) see
    with a singular value above ``rcond`` times the largest."""
    rows = np.asarray(rows, dtype=float)
    _, s, Vt = np.linalg.svd(rows.reshape(-1, rows.shape[-1]), full_matrices=False)
    return Vt[s > rcond * s[0]].T


def reduced_rows(rows: ArrayLike, V: ArrayLike) -> Array:
    """Per-pose blocks ``J_c V`` (M, r, m) of rows (M, r, K): each pose's rows in the
    identifiable directions. Pose c's information is ``A_c = (J_c V)^T (J_c V)``."""
    return np.asarray(rows, dtype=float) @ np.asarray(V, dtype=float)


def subset_information(R: Array, X: NDArray[np.intp]) -> Array:
    """``G_S = sum_{c in S} A_c = (J_S V)^T (J_S V)`` for each row S of X (P, w) of pose
    indices, from the per-pose blocks R (N, r, m): (P, m, m). Gathering the r x m blocks and
    multiplying moves fewer numbers than summing the m x m ``A_c`` when r < m (about half the
    time for positions, 3 rows against 25 directions)."""
    P, w = X.shape
    J = R[X].reshape(P, w * R.shape[1], R.shape[2])
    return np.swapaxes(J, 1, 2) @ J


def indices(G: ArrayLike, n_poses: int | ArrayLike) -> dict[str, Array]:
    """The indices of information matrices G (P, m, m) of subsets of ``n_poses`` poses, each (P,),
    from the singular values ``s_i = sqrt(eig_i(G))``, ``s_1 >= ... >= s_m``:

    - ``O1 = (s_1 ... s_m)^(1/m) / sqrt(M)`` (Borm and Menq; D-optimality),
    - ``O2 = s_m / s_1`` (inverse condition number; Driels and Pathre),
    - ``O3 = s_m`` (minimum singular value; Nahvi, Hollerbach and Hayward),
    - ``O4 = s_m^2 / s_1`` (noise amplification index; Nahvi and Hollerbach),
    - ``A = trace(G^-1) = sum 1 / s_i^2`` (A-optimality).

    O1-O4 are larger for better subsets, A smaller; a singular G (eigenvalues below
    ``m eps`` times the largest count as zero) gives O1 = O2 = O3 = O4 = 0 and A = inf.
    """
    ev = np.linalg.eigvalsh(np.asarray(G, dtype=float))  # ascending
    ev = np.where(ev > ev.shape[1] * np.finfo(float).eps * ev[:, -1:], ev, 0.0)  # rounding-level eigenvalues are zero
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.sqrt(ev)
        s_min, s_max = s[:, 0], s[:, -1]
        log_s = np.where(s > 0, np.log(np.where(s > 0, s, 1.0)), -np.inf)
        o1 = np.exp(np.mean(log_s, axis=1)) / np.sqrt(np.asarray(n_poses, dtype=float))
        return {
            "O1": o1,
            "O2": np.where(s_max > 0, s_min / s_max, 0.0),
            "O3": s_min,
            "O4": np.where(s_max > 0, s_min**2 / s_max, 0.0),
            "A": np.sum(1.0 / ev, axis=1),
        }


def index_cost(G: ArrayLike, n_poses: int, index: str) -> Array:
    """What an optimiser minimises for ``index``, for information matrices G (P, m, m):
    ``1 / O1`` .. ``1 / O4`` (positive, so that costs can be plotted on a log scale), or A
    itself; inf for a singular G. ``1 / O1`` comes from a Cholesky factor G = L L^T,
    ``(s_1 ... s_m)^(1/m) = exp(mean(log diag L))``, several times cheaper than the
    eigenvalues the other indices need (falling back to them when G is not positive definite)."""
    G = np.asarray(G, dtype=float)
    if index == "O1":
        try:
            L = np.linalg.cholesky(G)
        except np.linalg.LinAlgError:
            pass
        else:
            diagonal = np.diagonal(L, axis1=1, axis2=2)
            return np.sqrt(float(n_poses)) * np.exp(-np.mean(np.log(diagonal), axis=1))
    values = indices(G, n_poses)
    if index == "A":
        return values["A"]
    with np.errstate(divide="ignore"):
        return 1.0 / values[index]
