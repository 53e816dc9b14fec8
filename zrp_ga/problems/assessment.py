"""How far a calibration can be trusted, for ``summary.json``, the console and
:func:`zrp_ga.calibrate`'s result: what the data identified and what was left at nominal, the
uncertainty of the result (:mod:`zrp_ga.model.uncertainty`) and what it predicts on the
validation poses against what was measured there, where the validation poses lie against the
calibration's coverage (:mod:`zrp_ga.model.coverage`), the outliers, and whether the model is
predicted to be worse than the nominal arm over its own coverage.
"""

from __future__ import annotations

import copy
import dataclasses
import weakref
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.model import metrics, subspace
from zrp_ga.model.coverage import MOST, Coverage
from zrp_ga.model.uncertainty import Uncertainty
from zrp_ga.problems import Task, identify

Array = NDArray[np.float64]
SUBSPACE_MOVED_RAD = 0.05  # the identified directions at the result this far from those searched: a warning
FLOOR_MM = 1e-6  # predicted model errors closer than a nanometre are the same (round-off: a perfect arm's 3e-14 mm against 0)


@dataclasses.dataclass
class Assessment:
    """The entries for ``summary.json`` (``identified``, ``uncertainty``, ``coverage``,
    ``outliers``), the warnings, the :class:`Uncertainty` and :class:`Coverage` (their files),
    and whether the model is predicted to be worse than nominal over its own coverage (the
    warning's words, :meth:`worse_note`)."""

    entries: dict[str, Any]
    warnings: list[str]
    uncertainty: Uncertainty | None
    coverage: Coverage
    predicted_worse: bool
    beyond: list[str] = dataclasses.field(default_factory=list)  # the warning about the model across the joint limits (for a returned model)

    def worse_note(self, then: str = "") -> list[str]:
        """The warning that the model is predicted worse than nominal (none when it is not),
        ending with ``then`` (what is returned instead)."""
        if not self.predicted_worse:
            return []
        p = self.entries["uncertainty"]["predicted_model_rms_mm"]
        return [f"the calibrated model is predicted to be worse than the nominal one over its own coverage "
                f"({p['calibrated']:.4g} mm > {p['nominal']:.4g} mm RMS at the calibration poses){then}"]  # fmt: skip


def assess(task: Task, x: Array, val_rms_m: float) -> Assessment:
    """The assessment of the calibrated genome ``x`` (the problem's genome) whose measured
    validation RMS is ``val_rms_m`` (NaN: no validation poses). What does not depend on ``x``
    is computed once per problem instance (:func:`_fixed`: the runs of a sweep's batch share it)."""
    p, setup = task.problem, task.setup
    unc = identify.uncertainty(p, x, setup)
    fixed = _fixed(task)
    cov = fixed.coverage
    out: dict[str, Any] = {"identified": identified(task, x), "outliers": copy.deepcopy(fixed.outliers),
                           "coverage": copy.deepcopy(fixed.coverage_entry)}  # fmt: skip
    notes: list[str] = list(fixed.coverage_notes)
    worse = False
    across_note: list[str] = []
    u: dict[str, Any] = {"available": unc is not None}
    if unc is not None:
        u.update(_uncertainty_entries(task, x, unc, val_rms_m))
        worse = bool(u["predicted_model_rms_mm"]["calibrated"] > u["predicted_model_rms_mm"]["nominal"] + FLOOR_MM)
        u["across_joint_limits_mm"] = across = _across_limits(task, unc, cov)
        across_note = _beyond_note(across, max(u["predicted_model_rms_mm"]["nominal"], u["noise_mm"]))
    else:
        u["why"] = "the data leave no residual degrees of freedom to estimate the noise"
    out["uncertainty"] = u
    notes += _outlier_notes(out["outliers"]) + _moved_note(out["identified"])
    return Assessment(out, notes, unc, cov, worse, across_note)


