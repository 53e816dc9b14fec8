"""What a compensation writes: ``joints.csv``, ``targets.csv`` and ``compensation.json``, in
the program's own units and orientation convention, so that a programmer can paste them.

Every column of a number carries its unit (``q1_deg``, ``q3_mm``, ``x_mm``, ``A_deg``;
quaternions and branch numbers have none); the orientation columns have the convention's own
names (:mod:`zrp_ga.compensation.orientation`), each angle the turn nearest the program's own
where it gave one; each row carries the branch its corrected joints are on
(:mod:`zrp_ga.compensation.configuration`). How sure each row is, where the calibration
carries it (a run directory or a calibration, not a robot file alone): ``sigma_mm`` and
``sigma_deg``, the calibrated model's predicted 1-sigma position and orientation error at the
corrected joints and the program's point (its parameter covariance,
:mod:`zrp_ga.model.uncertainty`), and ``outside``, ``distance_ratio``, ``beyond_range_deg``
(``beyond_range_mm``), where the corrected joints lie against the calibration poses
(:mod:`zrp_ga.model.coverage`); ``compensation.json`` says what each means under ``predicted``.
The corrected Cartesian targets are in the program's
frame when that is a work object (to be used with the work object as ``compensation.json``
gives it in the base frame), in the robot's base frame otherwise.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.compensation import configuration, frames, orientation
from zrp_ga.core.checks import ROTVEC
from zrp_ga.io.measurements import ANGLE, LENGTH

Compensation = Any  # a zrp_ga.compensation.result.Compensation (which imports this module to write itself)

Array = NDArray[np.float64]
FILES = {"joints": "joints.csv", "targets": "targets.csv", "summary": "compensation.json"}


def tables(c: Compensation):
    """``joints.csv`` and ``targets.csv`` (pandas DataFrames): line, status, the corrected joint
    values (joints) or Cartesian targets (targets) in the program's units, the branch, the
    residuals and the correction sizes."""
    import pandas as pd

    pr, ok = c.program, c.reached
    head = {"line": [w.split()[-1] for w in pr.where],
            "status": ["ok" if r else f"unreachable: {why}" for r, why in zip(ok, c.reasons)]}  # fmt: skip
    branch = {k: pd.array(np.where(np.isfinite(v), v, np.nan), dtype="Int64") for k, v in configuration.table(c.arms.nominal, c.q).items()}
    stats = {k: np.where(ok, v, np.nan) for k, v in _stats(c).items()}
    stats.update({k: pd.array(np.where(ok, v, None), dtype="boolean") if v.dtype == bool else np.where(ok, v, np.nan)
                  for k, v in c.predicted.items()})  # fmt: skip
    joints = pd.DataFrame({**head, **joint_columns(c), **branch, **stats})
    targets = pd.DataFrame({**head, **target_columns(c), **branch, **stats})
    return joints, targets


def joint_columns(c: Compensation) -> dict[str, Array]:
    """The corrected joint values in the program's units, named with them (``q1_deg``)."""
    pr, robot = c.program, c.arms.calibrated
    out = {}
    for j, (name, t) in enumerate(zip(pr.joint_columns, robot.joint_types)):
        unit = pr.length_unit if t == "P" else pr.angle_unit
        out[f"{name}_{unit}"] = c.q[:, j] / (LENGTH[unit] if t == "P" else ANGLE[unit])
    return out


def target_columns(c: Compensation) -> dict[str, Array]:
    """The corrected Cartesian targets (the program's frame when it is a work object, else the
    base frame) in the program's units and orientation convention."""
    pr = c.program
    T = frames.inverse(c.to_base) if c.frame == "work object" else np.eye(4)
    p, R = frames.apply(T, c.p_corrected, c.R_corrected)
    L = LENGTH[pr.length_unit]
    out = {f"{k}_{pr.length_unit}": np.where(c.reached, p[:, j] / L, np.nan) for j, k in enumerate("xyz")}
    convention = pr.convention or ROTVEC
    near = pr.angles if pr.angles is not None and orientation.is_angle(convention) and c.frame != "instrument" else None
    values = orientation.from_matrices(R, convention, near)
    scale = ANGLE[pr.orientation_unit] if orientation.is_angle(convention) else 1.0
    suffix = f"_{pr.orientation_unit}" if orientation.is_angle(convention) else ""
    for j, name in enumerate(orientation.columns(convention)):
        out[f"{name}{suffix}"] = np.where(c.reached, values[:, j] / scale, np.nan)
    return out


def _stats(c: Compensation) -> dict[str, Array]:
    cols = {"residual_mm": c.residual_mm, "uncompensated_mm": c.uncompensated_mm}
    if c.R is not None:
        cols.update(residual_deg=c.residual_deg, uncompensated_deg=c.uncompensated_deg)
    cols.update(c.correction())
    return cols


