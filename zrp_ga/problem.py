"""A calibration problem: bounds and a vectorised cost for a population, in pymoo's shape, plus
the residual and its Jacobian for one genome (for least squares and the pseudo-inverse step).

Genomes are parameter errors laid out by :class:`zrp_ga.layout.Layout`. Costs of a population
(P, K) are one vectorised call:

- ``linear`` (the paper): ``|| [dr; dp; 0] - J x ||`` with J the error Jacobian at the nominal
  parameters (Eq. 21-27) and ``[dr; dp]`` the pose errors of the nominal robot;
- ``nonlinear``: the forward-kinematics residual over all poses plus the unit rows
  ``(|u0_i + du0_i|^2 - 1) / 2`` (equal to the paper's ``u0_i^T du0_i`` to first order).

The forward kinematics turns about the normalised axes: Rodrigues' formula with a stretched
axis no longer leaves the axis fixed, and least squares then fits noise with points slid metres
along the axes (seen with LM before this choice: b0 genes of 14 m).
``norm="spectral"`` is the 2-norm of the residual vector, ``"rms"`` divides by the square root
of its length. Orientation rows are multiplied by ``orientation_weight`` (m per rad).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga import error_model, kinematics, so3
from zrp_ga.config import Cost, Kernel, Norm
from zrp_ga.layout import Layout
from zrp_ga.measurements import Measurements
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


@dataclasses.dataclass
class CalibrationProblem:
    """Nominal robot, calibration poses, genome layout and gene ranges ``lower``/``upper`` (K,)."""

    nominal: ZRPRobot
    data: Measurements
    layout: Layout
    lower: Array
    upper: Array
    cost: Cost = Cost.nonlinear
    norm: Norm = Norm.spectral
    orientation_weight: float = 1.0
    kernel: Kernel = Kernel.rodrigues  # which compiled cost evaluates a population (float64 unless float32)

    def __post_init__(self) -> None:
        K, n = self.layout.size, self.nominal.n
        self.cost, self.norm, self.kernel = Cost(self.cost), Norm(self.norm), Kernel(self.kernel)
        if self.layout.n != n:
            raise ValueError(f"layout: made for {self.layout.n} joints, the robot has {n}")
        if self.data.q.shape[1] != n:
            raise ValueError(f"{self.data.source}: {self.data.q.shape[1]} joint values per pose, the robot has {n} joints")
        if not (np.isfinite(self.orientation_weight) and self.orientation_weight >= 0):
            raise ValueError(f"problem.orientation_weight: must be a number >= 0, got {self.orientation_weight}")
        self.lower = np.broadcast_to(np.asarray(self.lower, dtype=float), (K,)).copy()
        self.upper = np.broadcast_to(np.asarray(self.upper, dtype=float), (K,)).copy()
        if not np.all(self.lower < self.upper):
            k = int(np.argmin(self.upper - self.lower))
            raise ValueError(f"gene range of {self.layout.names[k]}: lower {self.lower[k]} is not below upper {self.upper[k]}")
        data = self.data
        self.n_rows = (3 if data.position_only else 6) * data.M + n
        self._position_weights = np.ones((data.M, 3)) if data.weights is None else data.weights
        pose = self._position_weights
        if not data.position_only:
            pose = np.hstack([np.full((data.M, 3), self.orientation_weight), pose])
        self._row_weights = np.concatenate([pose.ravel(), np.ones(n)])
        self._terms = kinematics.joint_terms(data.q, self.nominal.prismatic)
        self.J_nominal = self._jacobian(np.zeros(K), exact=False)
        self.y_nominal = self._residual(np.zeros(K))  # [dr; dp; 0] of the nominal robot

    @property
    def names(self) -> list[str]:
        return self.layout.names

    # --- a population -----------------------------------------------------------------------
    def costs(self, X: ArrayLike) -> Array:
        """Cost of every genome of X (P, K), (P,); NaN or inf where the genes break the model."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        with np.errstate(all="ignore"):
            if self.cost is Cost.linear:
                r = self.y_nominal[None] - X @ self.J_nominal.T
                total = np.einsum("pr,pr->p", r, r)
            else:
                m = self.layout.unpack(self.nominal, X)
                data = self.data
                sums = kinematics.residual_sums_unchecked(m.U, m.B, m.H, self._terms, data.p, data.R,
                                                          self._position_weights, kernel=self.kernel.value)  # fmt: skip
                unit = 0.5 * (m.length2 - 1.0)
                total = self.orientation_weight**2 * sums[0] + sums[1] + np.einsum("ip,ip->p", unit, unit)
            if self.norm is Norm.rms:
                total = total / self.n_rows
            return np.sqrt(total)

    # --- one genome ---------------------------------------------------------------------------
    def residual(self, x: ArrayLike) -> Array:
        """Weighted residual vector (rows,) of one genome under this problem's cost."""
        x = np.asarray(x, dtype=float)
        if self.cost is Cost.linear:
            return self.y_nominal - self.J_nominal @ x
        return self._residual(x)

    def jacobian(self, x: ArrayLike) -> Array:
        """Jacobian of the model with respect to x, so that ``residual(x + d) ~ residual(x) - J d``."""
        if self.cost is Cost.linear:
            return self.J_nominal
        return self._jacobian(np.asarray(x, dtype=float), exact=True)

    def _residual(self, x: Array) -> Array:
        """Nonlinear weighted residual: per pose [w dr; dp] (or dp), then -(|u0 + du0|^2 - 1) / 2."""
        u0, b0, R_h0 = self.layout.unpack(self.nominal, x).population_first()
        data = self.data
        R, p = kinematics.forward_batch(u0, b0, R_h0, data.q, self.nominal.prismatic)
        dp = data.p - p[0]
        pose = dp if data.position_only else np.hstack([error_model.pose_error(data.R, data.p, R[0], p[0])[0], dp])
        unit = -0.5 * (np.sum((self.nominal.u0 + x[self.layout.blocks["u0"]].reshape(-1, 3)) ** 2, axis=1) - 1.0)
        return np.concatenate([pose.ravel(), unit]) * self._row_weights

    def _jacobian(self, x: Array, exact: bool) -> Array:
        """Stacked, weighted error Jacobian at ``x``. ``exact``: the orientation rows are the
        derivative of this problem's residual ``vee(skew(W))``, ``W = R_meas R^T``, which is
        ``(tr(W) I - W^T) / 2`` times the paper's J1 rows (equal when W = I)."""
        m = self.layout.unpack(self.nominal, x)
        data, n, blocks = self.data, self.nominal.n, self.layout.blocks
        raw = self.nominal.u0 + x[blocks["u0"]].reshape(n, 3)
        length = np.linalg.norm(raw, axis=1)
        unit = raw / length[:, None]
        J = error_model.jacobian_arrays(unit, m.B[:, :, 0], self.nominal.prismatic, data.q, self.layout.base, self.layout.hand)
        if data.position_only:
            J = J[:, 3:]
        elif exact:
            if self.layout.hand:  # dexp of the hand rotation vector: its left Jacobian
                J[:, :3, blocks["hand"]] = J[:, :3, blocks["hand"]] @ so3.left_jacobian(x[blocks["hand"]])
            u0, b0, R_h0 = m.population_first()
            R, _ = kinematics.forward_batch(u0, b0, R_h0, data.q, self.nominal.prismatic)
            W = data.R @ np.swapaxes(R[0], -1, -2)
            G = 0.5 * (np.trace(W, axis1=1, axis2=2)[:, None, None] * np.eye(3) - np.swapaxes(W, -1, -2))
            J[:, :3] = G @ J[:, :3]
        # chain rule through the normalisation u / |u|: (I - u_hat u_hat^T) / |u|
        N = (np.eye(3) - unit[:, :, None] * unit[:, None, :]) / length[:, None, None]
        Ju = J[..., : 3 * n].reshape(J.shape[:2] + (n, 3))
        J[..., : 3 * n] = np.einsum("mrik,ikl->mril", Ju, N).reshape(J.shape[:2] + (3 * n,))
        U = np.zeros((n, self.layout.size))
        for i in range(n):
            U[i, 3 * i : 3 * i + 3] = raw[i]
        return np.vstack([J.reshape(-1, J.shape[-1]), U]) * self._row_weights[:, None]

    def identifiability(self) -> error_model.IdentifiabilityReport:
        """Identifiability report of the calibration poses (Jacobian at the nominal parameters)."""
        return error_model.identifiability(self._jacobian(np.zeros(self.layout.size), exact=False), self.names, self.nominal)
