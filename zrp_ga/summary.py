"""What a run says about itself: the identifiability of its data before it starts, and after
it ends its files (``best_params.csv``, ``initial_population.csv``, the problem kind's own,
``summary.json``), the warnings when something is not what it seems, and the console lines."""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga import error_model, records
from zrp_ga.algorithms import Result
from zrp_ga.config import Cost
from zrp_ga.problems import Task

log = logging.getLogger("zrp_ga")


def model_rank(task: Task, n_poses: int = 60) -> int:
    """Rank of the error Jacobian over many random poses with this problem's kind of data: what
    the model can identify at best (the calibration data can only carry less)."""
    from zrp_ga.simulation import random_joints

    p = task.problem
    q = random_joints(p.nominal, n_poses, np.random.default_rng(0))
    J = error_model.error_jacobian(p.nominal, q, p.data.position_only, p.layout.base, p.layout.hand)
    return int(np.linalg.matrix_rank(J))


def diagnostics(task: Task, first: bool) -> dict[str, Any]:
    """The identifiability of the calibration data, and a warning when it carries less than the
    model could identify (once per sweep and problem instance; not again when resuming)."""
    report, rank = task.problem.identifiability(), model_rank(task)
    if report.rank < rank and first and _first_in_sweep(task.name):
        log.warning("the calibration poses identify %d of the %d parameter combinations the model can identify "
                    "(%d parameters); more poses would help. Unidentifiable:\n  %s", report.rank, rank,
                    report.n_params, "\n  ".join(report.null_directions))  # fmt: skip
    return {"rank": report.rank, "model_rank": rank, "n_params": report.n_params,
            "condition_number": report.condition_number, "unidentifiable": report.null_directions}  # fmt: skip


def _first_in_sweep(instance: str) -> bool:
    """True for a single run, and for the first job of a sweep that asks about ``instance``."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if not HydraConfig.initialized() or HydraConfig.get().mode != RunMode.MULTIRUN:
        return True
    marks = Path(HydraConfig.get().sweep.dir) / ".zrp_ga"
    marks.mkdir(parents=True, exist_ok=True)
    try:
        os.close(os.open(marks / f"announced-{hashlib.sha1(instance.encode()).hexdigest()[:12]}", os.O_CREAT | os.O_EXCL))
    except FileExistsError:
        return False
    return True


def warnings(task: Task, result: Result, nominal_cost: float, val: dict[str, float]) -> list[str]:
    """Whatever makes the result other than it seems: worse than the nominal model on the
    calibration or validation data, genes on (or beyond) their range bounds, divergence."""
    p, out = task.problem, []
    if not np.isfinite(result.cost):
        out.append(f"the optimiser diverged: its best cost is {result.cost}")
    elif result.cost > nominal_cost:
        out.append(f"the calibrated model fits the calibration data worse than the nominal one "
                   f"(cost {result.cost:.6g} > {nominal_cost:.6g})")  # fmt: skip
    if np.isfinite(val["calibrated"]) and val["calibrated"] > val["nominal"]:
        out.append(f"the calibrated model predicts the validation poses worse than the nominal one "
                   f"(RMS {val['calibrated']:.4g} mm > {val['nominal']:.4g} mm)")  # fmt: skip
    width = p.upper - p.lower
    low, high = result.x <= p.lower + 1e-9 * width, result.x >= p.upper - 1e-9 * width
    if np.any(low | high):
        names = [n for n, b in zip(p.names, low | high) if b]
        beyond = np.any((result.x < p.lower) | (result.x > p.upper))
        out.append(f"{len(names)} gene(s) of the best genome lie {'beyond' if beyond else 'on'} their range bounds "
                   f"({', '.join(names[:6])}{' ...' if len(names) > 6 else ''}): the true errors may be larger than the "
                   "ranges allow (problem.search_scale, axis_error, body_error)")  # fmt: skip
    return out


def judged(task: Task, result: Result) -> tuple[dict, np.ndarray]:
    """The reported genome (gauge-fixed for the nonlinear cost) and ``summary.json``'s entries
    that judge it: nominal cost, validation error and parameter error of the nominal and the
    calibrated arm, warnings, the genome by name. A problem kind whose genomes are not
    parameter errors judges its own (``task.judged(result)``, e.g. zrp_ga.problems.selection)."""
    if hasattr(task, "judged"):
        return task.judged(result)
    p, judge = task.problem, task.judge
    x = error_model.canonical(p.layout, p.nominal, result.x) if p.cost is Cost.nonlinear else result.x
    zero = np.zeros(p.layout.size)
    nominal_cost = float(p.costs(zero)[0])
    before, after = judge.validation_errors(zero), judge.validation_errors(x)
    val_rms = {"nominal": float(before[0][0]) * 1e3, "calibrated": float(after[0][0]) * 1e3}
    return {
        "nominal_cost": nominal_cost,
        "validation_rms_mm": val_rms,
        "validation_max_mm": {"nominal": float(before[1][0]) * 1e3, "calibrated": float(after[1][0]) * 1e3},
        "param_err": {"nominal": float(judge.param_error(zero)[0]), "calibrated": float(judge.param_error(x)[0])},
        "warnings": warnings(task, result, nominal_cost, val_rms),
        "best_genome": dict(zip(p.names, x.tolist())),
    }, x


def build(task: Task, result: Result, cfg, resolved: dict, diagnostics: dict, wall_s: float) -> tuple[dict, np.ndarray]:
    """``summary.json``'s content and the reported genome (:func:`judged`)."""
    from hydra.core.hydra_config import HydraConfig

    j, x = judged(task, result)
    initial = result.initial_costs[np.isfinite(result.initial_costs)]
    initial_best = float(initial.min()) if initial.size else float("nan")
    summary = {
        "instance": task.name,
        "algorithm": resolved["algorithm"]["_target_"].rsplit(".", 1)[-1].lower(),
        "choices": dict(HydraConfig.get().runtime.choices) if HydraConfig.initialized() else {},
        "seed": int(cfg.seed),
        "final_cost": result.cost,
        "initial_cost": initial_best,
        "nominal_cost": j["nominal_cost"],
        "final_over_initial": result.cost / initial_best,
        "nevals": result.nevals,
        "stop_reason": result.stop_reason,
        "wall_s": wall_s,
        "validation_rms_mm": j["validation_rms_mm"],
        "validation_max_mm": j["validation_max_mm"],
        "param_err": j["param_err"],
        "identifiability": diagnostics,
        "robot": {"name": task.robot.name, "joints": task.robot.n, "joint_types": task.robot.joint_types},
        "problem": task.info,
        "warnings": j["warnings"],
        "best_genome": j["best_genome"],
        **task.report(x),
        "config": resolved,
        "versions": records.versions(),
    }
    return summary, x