def summary(c: Compensation) -> dict[str, Any]:
    """What ``compensation.json`` holds: sources, frames (the program's, the base setup, the
    flange, the work object in the base frame), units and columns, counts, the largest and RMS
    residuals and corrections, the unreachable targets, and the notes (what the data leave open,
    with its size)."""
    ok = c.reached
    stat = lambda v: {"max": float(np.max(v[ok])), "rms": float(np.sqrt(np.mean(v[ok] ** 2)))} if ok.any() else None
    pr, arms = c.program, c.arms
    convention = pr.convention or ROTVEC
    return {
        "calibration": arms.source, "program": pr.source, "kind": pr.kind,
        "calibrated_robot": arms.calibrated.name, "nominal_robot": arms.nominal.name,
        "frame": c.frame, "frame_source": c.frame_source,
        "targets_frame": "the work object" if c.frame == "work object" else "the robot's base frame (the nominal model's, the controller's)",
        **_frames(c),
        "targets": "poses" if c.R is not None else "positions",
        "units": {"length": pr.length_unit, "joint_angle": pr.angle_unit, "orientation_angle": pr.orientation_unit,
                  "orientation_convention": convention, "orientation_columns": list(orientation.columns(convention)),
                  "whose": orientation.WHOSE.get(convention, f"the Euler sequence {convention} (scipy)")},
        "rows": pr.M, "reached": int(ok.sum()), "unreachable": c.unreachable,
        "stats": {k: stat(v) for k, v in _stats(c).items()},
        "predicted": _predicted_summary(c, stat), "notes": list(arms.notes),
    }  # fmt: skip


PREDICTED = {
    "sigma_mm": "the calibrated model's predicted 1-sigma position error at the corrected joints, at the program's point "
                "(from the calibration's parameter covariance: zrp_ga.model.uncertainty), mm",
    "sigma_deg": "the same for the orientation, deg (a calibration of positions alone did not fit the hand's own turn, "
                 "which is then not in it)",
    "outside": "the corrected joints lie outside the region the calibration poses cover (a joint beyond its calibrated "
               "range, or farther from every calibration pose than they lie from each other: zrp_ga.model.coverage)",
    "distance_ratio": "the distance (joint space) to the nearest calibration pose over the calibration poses' own spacing",
    "beyond_range_deg": "how far the corrected joints lie beyond the calibrated joint ranges (revolute, the largest), deg",
    "beyond_range_mm": "the same for prismatic joints, mm",
}  # fmt: skip


def _predicted_summary(c: Compensation, stat) -> dict[str, Any]:
    """The columns of how sure the correction is, what each means, their largest and RMS values
    and the share of targets outside the calibration's region; why not, where the calibration
    carries none."""
    p = c.predicted
    if not p:
        return {"columns": {}, "why_not": f"{c.arms.source} carries no covariance or calibration poses (a robot file "
                                          "alone); compensate with a run directory or a calibration to have them"}  # fmt: skip
    out: dict[str, Any] = {"columns": {k: PREDICTED[k] for k in p}}
    if "sigma_mm" not in p:
        out["why_no_sigma"] = "the calibration has no covariance (it returned the nominal arm, or left no degrees of freedom)"
    ok = c.reached
    for k, v in p.items():
        if k != "outside":
            out[k] = stat(np.asarray(v, dtype=float))
    if "outside" in p:
        out["share_outside"] = float(np.mean(p["outside"][ok])) if ok.any() else None
    return out


def _frames(c: Compensation) -> dict[str, Any]:
    """The base setup, the flange and, for a work object, its pose in the base frame (4, 4) and
    in the program's units and convention, to enter in the controller."""
    out: dict[str, Any] = {"base_setup": c.arms.frames.get("base"), "flange": c.arms.frames.get("flange")}
    if c.arms.base is not None:
        out["base_in_instrument"] = c.arms.base.tolist()
    if c.frame == "work object":
        pr, W = c.program, c.to_base
        convention = pr.convention or ROTVEC
        values = orientation.from_matrices(W[None, :3, :3], convention)[0]
        scale = ANGLE[pr.orientation_unit] if orientation.is_angle(convention) else 1.0
        suffix = f"_{pr.orientation_unit}" if orientation.is_angle(convention) else ""
        pose = {f"{k}_{pr.length_unit}": float(W[j, 3] / LENGTH[pr.length_unit]) for j, k in enumerate("xyz")}
        pose.update({f"{k}{suffix}": float(v / scale) for k, v in zip(orientation.columns(convention), values)})
        out["work_object_in_base"] = {"pose": pose, "matrix": W.tolist()}
    return out


def write(c: Compensation, out: str | Path) -> dict[str, Path]:
    """``joints.csv``, ``targets.csv`` and ``compensation.json`` in ``out`` (created); an
    OSError (a full disk) is one ValueError naming the file."""
    from zrp_ga.core import fileio

    out = Path(out)
    paths = {k: out / name for k, name in FILES.items()}
    joints, targets = tables(c)
    try:
        out.mkdir(parents=True, exist_ok=True)
        joints.to_csv(paths["joints"], index=False, na_rep="")
        targets.to_csv(paths["targets"], index=False, na_rep="")
        fileio.write_json(paths["summary"], summary(c))
    except OSError as exc:
        raise ValueError(f"out: cannot write {exc.filename or out}: {exc.strerror or exc}") from None
    return paths