@dataclasses.dataclass
class _Fixed:
    """What the assessment of any genome of one problem instance shares: the coverage and its
    entry and notes, the outliers, the identified entry but for the result's own part, the
    subspace seen at the first fit, the nominal arm's errors and the poses across the limits."""

    coverage: Coverage
    coverage_entry: dict[str, Any]
    coverage_notes: list[str]
    outliers: dict[str, Any]
    identified: dict[str, Any]
    first_fit_seen: Any  # subspace.Subspace | None (no set-up with a subspace: unused)
    nominal_ms: float  # the nominal arm's mean squared position error at the calibration poses, m^2
    across_q: Array
    across_share: Array


_FIXED: dict[int, tuple[weakref.ref[Task], tuple[int, ...], _Fixed]] = {}


def _fixed(task: Task) -> _Fixed:
    """:class:`_Fixed` of ``task``, computed at its first assessment (kept while the task lives
    and its problem, data, judge and set-up are the same objects)."""
    p = task.problem
    key = (id(p), id(p.data), id(task.judge), id(task.judge.validation), id(task.setup))
    held = _FIXED.get(id(task))
    if held is not None and held[0]() is task and held[1] == key:
        return held[2]
    cov = Coverage(p.data.q)
    entry: dict[str, Any] = {"joint_ranges": np.column_stack([cov.lower, cov.upper]).tolist(), "gap": cov.gap}
    notes: list[str] = []
    val = task.judge.validation
    if val is not None:
        where = cov.assess(val.q)
        entry["validation"] = where.summary()
        entry["validation_is_extrapolation"] = bool(where.share_outside > MOST)
        if where.share_outside > MOST:
            joints = [str(j + 1) for j, s in enumerate(np.mean(where.beyond, axis=0)) if s > MOST]
            beyond = f" (joint{'s' * (len(joints) > 1)} {', '.join(joints)} beyond the calibrated range)" if joints else ""
            notes.append(f"{where.share_outside:.0%} of the validation poses lie outside the joint-space region the calibration "
                         f"poses cover{beyond}: the validation is extrapolation and says little about the calibrated "
                         "region (validate within it, or calibrate over the region the arm will work in)")  # fmt: skip
    setup = task.setup
    seen = _seen(task, setup.x) if setup is not None and setup.subspace is not None else None
    nominal_err = metrics.position_errors(p.layout, p.nominal, np.zeros(p.layout.size), p.data)
    limits = p.nominal.joint_limits
    across_q = np.random.default_rng(0).uniform(limits[:, 0], limits[:, 1], size=(ACROSS_POSES, len(limits)))
    share = (cov.upper - cov.lower) / (limits[:, 1] - limits[:, 0])
    fixed = _Fixed(cov, entry, notes, outliers(task), _identified(task), seen, float(np.mean(nominal_err**2)), across_q, share)
    for k in [k for k, (ref, _, _) in _FIXED.items() if ref() is None]:  # instances gone
        del _FIXED[k]
    _FIXED[id(task)] = (weakref.ref(task), key, fixed)
    return fixed


def identified(task: Task, x: Array) -> dict[str, Any]:
    """What the data identify (``summary.json``'s ``identified``): the genome's kind and size,
    the rule, the dropped combinations in words, the noise, and the identified directions
    computed again at the result (rank and largest angle to those searched)."""
    fixed = _fixed(task)
    entry = copy.deepcopy(fixed.identified)
    if task.setup is not None and task.setup.subspace is not None:
        entry["at_result"] = _at_result(task, x, fixed.first_fit_seen)
    return entry