def write(out: Path, task: Task, result: Result, summary: dict, x: np.ndarray) -> None:
    """The run's files after the optimisation; each warning also on the console."""
    p = task.problem
    if hasattr(task, "params_table"):  # a problem kind whose genomes are not parameter errors
        params = task.params_table(x)
    else:
        truth = task.truth
        if truth is not None and p.cost is Cost.nonlinear:
            truth = error_model.canonical(p.layout, p.nominal, truth)
        params = records.params_by_joint(p.layout, x, truth)
    records.write_csv(out / "best_params.csv", params)
    records.write_csv(out / "initial_population.csv", records.population_table(p.names, result.initial_x, result.initial_costs))
    task.write(out, x)
    records.write_json(out / "summary.json", summary)


def console(out: Path, hc, multirun: bool) -> None:
    """What a finished run prints, read back from its ``summary.json``: one line per job in a
    sweep; where the files are, the cost and the validation error for a single run."""
    import json

    s = json.loads((out / "summary.json").read_text())
    v = s["validation_rms_mm"]
    if multirun:
        log.info("job %s [%s]: best %.6g after %d evaluations, validation %s mm, %.1f s", hc.job.num,
                 " ".join(hc.overrides.task), s["final_cost"], s["nevals"], _mm(v["calibrated"]), s["wall_s"])  # fmt: skip
        return
    paper = s["choices"].get("problem") == "paper" and s["choices"].get("algorithm") == "ga"
    print(f"results in {out}")
    print(f"cost {s['initial_cost']:.4g} -> {s['final_cost']:.4g} after {s['nevals']} evaluations: "
          f"final/initial = {s['final_over_initial']:.3g}" + (" (the paper: 0.241 after 11 iterations)" if paper else ""))  # fmt: skip
    if v["nominal"] is not None:
        print(f"validation RMS position error on unseen poses: {_mm(v['nominal'])} mm nominal -> {_mm(v['calibrated'])} mm calibrated")


def _mm(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4g}"
