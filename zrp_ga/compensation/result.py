"""A compensated program (:class:`Compensation`): per target, the corrected joint values and
Cartesian targets, the predicted residuals, the error of the program as written and the size of
the correction. Its tables and ``compensation.json`` are written by
:mod:`zrp_ga.compensation.writing`."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.compensation import writing
from zrp_ga.compensation.arms import Arms
from zrp_ga.compensation.program import Program
from zrp_ga.model import kinematics, so3

Array = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class Compensation:
    """The compensated program (:func:`zrp_ga.compensation.compensate.compensate`), per target
    (M rows): the corrected joint values ``q`` (M, n) (rad, m; NaN where not reached), the
    nominal solution ``q_nominal``, the targets ``p`` (M, 3) m and ``R`` (M, 3, 3) (None for
    positions) in the robot's base frame, the corrected Cartesian targets ``p_corrected``,
    ``R_corrected`` in the base frame (what a controller using the nominal model is sent), the
    predicted residuals and uncompensated errors (mm, deg), ``reasons`` (empty where reached),
    ``to_base`` (4, 4): the program's frame in the base frame (``frame`` names it), and
    ``predicted``: per target, how sure the calibrated model is at the corrected joints and
    where they lie against its calibration poses (:func:`predicted`; empty where the
    calibration has neither)."""

    program: Program
    arms: Arms
    q: Array
    q_nominal: Array
    p: Array
    R: Array | None
    p_corrected: Array
    R_corrected: Array
    residual_mm: Array
    residual_deg: Array
    uncompensated_mm: Array
    uncompensated_deg: Array
    reached: NDArray[np.bool_]
    reasons: tuple[str, ...]
    frame: str = "base"
    to_base: Array = dataclasses.field(default_factory=lambda: np.eye(4))
    frame_source: str = ""
    predicted: dict = dataclasses.field(default_factory=dict)

    @property
    def unreachable(self) -> list[str]:
        """``"line 7: why"`` for every target not reached."""
        return [f"{w}: {r}" for w, r, ok in zip(self.program.where, self.reasons, self.reached) if not ok]

    def correction(self) -> dict[str, Array]:
        """Size of the correction per target: the largest revolute joint change ``dq_deg`` and
        prismatic ``dq_mm`` (absent without prismatic joints), the Cartesian ``dx_mm`` and
        ``dr_deg`` (NaN where not reached)."""
        dq = np.abs(self.q - self.q_nominal)
        pri = self.arms.calibrated.prismatic
        out = {"dq_deg": np.degrees(dq[:, ~pri].max(axis=1, initial=0.0))}
        if pri.any():
            out["dq_mm"] = dq[:, pri].max(axis=1) * 1e3
        out["dx_mm"] = np.linalg.norm(self.p_corrected - self.p, axis=1) * 1e3
        R_ref, _ = kinematics.forward(self.arms.nominal, self.q_nominal)
        out["dr_deg"] = np.degrees(np.linalg.norm(so3.log(self.R_corrected @ np.swapaxes(R_ref, 1, 2)), axis=-1))
        return {k: np.where(self.reached, v, np.nan) for k, v in out.items()}

    def tables(self):
        """``joints.csv`` and ``targets.csv`` as pandas DataFrames (:func:`zrp_ga.compensation.writing.tables`)."""
        return writing.tables(self)

    def summary(self) -> dict[str, Any]:
        """What ``compensation.json`` holds (:func:`zrp_ga.compensation.writing.summary`)."""
        return writing.summary(self)

    def write(self, out: str | Path) -> dict[str, Path]:
        """``joints.csv``, ``targets.csv`` and ``compensation.json`` in ``out``
        (:func:`zrp_ga.compensation.writing.write`)."""
        return writing.write(self, out)


def evaluated(pr: Program, arms: Arms, q_cal: Array, q_nom: Array, p: Array, R: Array | None, reached, reasons,
              **where: Any) -> Compensation:  # fmt: skip
    """The :class:`Compensation` of solutions ``q_cal`` (calibrated) and ``q_nom`` (nominal)
    (M, n) of targets ``p`` (M, 3), ``R`` (M, 3, 3) or None: residuals ``FK_cal(q*) - T*``,
    errors as written ``FK_cal(q_nom) - T*``, corrected Cartesian targets ``FK_nom(q*)``."""
    cal, nom = arms.calibrated, arms.nominal
    R_after, p_after = kinematics.forward(cal, q_cal)
    R_before, p_before = kinematics.forward(cal, q_nom)
    if arms.residual is not None:  # the full model: the residual model's correction too (NaN rows stay NaN)
        ok_after, ok_before = np.all(np.isfinite(q_cal), axis=1), np.all(np.isfinite(q_nom), axis=1)
        p_after[ok_after] += arms.correction(q_cal[ok_after])
        p_before[ok_before] += arms.correction(q_nom[ok_before])
    R_corr, p_corr = kinematics.forward(nom, q_cal)
    angle = lambda A: np.degrees(np.linalg.norm(so3.log(A @ np.swapaxes(R, 1, 2)), axis=-1)) if R is not None else np.zeros(pr.M)
    q = np.where(reached[:, None], q_cal, np.nan)
    return Compensation(
        pr, arms, q, q_nom, p, R, p_corr, R_corr,
        residual_mm=np.linalg.norm(p_after - p, axis=1) * 1e3, residual_deg=angle(R_after),
        uncompensated_mm=np.linalg.norm(p_before - p, axis=1) * 1e3, uncompensated_deg=angle(R_before),
        reached=reached, reasons=tuple(reasons), predicted=predicted(arms, q, orientations=R is not None), **where,
    )  # fmt: skip


def predicted(arms: Arms, q: Array, orientations: bool = True) -> dict[str, Any]:
    """Per target at the corrected joints q (M, n) (NaN rows: not reached, NaN there): the
    calibrated model's predicted 1-sigma error at the program's point, ``sigma_mm`` (position
    radius; with a residual model its predictive standard deviation added, ``sqrt(3) s`` in
    quadrature: the process's own uncertainty, which grows to its prior's away from the
    calibration poses) and, with ``orientations``, ``sigma_deg`` (the calibration's covariance,
    :meth:`zrp_ga.model.uncertainty.Uncertainty.predict`, carried from its measured point to the
    program's by the lever arm between them, in the instrument's frame); and where q lies against
    the calibration poses (:mod:`zrp_ga.model.coverage`): ``outside`` (bool), ``distance_ratio``
    (the distance to the nearest calibration pose over their own spacing) and how far beyond
    the calibrated joint ranges, ``beyond_range_deg`` (revolute joints, the largest) and
    ``beyond_range_mm`` (prismatic). Only what the calibration carries (a robot file alone:
    nothing)."""
    ok = np.all(np.isfinite(q), axis=1)
    M, out = len(q), dict[str, Any]()
    u, c = arms.uncertainty, arms.coverage
    if u is not None:
        sigma, turn = np.full(M, np.nan), np.full(M, np.nan)
        if ok.any():
            B = np.eye(4) if arms.base is None else arms.base
            _, p = kinematics.forward(arms.calibrated, q[ok])
            _, at = kinematics.forward(u.robot(0), q[ok])
            e = u.predict(q[ok], 0, offset_m=p @ B[:3, :3].T + B[:3, 3] - at)
            gp = arms.residual_spread(q[ok])  # the residual model's own uncertainty, as a radius
            sigma[ok] = np.hypot(e["position_total_m"], gp) * 1e3
            turn[ok] = np.degrees(np.hypot(e["orientation_rad"], e["orientation_unidentified_rad"]))
        out["sigma_mm"] = sigma
        if orientations:
            out["sigma_deg"] = turn
    if c is not None and c.q.shape[1] == q.shape[1]:
        outside, ratio = np.zeros(M, dtype=bool), np.full(M, np.nan)
        excess = np.full(q.shape, np.nan)
        if ok.any():
            a = c.assess(q[ok])
            outside[ok], ratio[ok], excess[ok] = a.outside, a.ratio, a.excess
        out["outside"], out["distance_ratio"] = outside, ratio
        pri = arms.calibrated.prismatic
        out["beyond_range_deg"] = np.degrees(np.max(excess[:, ~pri], axis=1, initial=0.0)) if (~pri).any() else None
        out["beyond_range_mm"] = np.max(excess[:, pri], axis=1, initial=0.0) * 1e3 if pri.any() else None
        out = {k: v for k, v in out.items() if v is not None}
        for k in ("beyond_range_deg", "beyond_range_mm"):
            if k in out:
                out[k] = np.where(ok, out[k], np.nan)
    return out