def _identified(task: Task) -> dict[str, Any]:
    """:func:`identified` but for the result's own part (``at_result``)."""
    setup = task.setup
    if setup is None:
        return {"subspace": "full", "genes": task.problem.layout.size}
    s = setup.subspace
    entry: dict[str, Any] = {"subspace": "full" if s is None else "identified", "genes": task.problem.layout.size,
                             "parameters": setup.layout.size, "seen_at_nominal": setup.exact_rank,
                             "noise": setup.noise.to_dict(), "first_fit": {"cost": setup.cost, "nevals": setup.nevals}}  # fmt: skip
    if s is None:
        return entry
    n = task.problem.nominal.n
    arm = setup.layout.robot(task.problem.nominal, setup.x)
    assert setup.problem is not None  # prepare() gives it
    U = setup.problem.J_nominal[-n:]
    entry.update(rule=s.rule(), max_se=s.max_se, rank=s.rank, combinations=len(s.singular_values),
                 dropped=len(s.singular_values) - s.rank,
                 dropped_combinations=subspace.describe(s, setup.layout.names, arm, U),
                 standard_errors_expected=None if s.standard_errors is None else s.standard_errors[: s.rank].round(4).tolist())  # fmt: skip
    return entry


def _seen(task: Task, at: Array) -> subspace.Subspace | None:
    """Rule 1 (the directions the poses see at all) at the set-up's point ``at``; None where
    the poses see none."""
    setup = task.setup
    assert setup is not None and setup.problem is not None  # called on a task with a set-up
    n = task.problem.nominal.n
    J = identify.plain(setup.problem, "jacobian", at)
    try:
        return subspace.identify(J[:-n], J[-n:], setup.prior, None)
    except ValueError:
        return None


def _at_result(task: Task, x: Array, then: subspace.Subspace | None) -> dict[str, Any]:
    """Rule 1 (the directions the poses see at all) applied again at the result ``x`` and at
    the first fit's point, where the genome was chosen (``then``, :func:`_seen` there): their
    numbers and the largest principal angle (rad) between them. (Directions near the noise
    threshold, rule 2, come and go with any refit; these do not unless the fit moved the arm
    where other combinations are seen.)"""
    setup = task.setup
    assert setup is not None  # called by identified() on a task with a set-up
    now = _seen(task, setup.layout.restrict(task.problem.layout.expand(x)))
    if now is None or then is None:
        return {"rank": 0 if now is None else now.rank, "first_fit_rank": 0 if then is None else then.rank, "angle_rad": float(np.pi / 2)}
    return {"rank": now.rank, "first_fit_rank": then.rank, "angle_rad": subspace.principal_angle(now.basis, then.basis)}


def outliers(task: Task) -> dict[str, Any]:
    setup = task.setup
    if setup is None:
        return {"found": []}
    return {"found": setup.outliers, "dropped": setup.dropped, "change": setup.change,
            "loss": getattr(task.problem, "loss", "linear"),
            "loss_scale_mm": None if setup.loss_scale is None else setup.loss_scale * 1e3}  # fmt: skip


def _uncertainty_entries(task: Task, x: Array, unc: Uncertainty, val_rms_m: float) -> dict[str, Any]:
    """Standard errors, predicted model error at the calibration poses (calibrated and
    nominal), predicted and measured validation RMS."""
    p = task.problem
    L = p.layout.restrict(unc.cov_factor.T).T  # G L: the genome's covariance factor
    se = np.sqrt(np.sum(L**2, axis=1))
    data = p.data
    model = unc.predicted_rms_m(data.q, data.tools, noise=False)
    nominal_model = np.sqrt(max(_fixed(task).nominal_ms - 3 * unc.noise_m**2, 0.0))
    pred_cal = unc.predict(data.q[data.tools == 0])
    entry = {"noise_mm": unc.noise_m * 1e3, "noise_source": unc.source,
             "standard_errors": dict(zip(p.names, se.tolist())),
             "calibration_poses_mm": {"identified_rms": _rms(pred_cal["position_m"]) * 1e3,
                                      "unidentified_rms": _rms(pred_cal["position_unidentified_m"]) * 1e3,
                                      "orientation_mrad_rms": _rms(pred_cal["orientation_rad"]) * 1e3},
             "predicted_model_rms_mm": {"calibrated": model * 1e3, "nominal": float(nominal_model) * 1e3}}  # fmt: skip
    val = task.judge.validation
    if val is not None:
        predicted = unc.predicted_rms_m(val.q, val.tools)
        entry["validation_rms_mm"] = {"predicted": predicted * 1e3, "measured": val_rms_m * 1e3,
                                      "measured_over_predicted": val_rms_m / predicted if predicted > 0 else float("nan")}  # fmt: skip
    return entry


