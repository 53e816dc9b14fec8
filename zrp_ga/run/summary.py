"""What a run says about itself: the identifiability of its data before it starts, and after
it ends its files (``best_params.csv``, ``initial_population.csv``, the calibrated arm as robot
files, the problem kind's own, ``summary.json``), the warnings when something is not what it
seems, and the console lines.

What is returned. The reported genome is the optimiser's best, gauge-fixed for the nonlinear
cost. When that genome fits the calibration data worse than the nominal arm (or the optimiser
diverged) on a task that says so (measured data: ``Task.nominal_if_worse``), the nominal arm is
returned instead: ``best_genome`` is all zero, the robot files are the nominal arm's,
``final_cost`` is the nominal cost, ``returned`` is ``"nominal"``, the optimiser's own best cost
stays in ``optimiser_cost`` and a warning says so. In simulated studies the optimiser's result
is kept (``returned: "optimiser"``) so that benchmarks see what each optimiser found; the
warning is the same.

Robot files (:func:`write_robot`, :func:`zrp_ga.io.robot_files.write_robot_files`): every run
writes ``calibrated_robot.urdf`` (the robot alone, from its own base frame: its forward
kinematics from the root link to the hand is the calibrated model's,
:func:`zrp_ga.model.kinematics.forward`), ``calibrated_robot_dh.yaml`` and
``calibrated_robot_mdh.yaml`` (standard and modified DH in the nominal table's conventions, with
``_dh_corrections.csv`` and ``_mdh_corrections.csv`` beside them; the remaining mismatch in each
header and in ``summary.json``), ``calibrated_robot.yaml`` (ZRP), ``calibrated_robot_frames.yaml``
(base and tool transforms as 4x4 matrices and as xyz + quaternion; every tool under ``tools``)
and, for a Universal Robots arm, ``calibrated_robot_default_kinematics.yaml`` (ur_description's).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga.algorithms import Result
from zrp_ga.core.errors import warn
from zrp_ga.core.schema import Config, Cost, Objective
from zrp_ga.io import records, robot_files
from zrp_ga.model import error_model
from zrp_ga.problems import Task
from zrp_ga.problems.assessment import FLOOR_MM
from zrp_ga.problems.protocol import SelfJudging
from zrp_ga.run import directory
from zrp_ga.run.shared import Cache

log = logging.getLogger("zrp_ga")

Summary = dict[str, Any]  # summary.json's entries


def model_rank(task: Task) -> int:
    """Rank of the error Jacobian over many random poses with this problem's kind of data and
    its layout (tools included): what the model can identify at best (the calibration data can
    only carry less)."""
    from zrp_ga.model.cost import model_rank as rank

    p = task.problem
    return rank(p.nominal, task.layout, p.data.position_only)


def diagnostics(task: Task, first: bool, key: str, cache: Cache, sweep: Path | None = None) -> dict[str, Any]:
    """The identifiability of the calibration data, and a warning when it carries less than the
    model could identify (one line, the directions in the log files; once per sweep for each
    text; not again when resuming).
    ``key``: the problem instance's key; the figures are computed once per instance in this
    process (``cache``) and once per ``sweep``, which keeps them beside its manifest."""
    d = cache.diagnostics.get(key)
    if d is None:
        d = cache.diagnostics[key] = directory.shared(sweep, key, lambda: _compute(task), "diagnostics")
    if d["rank"] < d["model_rank"] and first and directory.first_to_ask(sweep, identifiability_line(d)):  # once a sweep
        warn(identifiability_line(d), log, details=[f"unidentifiable: {u}" for u in d["unidentifiable"]])
    return d


def identifiability_line(d: dict[str, Any]) -> str:
    """The one console line of the identifiability warning (:func:`diagnostics`' figures
    ``d``): what (the combinations the poses identify), how bad (how many stay at nominal),
    what to do (more, or more varied, poses) and where the directions are listed."""
    left = d["model_rank"] - d["rank"]
    return (f"the calibration poses identify {d['rank']} of the {d['model_rank']} parameter combinations the model can "
            f"identify ({d['n_params']} parameters): {left} stay at nominal; more (or more varied) poses would identify "
            "them (the directions: summary.json's identifiability, and the log)")  # fmt: skip


def _compute(task: Task) -> dict[str, Any]:
    report = task.identifiability()  # plain numbers, as they read back from JSON
    return {"rank": int(report.rank), "model_rank": model_rank(task), "n_params": int(report.n_params),
            "condition_number": float(report.condition_number), "unidentifiable": list(report.null_directions)}  # fmt: skip


ROUND_OFF = directory.ROUND_OFF
UNCERTAINTY, COVERAGE = "uncertainty.json", "coverage.json"
FLOOR_M = FLOOR_MM * 1e-3  # validation errors closer than the assessment's nanometre are the same (a perfect arm's fit: 2.6e-16 m against 2.3e-16)
COST_FLOOR = 1e-12  # costs (m-like) closer than this are the same


def floor(task: Task, key: str | None = None, cache: Cache | None = None, sweep: Path | None = None) -> dict[str, Any]:
    """The instance's floor: Levenberg-Marquardt's final cost from the nominal model (``cost``,
    as zrp-ga-report reads it; its evaluations ``lm_nevals`` and validation RMS ``lm_val_rms_mm``,
    the report's reference, too), and ``reference`` = max(floor, ROUND_OFF x nominal cost), the
    cost the objective ``over_floor`` divides by. With ``key``, computed once per instance in this
    process (``cache``) and once per ``sweep`` (kept beside its manifest, as :func:`diagnostics` is)."""
    if key is None or cache is None:
        return _lm_floor(task)
    d = cache.floors.get(key)
    if d is None:
        d = cache.floors[key] = directory.shared(sweep, key, lambda: _lm_floor(task), "floor")
    return d


def _lm_floor(task: Task) -> dict[str, Any]:
    from zrp_ga.algorithms.lm import LM

    p = task.problem
    lm = LM().run(p, np.random.default_rng(0))
    nominal = float(p.costs(np.zeros(p.lower.size))[0])
    best = min(lm.cost, nominal) if np.isfinite(lm.cost) else nominal
    x = lm.x if lm.x is not None and best == lm.cost else np.zeros(p.lower.size)
    val_mm = float(task.judge.validation_errors(x)[0][0]) * 1e3  # the reference's validation error, for the report
    return {"cost": float(best), "reference": max(float(best), ROUND_OFF * nominal), "lm_nevals": int(lm.nevals),
            "lm_val_rms_mm": val_mm if np.isfinite(val_mm) else None}


def objective(cfg: Config, task: Task, written: Summary, key: str, cache: Cache, sweep: Path | None) -> float:
    """What the run returns to a sweeper (``objective``): the final cost, or the final cost over
    the instance's floor's reference (:func:`floor`, then also in ``written`` as ``floor``)."""
    if cfg.objective is Objective.over_floor:
        written["floor"] = floor(task, key, cache, sweep)
        return float(written["final_cost"]) / float(written["floor"]["reference"])
    return float(written["final_cost"])


def worse_than_nominal(result: Result, nominal_cost: float) -> bool:
    """The optimiser diverged or its best fits the calibration data worse than the nominal arm
    (by more than round-off: :func:`fits_worse`)."""
    return result.x is None or not np.isfinite(result.cost) or fits_worse(result.cost, nominal_cost)


def fits_worse(cost: float, nominal_cost: float) -> bool:
    """``cost`` above ``nominal_cost`` by more than round-off: relatively (1e-9) and absolutely
    (``COST_FLOOR``; a perfect arm's fit ends at 5.7e-16 against the nominal's 3.7e-16)."""
    return bool(cost > nominal_cost * (1.0 + 1e-9) + COST_FLOOR)


def on_bounds(task: Task, x: np.ndarray, reported: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Genes (K,) on a bound and beyond one: on or beyond in the optimiser's genome ``x`` and
    still within 1% of the range's width of it (or beyond) in the ``reported`` (gauge-fixed)
    one. Genes that only the exact slides along the axes carry out of range (LM is unbounded
    and moves freely along them) count as neither."""
    p = task.problem
    width = p.upper - p.lower
    held = (reported <= p.lower + 0.01 * width) | (reported >= p.upper - 0.01 * width)
    outside = (x < p.lower) | (x > p.upper)
    on = ~outside & ((x <= p.lower + 1e-9 * width) | (x >= p.upper - 1e-9 * width))
    return on & held, outside & held


def _listed(names: list[str], mask: np.ndarray, k: int = 6) -> str:
    """The first k names where ``mask`` holds, then "..." if there are more."""
    chosen = [n for n, b in zip(names, mask) if b]
    return ", ".join(chosen[:k]) + (" ..." if len(chosen) > k else "")


def warnings(task: Task, result: Result, nominal_cost: float, val: dict[str, float], returned: str,
             reported: np.ndarray, notes: Sequence[str] = ()) -> list[str]:  # fmt: skip
    """Whatever makes the result other than it seems: what the problem found while it was
    built, worse than the nominal model on the calibration or validation data (and what is
    returned then), genes held by their range bounds (:func:`on_bounds`; ``reported`` is the
    gauge-fixed optimiser genome), divergence; ``notes``: the assessment's
    (:mod:`zrp_ga.problems.assessment`: extrapolation, outliers, predicted worse than nominal)."""
    p, out = task.problem, list(task.warnings) + list(notes)
    then = "; the nominal arm is returned instead" if returned == "nominal" else ""
    if result.x is None or not np.isfinite(result.cost):
        out.append(f"the optimiser diverged: its best cost is {result.cost}{then}")
    elif fits_worse(result.cost, nominal_cost):
        out.append(f"the calibrated model fits the calibration data worse than the nominal one "
                   f"(cost {result.cost:.6g} > {nominal_cost:.6g}){then}")  # fmt: skip
    if np.isfinite(val["found"]) and val["found"] > val["nominal"] + FLOOR_M * 1e3:  # mm
        out.append(f"the calibrated model predicts the validation poses worse than the nominal one "
                   f"(RMS {val['found']:.4g} mm > {val['nominal']:.4g} mm){then}")  # fmt: skip
    if result.x is None:
        return out
    on, beyond = on_bounds(task, result.x, reported)
    if on.any():
        out.append(f"{int(on.sum())} gene(s) of the best genome sit on their range bounds ({_listed(p.names, on)}): the search "
                   "was held there, and the true errors may be larger than the ranges allow (widen them: "
                   "problem.search_scale, or problem.ranges=fixed with axis_error and body_error)")  # fmt: skip
    if beyond.any():
        out.append(f"{int(beyond.sum())} gene(s) of the (unbounded) optimiser's genome lie beyond the gene ranges "
                   f"({_listed(p.names, beyond)}): a bounded search (GA, CMA-ES) could not reach this model; widen the "
                   "ranges if it ends worse")  # fmt: skip
    return out


def judged(task: Task, result: Result) -> tuple[dict[str, Any], np.ndarray]:
    """The reported genome and ``summary.json``'s entries that judge it, the assessment's
    among them (:func:`zrp_ga.problems.assessment.assess`: what the data identify, the
    uncertainty, the coverage, the outliers): final cost (the nominal arm's when it is returned instead),
    nominal cost, validation error and parameter error of the nominal and the calibrated arm,
    warnings, the genome by name. The nominal arm is returned when the optimiser diverged, or
    its model is worse than nominal on the calibration or the validation data or predicted
    worse over its own coverage, and the task says so (``problem.if_worse``,
    :attr:`Task.returns_nominal`). The genome is gauge-fixed for the nonlinear cost. A problem
    kind whose genomes are not parameter errors judges its own (``task.judged(result)``, e.g.
    zrp_ga.problems.selection)."""
    if isinstance(task, SelfJudging):
        return task.judged(result)
    from zrp_ga.problems.assessment import assess

    p, judge = task.problem, task.judge
    zero = np.zeros(p.layout.size)
    nominal_cost = float(p.costs(zero)[0])
    found = result.x if result.x is not None else zero
    found = error_model.canonical(p.layout, p.nominal, found) if p.cost is Cost.nonlinear else found
    task.fit_residual(found)  # a residual model (problem.model's +gp) on the found genome's residuals
    before, at_found = judge.validation_errors(zero), judge.validation_errors(found, corrected=True)
    a = assess(task, found, float(at_found[0][0]))
    worse_val = bool(np.isfinite(at_found[0][0]) and at_found[0][0] > before[0][0] + FLOOR_M)  # round-off is no verdict
    worse = worse_than_nominal(result, nominal_cost) or worse_val or a.predicted_worse
    returned = "nominal" if task.returns_nominal and worse else "optimiser"
    x, final_cost = (zero, nominal_cost) if returned == "nominal" else (found, result.cost)
    if returned == "nominal":  # the residual model, if any, on the nominal arm's residuals
        task.fit_residual(zero)
    after = judge.validation_errors(zero, corrected=True) if returned == "nominal" else at_found
    val_rms = {"nominal": float(before[0][0]) * 1e3, "calibrated": float(after[0][0]) * 1e3}
    return {
        "final_cost": final_cost,
        "optimiser_cost": result.cost,
        "returned": returned,
        "nominal_cost": nominal_cost,
        "validation_rms_mm": val_rms,
        "validation_max_mm": {"nominal": float(before[1][0]) * 1e3, "calibrated": float(after[1][0]) * 1e3},
        "param_err": {"nominal": float(judge.param_error(zero)[0]), "calibrated": float(judge.param_error(x)[0])},
        "warnings": warnings(task, result, nominal_cost, {**val_rms, "found": float(at_found[0][0]) * 1e3}, returned, found,
                             a.warnings + a.worse_note("; the nominal arm is returned instead" if returned == "nominal" else "")
                             + (a.beyond if returned == "optimiser" else [])),
        "best_genome": dict(zip(p.names, x.tolist())),
        **a.entries,
    }, x


def build(task: Task, result: Result, cfg: Config, resolved: dict[str, Any], diagnostics: dict[str, Any], wall_s: float,
          choices: dict[str, Any]) -> tuple[Summary, np.ndarray]:  # fmt: skip
    """``summary.json``'s content and the reported genome (:func:`judged`); ``choices``: the
    config groups' options."""
    j, x = judged(task, result)
    initial = result.initial_costs[np.isfinite(result.initial_costs)]
    initial_best = float(initial.min()) if initial.size else float("nan")
    robot = task.robot
    summary: Summary = {
        "instance": task.name,
        "algorithm": resolved["algorithm"]["_target_"].rsplit(".", 1)[-1].lower(),
        "choices": dict(choices),
        "seed": int(cfg.seed),
        "final_cost": j["final_cost"],
        "optimiser_cost": j["optimiser_cost"],
        "returned": j["returned"],
        "initial_cost": initial_best,
        "nominal_cost": j["nominal_cost"],
        "final_over_initial": j["final_cost"] / initial_best,
        "nevals": result.nevals,
        "stop_reason": result.stop_reason,
        "wall_s": wall_s,
        "validation_rms_mm": j["validation_rms_mm"],
        "validation_max_mm": j["validation_max_mm"],
        "param_err": j["param_err"],
        "identifiability": diagnostics,
        **{k: j[k] for k in ("identified", "uncertainty", "coverage", "outliers") if k in j},
        "robot": {"name": robot.name, "joints": robot.n, "joint_types": robot.joint_types},
        "robot_model": robot.to_dict(),  # the arm as given (ZRP, before any registration)
        "problem": task.info,
        "warnings": j["warnings"],
        "best_genome": j["best_genome"],
        **task.report(x),
        **terms_summary(task, x),
        "config": resolved,
        "versions": records.versions(),
    }
    return summary, x


def terms_summary(task: Task, x: np.ndarray) -> dict[str, Any]:
    """``terms``: the calibrated non-geometric terms (``problem.terms``) by name, with their units
    (compliance rad/(N m), harmonics rad); nothing without terms."""
    if not task.problem.layout.terms:
        return {}
    t = task.calibrated_robot(x).terms
    if t is None:
        return {}
    return {"terms": {name: {"value": float(v), "unit": "rad/(N m)" if name.startswith("compliance_") else "rad"}
                      for name, v in zip(t.spec.names, t.values)}}  # fmt: skip


def write(out: Path, task: Task, result: Result, summary: Summary, x: np.ndarray, full: bool = True) -> None:
    """The run's files after the optimisation; each warning also on the console. A write that
    fails (a full disk) names the run's directory when its error names no file. ``full``: False
    (``outputs=study``, :mod:`zrp_ga.run.assembly`): what a study reads only, summary.json,
    best_params.csv and initial_population.csv, without the problem kind's own files, the
    uncertainty and coverage, and the robot files (summary.json then has no ``calibrated_robot``)."""
    from zrp_ga.core.fileio import named

    try:
        _write(out, task, result, summary, x, full)
    except OSError as exc:
        raise named(exc, out) from None


def _write(out: Path, task: Task, result: Result, summary: Summary, x: np.ndarray, full: bool) -> None:
    p = task.problem
    if isinstance(task, SelfJudging):
        params = task.params_table(x)
    else:
        truth = task.truth
        if truth is not None and p.cost is Cost.nonlinear:
            truth = error_model.canonical(p.layout, p.nominal, truth)
        params = records.params_by_joint(p.layout, x, truth)
    records.write_csv(out / directory.BEST_PARAMS, params)
    records.write_population(out / directory.INITIAL_POPULATION, p.names, result.initial_x, result.initial_costs)
    if not full:
        records.write_json(out / directory.SUMMARY, summary)
        return
    task.write(out, x)
    if "coverage" in summary:  # what zrp_ga.model.uncertainty.predict_error_mm and coverage.assess_targets read
        from zrp_ga.model.coverage import Coverage
        from zrp_ga.problems.identify import uncertainty

        unc = uncertainty(p, x, task.setup) if summary["returned"] == "optimiser" else None
        if unc is not None:
            unc.write(out / UNCERTAINTY)
        records.write_json(out / COVERAGE, Coverage(p.data.q).to_dict())
    summary["calibrated_robot"] = write_robot(out, task, x)
    records.write_json(out / directory.SUMMARY, summary)


def write_robot(out: Path, task: Task, x: np.ndarray, stem: str = "calibrated_robot") -> dict[str, Any]:
    """The calibrated arm of genome ``x`` as robot files (module docstring); what
    ``summary.json`` says about them: the files, the DH table's mismatch, base and tools."""
    arm, base, tools = task.export(x)
    first = next(iter(tools.values()), None)
    paths, mismatch = robot_files.write_all(arm, out, stem, base=base, tool=first)
    if len(tools) > 1:
        from zrp_ga.io.robot_files import _frame_entry  # the frames file's own entry format

        entries = {name: _frame_entry(T) for name, T in tools.items()}
        with open(paths["frames"], "a") as f:
            f.write("# tools: every tool point's frame in the hand frame (tool: the first).\n")
            f.write(records.yaml_text({"tools": entries}, sort_keys=False, default_flow_style=None))
    return {"files": {k: v.name for k, v in paths.items()},
            **{f"{k}_mismatch": {"position_mm": m.position_m * 1e3, "orientation_mrad": m.orientation_rad * 1e3,
                                 "samples": m.samples, "notes": list(m.notes)} for k, m in mismatch.items()},
            "base": None if base is None else base.tolist(), "tools": {k: T.tolist() for k, T in tools.items()}}  # fmt: skip


def console(out: Path, job: tuple[int, str] | None = None) -> None:
    """What a finished run prints, read back from its ``summary.json``: one line for a job of a
    sweep (``job``: its number and overrides); where the files are, the cost and the validation
    error for a single run."""
    s = directory.read_summary(out)
    v = s["validation_rms_mm"]
    if job is not None:
        log.info("job %s [%s]: best %.6g after %d evaluations, validation %s mm, %.1f s", job[0], job[1],
                 s["final_cost"], s["nevals"], _mm(v["calibrated"]), s["wall_s"])  # fmt: skip
        return
    paper = s["choices"].get("problem") == "paper" and s["choices"].get("algorithm") == "ga"
    print(f"results in {out}")
    print(f"cost {s['initial_cost']:.4g} -> {s['final_cost']:.4g} after {s['nevals']} evaluations: "
          f"final/initial = {s['final_over_initial']:.3g}" + (" (the paper: 0.241 after 11 iterations)" if paper else ""))  # fmt: skip
    if v["nominal"] is not None:
        print(f"validation RMS position error on unseen poses: {_mm(v['nominal'])} mm nominal -> {_mm(v['calibrated'])} mm calibrated")
    line = uncertainty_line(s)
    if line:
        print(line)


def uncertainty_line(s: Summary) -> str:
    """The one console line on how sure the result is: the predicted 1-sigma error at the
    calibration poses, the predicted against the measured validation RMS, the share of the
    validation poses outside the calibrated region, and the combinations left at nominal."""
    u, ident = s.get("uncertainty") or {}, s.get("identified") or {}
    if not u.get("available"):
        return "uncertainty: n/a (" + u.get("why", "none computed") + ")" if u else ""
    cal = u["calibration_poses_mm"]
    parts = [f"uncertainty: +-{cal['identified_rms']:.3g} mm (1 sigma, RMS over the calibration poses; noise {u['noise_mm']:.3g} mm)"]
    if "validation_rms_mm" in u:
        v = u["validation_rms_mm"]
        parts.append(f"validation RMS predicted {v['predicted']:.4g} mm, measured {v['measured']:.4g} mm")
    where = (s.get("coverage") or {}).get("validation")
    if where:
        parts.append(f"{where['share_outside']:.0%} of validation poses outside the calibrated region")
    if ident.get("subspace") == "identified":
        parts.append(f"{ident['rank']} of {ident['combinations']} combinations identified, {ident['dropped']} left at nominal")
    return "; ".join(parts)


def _mm(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4g}"
