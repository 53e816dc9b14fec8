"""How good a calibration is, in SI units: position errors on poses (m), their RMS and maximum,
and the distance to the true parameters where they are known (simulation). Files carry the
unit in the column name (``val_rms_mm``); the conversion happens where they are written.

Validation as engineers do it: in the calibration's frame (``registration="none"``), or in
another instrument frame (``"rigid"``: the tracker moved between the sets, so each model's
predictions are first moved rigidly onto the measured points, :func:`zrp_ga.model.registration.align`,
and what is left is scored), with the calibration's tool points or a known other one (the
layout's ``known_tools``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model import error_model, kinematics, terms
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


REGISTRATIONS = ("none", "rigid")


def predicted_positions(layout: Layout, nominal: ZRPRobot, X: ArrayLike, data: Measurements, each: bool = False) -> Array:
    """Predicted positions (P, M, 3), m, of genomes X (P, K) or (K,) at every pose of ``data``,
    each with its tool (``data.tool`` indexes the layout's tools, then its known tools);
    ``each``: every genome's exactly as alone (:meth:`zrp_ga.model.layout.Layout.unpack`)."""
    m = layout.unpack(nominal, X, each)
    tools = data.tools
    p = np.empty((m.U.shape[2], data.M, 3))
    for k in np.unique(tools):
        rows = tools == k
        u0, b0, R_h0 = m.for_tool(int(k)).population_first()
        dq = None
        if layout.terms:  # the non-geometric terms' joint offsets, features on the nominal arm (zrp_ga.model.terms)
            assert m.theta is not None  # unpack sets the term genes whenever the layout has terms
            dq = terms.offsets(layout.terms, nominal.n, terms.features(layout.terms, nominal, data.q[rows]), m.theta)
        p[:, rows] = kinematics.forward_batch(u0, b0, R_h0, data.q[rows], nominal.prismatic, dq)[1]
    return p


def position_errors(layout: Layout, nominal: ZRPRobot, X: ArrayLike, data: Measurements, registration: str = "none",
                    each: bool = False, correction: Callable[[Array], Array] | None = None) -> Array:  # fmt: skip
    """Distance (m) between measured and predicted positions at every pose of ``data``: (M,) for
    one genome (K,), (P, M) for a population (P, K); NaN where the genes break the model. With
    ``registration="rigid"`` each genome's predictions are first moved rigidly onto the
    measurements (module docstring)."""
    if registration not in REGISTRATIONS:
        raise ValueError(f"problem.validation_registration: {registration!r}, expected one of {', '.join(REGISTRATIONS)}")
    X = np.asarray(X, dtype=float)
    with np.errstate(all="ignore"):
        p = predicted_positions(layout, nominal, X, data, each)
        if correction is not None:  # a residual model's correction (M, 3) m at the poses (zrp_ga.model.residual)
            p = p + correction(data.q)[None]
        if registration == "rigid":
            from zrp_ga.model.registration import align  # imported for this choice only

            p = np.array([align(pk, data.p) if np.all(np.isfinite(pk)) else pk for pk in p])
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
    registration: str = "none"  # of the predictions onto the validation poses (module docstring)
    correction: Callable[[Array], Array] | None = None  # a residual model's (M, 3) m at poses (M, n): added when asked

    def validation_errors(self, x: ArrayLike, each: bool = False, corrected: bool = False) -> tuple[Array, Array]:
        """RMS and max position error (m) on the validation poses, each (P,); NaN without them.
        ``each``: every genome's exactly as judged alone (:meth:`zrp_ga.model.layout.Layout.unpack`);
        ``corrected``: with the residual model's :attr:`correction` (fitted to the final genome)."""
        X = np.atleast_2d(np.asarray(x, dtype=float))
        if self.validation is None:
            nan = np.full(X.shape[0], np.nan)
            return nan, nan
        err = position_errors(self.layout, self.nominal, X, self.validation, self.registration, each,
                              self.correction if corrected else None)  # fmt: skip
        return np.sqrt(np.mean(err**2, axis=1)), np.max(err, axis=1)

    def param_error(self, x: ArrayLike) -> Array:
        """Distance to the true genome in the identifiable subspace, (P,); NaN if unknown. With
        fixed genes, ``truth`` and ``projector`` are the full genome's (the fixed genes count)."""
        X = np.atleast_2d(np.asarray(x, dtype=float))
        if self.truth is None or self.projector is None:
            return np.full(X.shape[0], np.nan)
        if X.shape[1] != self.truth.shape[-1]:
            X = self.layout.expand(X)
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