ACROSS_POSES, NARROW = 200, 0.05  # poses drawn across the joint limits; a joint moved over less than this share of its limits


def _across_limits(task: Task, unc: Uncertainty, cov: Coverage) -> dict[str, Any]:
    """The model's predicted position error (1-sigma radius, RMS, mm) at ``ACROSS_POSES`` poses
    drawn uniformly within the arm's joint limits (a fixed draw), of the identified combinations
    and of those left at nominal (their prior), and the joints the calibration poses moved over
    less than ``NARROW`` of their limits: what the calibration says away from its own poses."""
    fixed = _fixed(task)
    pred = unc.predict(fixed.across_q)
    share = fixed.across_share
    return {"identified_rms": _rms(pred["position_m"]) * 1e3, "unidentified_rms": _rms(pred["position_unidentified_m"]) * 1e3,
            "total_rms": _rms(pred["position_total_m"]) * 1e3, "poses": ACROSS_POSES,
            "narrow_joints": [j + 1 for j in np.flatnonzero(share < NARROW).tolist()]}  # fmt: skip


def _beyond_note(across: dict[str, Any], nominal_mm: float) -> list[str]:
    """A warning when the model is predicted to be further off across the joint limits than the
    nominal arm was measured to be at the calibration poses (its error less the noise; at least
    the noise: a perfect arm's fit is not warned about its 0.01 mm against 0): the calibration
    then holds only within the region its poses cover."""
    if not np.isfinite(across["total_rms"]) or across["total_rms"] <= nominal_mm + FLOOR_MM:
        return []
    narrow = across["narrow_joints"]
    moved = f"; joint{'s' * (len(narrow) > 1)} {', '.join(map(str, narrow))} barely moved in the calibration data" if narrow else ""
    return [f"away from its calibration poses the model is predicted to be {across['total_rms']:.3g} mm off (RMS of the "
            f"1-sigma error at {across['poses']} poses across the joint limits, {across['unidentified_rms']:.3g} mm of it from "
            f"what the data could not identify), more than the nominal arm's {nominal_mm:.3g} mm at the calibration poses"
            f"{moved}: use it within the joint ranges the calibration covers (coverage in summary.json; "
            "Calibration.predict gives the error at any pose), or calibrate over the region the arm will work in"]  # fmt: skip


def _rms(a: Array) -> float:
    return float(np.sqrt(np.mean(np.square(a)))) if np.size(a) else float("nan")


def _outlier_notes(o: dict[str, Any]) -> list[str]:
    found = o.get("found") or []
    if not found:
        return []
    listed = ", ".join(f"{f['where']} ({f['size_mm']:.3g} mm)" for f in found[:8]) + (" ..." if len(found) > 8 else "")
    what = "dropped and the fit repeated without them" if o.get("dropped") else "kept (problem.outliers=drop fits without them)"
    return [f"{len(found)} point(s) of {found[0]['file']} lie far beyond the noise: {listed}; {what}"]


def _moved_note(entry: dict[str, Any]) -> list[str]:
    now = entry.get("at_result")
    if not now or (now["rank"] == now["first_fit_rank"] and now["angle_rad"] <= SUBSPACE_MOVED_RAD):
        return []
    return [f"at the result the poses see {now['rank']} combinations ({now['first_fit_rank']} where the genome was chosen; "
            f"largest angle {now['angle_rad']:.3g} rad): the fit moved the arm where other combinations are seen"]  # fmt: skip
