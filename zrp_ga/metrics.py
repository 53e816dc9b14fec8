"""How good a calibration is, in SI units: position errors on poses (m), their RMS and maximum,
and the distance to the true parameters where they are known (simulation). Files carry the
unit in the column name (``val_rms_mm``); the conversion happens where they are written."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga import error_model, kinematics
from zrp_ga.layout import Layout
from zrp_ga.measurements import Measurements
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


def position_errors(layout: Layout, nominal: ZRPRobot, X: ArrayLike, data: Measurements) -> Array:
    """Distance (m) between measured and predicted positions at every pose of ``data``: (M,) for
    one genome (K,), (P, M) for a population (P, K); NaN where the genes break the model."""
    X = np.asarray(X, dtype=float)
    u0, b0, R_h0 = layout.unpack(nominal, X).population_first()
    with np.errstate(all="ignore"):
        _, p = kinematics.forward_batch(u0, b0, R_h0, data.q, nominal.prismatic)
        err = np.linalg.norm(data.p[None] - p, axis=2)
    return err[0] if X.ndim == 1 else err


def summary(errors: ArrayLike) -> dict[str, float]:
    """Mean, RMS and max of position errors (m), and the number of poses."""
    e = np.asarray(errors, dtype=float)
    return {"mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e**2))), "max": float(e.max()), "poses": int(e.size)}


@dataclasses.dataclass
class Judge:
    """What is known beyond the calibration data: validation poses and, in simulation, the true
    genome. Calling it on a genome gives the row a convergence log records."""

    layout: Layout
    nominal: ZRPRobot
    validation: Measurements | None = None
    truth: Array | None = None
    projector: Array | None = None  # onto the identifiable parameter directions (for param_err)

    def validation_errors(self, x: ArrayLike) -> tuple[Array, Array]:
        """RMS and max position error (m) on the validation poses, each (P,); NaN without them."""
        X = np.atleast_2d(np.asarray(x, dtype=float))
        if self.validation is None:
            nan = np.full(X.shape[0], np.nan)
            return nan, nan
        err = position_errors(self.layout, self.nominal, X, self.validation)
        return np.sqrt(np.mean(err**2, axis=1)), np.max(err, axis=1)

    def param_error(self, x: ArrayLike) -> Array:
        """Distance to the true genome in the identifiable subspace, (P,); NaN if unknown."""
        X = np.atleast_2d(np.asarray(x, dtype=float))
        if self.truth is None or self.projector is None:
            return np.full(X.shape[0], np.nan)
        return np.linalg.norm((X - self.truth) @ self.projector, axis=1)

    def __call__(self, x: ArrayLike) -> dict[str, float]:
        """``val_rms_m``, ``val_max_m`` and ``param_err`` of one genome."""
        rms, vmax = self.validation_errors(x)
        return {"val_rms_m": float(rms[0]), "val_max_m": float(vmax[0]), "param_err": float(self.param_error(x)[0])}


def identifiable_projector(nominal: ZRPRobot, layout: Layout, q: Array, position_only: bool) -> Array:
    """Projector onto the parameter directions that poses ``q`` (M, n) can see at the nominal
    parameters (rows of the stacked Jacobian with its unit rows)."""
    J = error_model.jacobian_arrays(nominal.u0, nominal.b0, nominal.prismatic, q, layout.base, layout.hand)
    if position_only:
        J = J[:, 3:]
    return error_model.row_space_projector(np.vstack([J.reshape(-1, J.shape[-1]), error_model.unit_rows(nominal, layout.size)]))
