"""A robust cost (``problem.loss``: ``soft_l1`` or ``huber``): one mis-measured point (a
reflector seen through a beam break) no longer pulls the fit.

The cost is scipy's (``scipy.optimize.least_squares``' ``loss`` and ``f_scale`` C), applied to
every weighted residual row f_i of the plain problem:

    cost = sqrt( sum_i C^2 rho(f_i^2 / C^2) )        (= 2 x scipy's ``cost``, square-rooted)
    soft_l1: rho(z) = 2 (sqrt(1 + z) - 1);    huber: rho(z) = z (z <= 1), 2 sqrt(z) - 1 (z > 1)

which is the plain cost when every |f_i| << C. Levenberg-Marquardt hands scipy the plain
residual with ``loss`` and ``f_scale`` (:func:`zrp_ga.problems.least_squares.levenberg_marquardt`);
the GA and CMA-ES minimise the same number (:meth:`RobustProblem.costs`), and the pseudo-inverse
step is an iteratively reweighted least-squares step: :meth:`RobustProblem.residual` and
:meth:`RobustProblem.jacobian` are the plain rows and Jacobian times ``sqrt(rho'(f_i^2 / C^2))``
(scipy scales them so too, without its second-order correction; a Gauss-Newton step on the
square-rooted rows ``sign(f) C sqrt(rho)``, whose sum of squares is the cost, diverged on
planted outliers). For a convex loss (both) these steps lower the cost to its minimum (IRLS for
M-estimators: P. J. Huber, *Robust Statistics*, 1981, section 7.8).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.schema import Cost, Norm
from zrp_ga.model import error_model, kinematics
from zrp_ga.model.cost import CalibrationProblem

Array = NDArray[np.float64]
LOSSES = ("soft_l1", "huber")


def rho(z: Array, loss: str) -> tuple[Array, Array]:
    """scipy's loss ``rho(z)`` and its derivative ``rho'(z)`` (``z = f^2 / C^2 >= 0``)."""
    if loss == "soft_l1":
        t = np.sqrt(1.0 + z)
        return 2.0 * (t - 1.0), 1.0 / t
    if loss == "huber":
        big = z > 1.0
        root = np.sqrt(np.where(big, z, 1.0))
        return np.where(big, 2.0 * root - 1.0, z), np.where(big, 1.0 / root, 1.0)
    raise ValueError(f"problem.loss: {loss!r}, expected linear, {' or '.join(LOSSES)}")


@dataclasses.dataclass
class RobustProblem(CalibrationProblem):
    """:class:`~zrp_ga.model.cost.CalibrationProblem` with a robust ``loss`` of scale
    ``loss_scale`` C (m, on the weighted rows; module docstring)."""

    loss: str = "soft_l1"
    loss_scale: float = 1e-4

    def __post_init__(self) -> None:
        rho(np.zeros(1), self.loss)  # an unknown loss: one line
        if not (np.isfinite(self.loss_scale) and self.loss_scale > 0):
            raise ValueError(f"problem.loss_scale: must be a length > 0 (m), got {self.loss_scale}")
        super().__post_init__()

    # --- the plain problem's rows (what scipy's loss is applied to) ---------------------------
    def plain_residual(self, x: ArrayLike) -> Array:
        return super().residual(x)

    def plain_jacobian(self, x: ArrayLike) -> Array:
        return super().jacobian(x)

    def _weights(self, f: Array) -> Array:
        """``sqrt(rho'(f^2 / C^2))`` of the rows ``f``: each row's weight in a reweighted step."""
        return np.sqrt(rho((f / self.loss_scale) ** 2, self.loss)[1])

    def residual(self, x: ArrayLike) -> Array:
        """The rows reweighted for one step, ``sqrt(rho'(z)) f`` (module docstring)."""
        f = self.plain_residual(x)
        return self._weights(f) * f

    def jacobian(self, x: ArrayLike) -> Array:
        """The plain Jacobian with the rows' weights at ``x``, so that a least-squares step on
        :meth:`residual` is the iteratively reweighted step of the robust cost."""
        return self._weights(self.plain_residual(x))[:, None] * self.plain_jacobian(x)

    def costs(self, X: ArrayLike) -> Array:
        """The robust cost of every genome of X (P, K), (P,): the rows of each genome at once
        (:meth:`rows`), then the loss."""
        F = self.rows(X)
        with np.errstate(all="ignore"):
            total = np.sum(self.loss_scale**2 * rho((F / self.loss_scale) ** 2, self.loss)[0], axis=1)
            if self.norm is Norm.rms:
                total = total / self.n_rows
            return np.sqrt(total)

    def rows(self, X: ArrayLike) -> Array:
        """The plain weighted residual rows (P, n_rows) of genomes X (P, K), as
        :meth:`CalibrationProblem.residual` orders them, for a population at once."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self.cost is Cost.linear:
            return self.y_nominal[None] - X @ self.J_nominal.T
        data = self.data
        with np.errstate(all="ignore"):
            m = self.layout.unpack(self.nominal, X)
            P = X.shape[0]
            R, p = np.empty((P, data.M, 3, 3)), np.empty((P, data.M, 3))
            for k, rows, *_ in self._groups:
                u0, b0, R_h0 = m.for_tool(k).population_first()
                R[:, rows], p[:, rows] = kinematics.forward_batch(u0, b0, R_h0, data.q[rows], self.nominal.prismatic)
            dp = data.p[None] - p
            pose = dp if data.R is None else np.concatenate([error_model.pose_error(data.R[None], data.p[None], R, p)[0], dp], axis=2)
            unit = -0.5 * (m.length2.T - 1.0)  # (P, n)
        return np.concatenate([pose.reshape(P, -1), unit], axis=1) * self._row_weights[None]
