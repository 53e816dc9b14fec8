"""What the calibration data identify: the parameter combinations a fit may move, the rest left
at their nominal values, as base-parameter methods do (Khalil and Dombre; FIGAROH eliminates
the others by QR with column pivoting; a minimum-norm step does the same for one linear step).

With J the problem's weighted error Jacobian (pose rows, then the n unit-length rows), the
whitening ``W^(1/2) = diag(1 / sigma_row)`` of its pose rows, the expected size of each
parameter error ``p`` (K,) (the gene ranges over ``search_scale``: the scale of the prior) and
T an orthonormal basis of the directions in which the axes turn rather than stretch (the null
space of the unit rows times ``diag(p)``), the singular value decomposition

    A = W^(1/2) J_pose diag(p) T = U S V^T

gives directions ``v_i`` (in units of the expected errors) and the standard error ``1 / s_i`` of
a least-squares estimate along each (``sigma`` known: the data's own). A direction is
**identified** when

1. ``s_i > s_1 * max(A.shape) * eps`` (numpy's rank rule: not an exact null direction), and
2. ``1 / s_i <= max_se`` (its standard error is at most ``max_se`` expected errors; default
   0.5, below the standard deviation ``1/sqrt(3)`` of an error uniform within its expected
   size: an estimate along a direction that fails it is expected to be further from the truth
   than the nominal value is). Without a noise estimate (no residual degrees of freedom) only
   rule 1 applies.

The genome is then z with ``x = N z``, ``N = diag(p) T V_r`` with unit columns (z_k is the
length, m or rad, of the move along direction k), and the left inverse
``G = diag(|N_k|) V_r^T T^T diag(1 / p)`` (the projection in units of the expected errors): the
directions are the principal axes of the Gauss-Newton Hessian at the point of the Jacobian, so
that near it the cost is separable in z. Everything outside ``span(N)`` stays at nominal: the
dropped directions ``diag(p) T V_d`` and the axes' stretches.

Hand-written on numpy's SVD and ``scipy.linalg.null_space`` because the rule (relative to the
noise, in units of a prior) is the point; no library offers it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from zrp_ga.model import error_model
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
MAX_SE = 0.5  # default: standard error of an identified direction, in expected errors
RANGE_LEAST = 3**0.5  # a gene's range is at least this many expected errors (where the box's projection allows)


@dataclasses.dataclass(frozen=True)
class Subspace:
    """The identified directions of one Jacobian. ``basis`` N (K, r) unit columns and ``dual`` G
    (r, K), ``G N = I``, in the genome's coordinates it was computed in; ``singular_values`` s
    (m,) of A (module docstring), descending; ``rank`` r; ``exact_rank`` (rule 1 alone);
    ``whitened``: s is in units of the noise (rule 2 applied); ``scale`` (r,): the length (m or
    rad) of one expected error along each gene (the column norms of ``diag(p) T V_r``);
    ``spread`` (r,): each gene's largest value over the box ``|x_j| <= p_j`` in expected errors
    (``|T V_r|_1``, column sums), for the gene ranges; ``prior_factor`` (K, m - r): ``F`` with
    ``F F^T`` the covariance of an error uniform within ``+-p`` along the dropped directions
    ``diag(p) T V_d`` (what leaving them at nominal may cost), ``diag(p) T V_d / sqrt(3)``."""

    basis: Array
    dual: Array
    singular_values: Array
    rank: int
    exact_rank: int
    whitened: bool
    max_se: float
    scale: Array
    spread: Array
    prior_factor: Array

    @property
    def standard_errors(self) -> Array | None:
        """Standard errors (m,) of the estimates along every direction, in expected errors
        (``1 / s_i``); None without a noise estimate."""
        if not self.whitened:
            return None
        with np.errstate(divide="ignore"):
            return 1.0 / self.singular_values

    def rule(self) -> str:
        """The rank rule in words (``summary.json``)."""
        exact = "s_i > s_1 * max(rows, K) * eps"
        if not self.whitened:
            return f"{exact} (no noise estimate: no residual degrees of freedom)"
        return f"{exact} and standard error 1/s_i <= {self.max_se:g} expected errors (s of the noise-whitened, prior-scaled Jacobian)"


def tangent(unit_rows: Array, prior: Array) -> Array:
    """Orthonormal basis T (K, K - rank) of the scaled genome ``xi = x / p`` in which every axis
    turns and none stretches: the null space of ``unit_rows @ diag(p)`` (``unit_rows``: (n, K),
    the problem's unit-length rows; a zero row, an axis fixed by a mask, constrains nothing)."""
    from scipy.linalg import null_space

    U = unit_rows * prior[None, :]
    U = U[np.linalg.norm(U, axis=1) > 0]
    return null_space(U) if U.size else np.eye(prior.size)


def identify(J_pose: Array, unit_rows: Array, prior: Array, row_sigma: Array | None, max_se: float = MAX_SE) -> Subspace:
    """The identified subspace (module docstring) of the pose rows ``J_pose`` (rows, K) of a
    weighted Jacobian, with the problem's ``unit_rows`` (n, K), the expected errors ``prior``
    (K,) (m, rad) and the noise ``row_sigma`` (rows,) of each weighted pose row (None: unknown,
    rule 1 only). ValueError when the data identify nothing."""
    prior = np.asarray(prior, dtype=float)
    T = tangent(unit_rows, prior)
    A = J_pose * prior[None, :] @ T
    if row_sigma is not None:
        A = A / np.asarray(row_sigma, dtype=float)[:, None]
    _, s, Vt = np.linalg.svd(A, full_matrices=A.shape[0] < A.shape[1])  # Vt (m, m) either way; no (rows, rows) U
    s = np.concatenate([s, np.zeros(T.shape[1] - s.size)]) if s.size < T.shape[1] else s
    exact = int(np.sum(s > (s[0] if s.size else 0.0) * max(A.shape) * np.finfo(float).eps)) if s.size and s[0] > 0 else 0
    rank = exact if row_sigma is None else int(np.sum((s[:exact] > 0) & (1.0 / np.maximum(s[:exact], 1e-300) <= max_se)))
    if rank == 0:
        raise ValueError("the calibration data identify no parameter combination: every direction's standard error exceeds "
                         f"{max_se:g} expected errors (problem.max_se), or the poses see none")  # fmt: skip
    V = Vt.T
    W = T @ V  # scaled directions (K, m), orthonormal
    B = prior[:, None] * W[:, :rank]
    norms = np.linalg.norm(B, axis=0)
    N = B / norms
    G = (norms[:, None] * W[:, :rank].T) / prior[None, :]
    spread = np.abs(W[:, :rank]).sum(axis=0)
    factor = prior[:, None] * W[:, rank:] / np.sqrt(3.0)
    return Subspace(N, G, s, rank, exact, row_sigma is not None, float(max_se), norms, spread, factor)


def principal_angle(a: Array, b: Array) -> float:
    """The largest principal angle (rad) between the column spans of ``a`` and ``b``
    (``scipy.linalg.subspace_angles``; pi/2 when their dimensions differ)."""
    from scipy.linalg import subspace_angles

    if a.shape[1] != b.shape[1]:
        return float(np.pi / 2)
    return float(np.max(subspace_angles(a, b)))


def restricted(layout: Layout, sub: Subspace) -> Layout:
    """``layout`` (masked or not, with or without a basis of its own) whose genome is the
    identified subspace ``sub`` (computed in ``layout``'s genome coordinates): the basis
    ``M N`` (M the layout's map to the full genome) and its left inverse ``G L`` (L the
    layout's own, :meth:`Layout.restrict`)."""
    if layout.basis is not None:
        return dataclasses.replace(layout, basis=layout.basis @ sub.basis, dual=sub.dual @ layout.restrict(np.eye(layout.full_size)).T)
    basis, dual = np.zeros((layout.full_size, sub.rank)), np.zeros((sub.rank, layout.full_size))
    free = layout.free
    basis[free], dual[:, free] = sub.basis, sub.dual  # a plain mask: zero rows (columns) at the fixed genes
    return dataclasses.replace(layout, basis=basis, dual=dual)


def half_widths(sub: Subspace, search_scale: float, least: float = RANGE_LEAST) -> Array:
    """Half widths (r,) of the genes of the identified genome, in expected errors along each
    gene ``min(spread * search_scale, max(search_scale, least))`` times its ``scale``: the box
    ``|x_j| <= search_scale p_j`` projected (its largest value, ``spread * search_scale``), but
    no wider than ``search_scale`` (a uniform gene with the variance of the box's projection on a
    unit direction, ``search_scale^2 / 3``: the corners of a box project far along directions
    that mix many genes, and a GA's first population and CMA-ES's first steps spread over the
    whole range) unless that is below ``least`` (``sqrt(3)``: 3 standard deviations of the
    projection of an error uniform within ``+-p``, so that ``search_scale = 1`` still holds it).
    On the simulated PUMA 560 (10 and 30 poses), a GA of 15 generations ended lower with these
    ranges than with the box's projection capped at ``sqrt(3)`` (medians over six seeds 0.050
    and 0.078 against 0.054 and 0.099)."""
    return sub.scale * np.minimum(sub.spread * search_scale, max(search_scale, least))


def describe(sub: Subspace, layout_names: list[str], robot: ZRPRobot, unit_rows: Array, max_listed: int = 8) -> list[str]:
    """The dropped directions in words (:func:`zrp_ga.model.error_model.identifiability`'s
    names: slides along axes, tilts about the end point, parameters without effect, then
    combinations by their leading parameters): the null directions of ``G`` stacked on the
    unit rows (the axes' stretches are not errors and are not named)."""
    if sub.prior_factor.shape[1] == 0:
        return []
    U = unit_rows[np.linalg.norm(unit_rows, axis=1) > 0]
    report = error_model.identifiability(np.vstack([sub.dual, U]), layout_names, robot, max_listed=max_listed)
    return report.null_directions
