"""How sure a calibration is: the covariance of the identified combinations and the predicted
position and orientation error at any pose (docs/model.md, section 3.3).

With ``J`` the pose rows (m, r) of the weighted residual's Jacobian at the calibrated genome z
(r identified combinations) and ``sigma`` (m,) each row's noise (the instrument's standard
deviations when the data give them, else the residual's: ``s^2 = |r|^2 / dof`` per group of
rows), the covariance of the estimate is

    C_z = (A^T A)^-1,   A = diag(1 / sigma) J          (Gauss-Markov; = s^2 (J^T W J)^-1)

and ``C = N C_z N^T`` in the full genome (N the genome's basis). What was left at nominal (the
dropped directions) carries the prior's covariance ``C_0`` (an error uniform within its
expected size along them, :class:`zrp_ga.model.subspace.Subspace`'s ``prior_factor``): it is
not estimated, and counts wherever those directions act (outside the poses that made them
unidentifiable). Both are kept as factors ``C = L L^T`` (K x r and K x d: never a K x K matrix). At a pose with Jacobian ``J_k`` (6, K) of the calibrated arm, the predicted
1-sigma position error radius is ``sqrt(tr(J_k^p C J_k^p^T))`` (the position rows; the same
for orientation, rad), and the predicted RMS error of measured points adds the measurement
noise: ``sqrt(mean_k tr(J_k^p (C + C_0) J_k^p^T) + 3 sigma_p^2)``.

Hand-written (numpy): the formulas are the point, and their pieces are checked in
tests/test_uncertainty.py against finite differences and a hand-computed covariance.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model import error_model, so3, terms
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
FILE = "uncertainty.json"


def factor(C: ArrayLike) -> Array:
    """``L`` with ``L L^T = C`` for a symmetric positive semi-definite C (r, r): its eigenvectors
    times the square roots of its eigenvalues (negative round-off clipped to 0)."""
    w, V = np.linalg.eigh(np.asarray(C, dtype=float))
    return V * np.sqrt(np.maximum(w, 0.0))


def covariance(J: ArrayLike, row_sigma: ArrayLike) -> Array:
    """``(A^T A)^+`` with ``A = diag(1 / row_sigma) J`` (m, r): the covariance (r, r) of a
    least-squares estimate under independent row noise of standard deviations ``row_sigma``
    (the pseudo-inverse, numpy's rank rule, for directions the rows do not see)."""
    A = np.asarray(J, dtype=float) / np.asarray(row_sigma, dtype=float)[:, None]
    return np.linalg.pinv(A.T @ A, hermitian=True)


def pose_jacobians(layout: Layout, nominal: ZRPRobot, x: ArrayLike, q: ArrayLike, tool: int = 0) -> Array:
    """Jacobians (M, 6, full_size) of ``[dr; dp]`` (rad, m) of tool ``tool``'s point at poses q
    (M, n) with respect to the full genome of ``layout`` (unmasked), at the genome ``x``
    (full_size,): the error Jacobian of the arm ``x`` describes, through the axes'
    normalisation and the hand's rotation vector as the cost has them
    (:meth:`zrp_ga.model.cost.CalibrationProblem.jacobian`)."""
    layout = layout.unmasked
    x = np.asarray(x, dtype=float)
    n, blocks = nominal.n, layout.blocks
    m = layout.unpack(nominal, x).for_tool(tool)
    raw = nominal.u0 + x[blocks["u0"]].reshape(n, 3)
    length = np.linalg.norm(raw, axis=1)
    unit = raw / length[:, None]
    core = 6 * n + 3 * layout.base + 3 * layout.hand
    poses: Array = np.atleast_2d(np.asarray(q, dtype=float))
    if layout.terms:  # the full model: the joints turned by the terms (features on the nominal arm, as the fit has them)
        assert m.theta is not None  # unpack sets the term genes whenever the layout has terms
        phi = terms.features(layout.terms, nominal, poses)
        poses = poses + terms.offsets(layout.terms, n, phi, m.theta[:, 0])
    Jc = error_model.jacobian_arrays(unit, m.B[:, :, 0], nominal.prismatic, poses, layout.base, layout.hand)
    if layout.hand:
        Jc[:, :3, blocks["hand"]] = Jc[:, :3, blocks["hand"]] @ so3.left_jacobian(x[blocks["hand"]])
    N = (np.eye(3) - unit[:, :, None] * unit[:, None, :]) / length[:, None, None]
    Ju = Jc[..., : 3 * n].reshape(Jc.shape[:2] + (n, 3))
    Jc[..., : 3 * n] = np.einsum("mrik,ikl->mril", Ju, N).reshape(Jc.shape[:2] + (3 * n,))
    J = np.zeros(Jc.shape[:2] + (layout.full_size,))
    J[..., :core] = Jc
    if layout.terms:  # d pose / d q_j times the term's feature
        import types

        arm = types.SimpleNamespace(u0=unit, b0=m.B[:, :, 0], R_h0=m.H[:, :, 0], prismatic=nominal.prismatic, n=n)
        J[..., blocks["terms"]] = terms.joint_jacobian(arm, poses)[:, :, layout.terms.joints] * phi[:, None, :]
    if tool:
        end = slice(6 * n - 3, 6 * n)
        J[..., blocks[f"tool{tool + 1}"]] = J[..., end]
        J[..., end] = 0.0
    return J


@dataclasses.dataclass(frozen=True)
class Uncertainty:
    """The covariance of a calibration and what it predicts (module docstring): the arm's
    ``nominal`` description and genome ``layout`` (tools included), the calibrated full genome
    ``x``, the factors (K, r) and (K, d) of the covariance of the identified combinations
    (``cov_factor``) and of what was left at nominal (``prior_factor``), in the full genome;
    the position noise per coordinate ``noise_m`` (m), and where the noise came from (``source``)."""

    layout: Layout
    nominal: ZRPRobot
    x: Array
    cov_factor: Array
    prior_factor: Array
    noise_m: float
    source: str = "residual"

    def predict(self, q: ArrayLike, tool: int = 0, offset_m: ArrayLike | None = None) -> dict[str, Array]:
        """Predicted 1-sigma errors at poses q (M, n) of tool ``tool``'s point, each (M,):
        ``position_m`` and ``orientation_rad`` from the identified combinations' covariance,
        ``position_unidentified_m`` and ``orientation_unidentified_rad`` from what was left at
        nominal (its prior), and ``position_total_m``, both together.

        ``offset_m`` (3,) or (M, 3), m: a point fixed to the hand at this vector from the tool's
        point (in the model's frame, at each pose) instead of the tool's point: its position
        error is ``dp + dr x d`` (a rigid lever arm), so its Jacobian's position rows are
        ``J_p - [d]x J_r``."""
        J = pose_jacobians(self.layout, self.nominal, self.x, q, tool)
        if offset_m is not None:
            d = np.broadcast_to(np.asarray(offset_m, dtype=float), (J.shape[0], 3))
            J = J.copy()
            J[:, 3:6] -= so3.skew(d) @ J[:, 0:3]
        radius = lambda L, rows: np.sqrt(np.sum((J[:, rows] @ L) ** 2, axis=(1, 2)))  # sqrt(tr(J L L^T J^T))
        pos, rot = slice(3, 6), slice(0, 3)
        C, C0 = self.cov_factor, self.prior_factor
        out = {"position_m": radius(C, pos), "orientation_rad": radius(C, rot),
               "position_unidentified_m": radius(C0, pos), "orientation_unidentified_rad": radius(C0, rot)}  # fmt: skip
        out["position_total_m"] = np.hypot(out["position_m"], out["position_unidentified_m"])
        return out

    def robot(self, tool: int = 0) -> ZRPRobot:
        """The calibrated arm this covariance is about (the model's frame), ending at tool
        ``tool``'s point: where :meth:`predict`'s ``offset_m`` starts."""
        return self.layout.robot(self.nominal, self.x, tool=tool)

    def position_m(self, q: ArrayLike, tool: ArrayLike | int = 0) -> Array:
        """The predicted 1-sigma position error radius (M,), m, both parts, at poses q (M, n);
        ``tool``: one tool index, or one per pose (a known tool without genes: the first tool's
        point stands in for it)."""
        q = np.atleast_2d(q)
        tools = np.broadcast_to(np.asarray(tool), (q.shape[0],))
        tools = np.where(tools < self.layout.n_tools, tools, 0)
        total = np.empty(q.shape[0])
        for t in np.unique(tools):
            total[tools == t] = self.predict(q[tools == t], int(t))["position_total_m"]
        return total

    def predicted_rms_m(self, q: ArrayLike, tool: ArrayLike | int = 0, noise: bool = True) -> float:
        """Predicted RMS position error (m) of measured points at poses q (M, n): the model's
        (:meth:`position_m`) plus, with ``noise``, the measurement noise ``3 noise_m^2``."""
        total = self.position_m(q, tool)
        return float(np.sqrt(np.mean(total**2) + (3 * self.noise_m**2 if noise else 0.0)))

    def to_dict(self) -> dict[str, Any]:
        L = self.layout
        return {"layout": {"n": L.n, "base": L.base, "hand": L.hand, "tools": [list(t) for t in L.tools], "terms": L.terms.to_dict()},
                "nominal": self.nominal.to_dict(), "x": self.x.tolist(), "cov_factor": self.cov_factor.tolist(),
                "prior_factor": self.prior_factor.tolist(), "noise_m": self.noise_m, "source": self.source}  # fmt: skip

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Uncertainty:
        L = d["layout"]
        spec, _ = terms.parse(L.get("terms"), "uncertainty.json: layout.terms")
        layout = Layout(int(L["n"]), base=bool(L["base"]), hand=bool(L["hand"]), tools=tuple(map(tuple, L["tools"])), terms=spec)
        arr = lambda k, cols: np.array(d[k], dtype=float).reshape(-1, cols) if cols is not None else np.array(d[k], dtype=float)
        K = layout.full_size
        return cls(layout, ZRPRobot.from_dict(d["nominal"]), arr("x", None), arr("cov_factor", None).reshape(K, -1),
                   arr("prior_factor", None).reshape(K, -1), float(d["noise_m"]), d.get("source", ""))  # fmt: skip

    def write(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict()))

    @classmethod
    def read(cls, run: str | Path) -> Uncertainty:
        """From a run directory's ``uncertainty.json`` (or that file)."""
        path = Path(run)
        path = path / FILE if path.is_dir() else path
        return cls.from_dict(json.loads(path.read_text()))


def predict_error_mm(run: str | Path, q: ArrayLike, tool: int = 0) -> Array:
    """For any program (compensation's rows): the predicted 1-sigma position error radius (mm),
    both parts, at joint values q (M, n) (the model's units: rad, m), from a finished run's
    directory (its ``uncertainty.json``)."""
    return Uncertainty.read(run).predict(q, tool)["position_total_m"] * 1e3
