"""The report's tables, built from the runs (definitions in the package docstring)."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from zrp_ga.report import compare, design, reference, stats, targets
from zrp_ga.report.labels import configurations
from zrp_ga.report.runs import Run, number
from zrp_ga.report.targets import TargetRule


def area_under_curve(conv, budget: float) -> float:
    """Mean of log10(best so far) over evaluations [first row, ``budget``] (a step function of
    the rows of ``convergence.csv``, columns ``nevals`` and ``best``); NaN when a cost is not
    positive and finite."""
    e = np.asarray(conv["nevals"], dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.log10(np.minimum.accumulate(np.asarray(conv["best"], dtype=float)))
    keep = e < budget
    edges = np.append(e[keep], budget)
    value = float(np.sum(b[keep] * np.diff(edges)) / (budget - e[0])) if budget > e[0] else float(b[0])
    return value if math.isfinite(value) else math.nan


def quartiles(x: ArrayLike) -> tuple[float, float, float]:
    """Median, first and third quartile of the finite values (NaN when none)."""
    values = np.asarray(x, dtype=float)
    finite = values[np.isfinite(values)]
    if not len(finite):
        return (math.nan,) * 3
    median, q1, q3 = np.percentile(finite, [50, 25, 75])
    return float(median), float(q1), float(q3)


def _per_run(runs: list[Run], labels: list[str], shown: dict, keys: list[str], floors: pd.DataFrame,
             primary: pd.DataFrame, refs: set[str]) -> pd.DataFrame:  # fmt: skip
    """``runs``: one row per run (``row``: its index in ``runs``)."""
    f = {i: (float(ref), float(tol)) for i, ref, tol in zip(floors["instance"], floors["reference"], floors["tolerance"])}
    hit = dict(zip(primary["run"], primary["hit"]))
    budget = min(float(r.columns["nevals"][-1]) for r in runs)
    rows = []
    for i, (r, label) in enumerate(zip(runs, labels)):
        ref, tol = f[r.instance]
        ratio = r.final_cost / ref if ref > 0 else math.nan
        rows.append(dict(
            run=str(r.path), row=i, configuration=label, instance=r.instance, **{k: shown[label].get(k, "") for k in keys},
            algo=reference.algorithm(r), is_reference=label in refs, seed=r.summary.get("seed"), final_cost=r.final_cost,
            reference=ref, final_over_ref=ratio, tol=tol, score=ratio / tol if tol > 0 else ratio,
            final_over_initial=number(r.summary.get("final_over_initial")), nevals=r.nevals,
            stopped_by_budget=targets.stopped_by_budget(r), val_rms_mm=r.validation_mm("calibrated"),
            val_rms_nominal_mm=r.validation_mm("nominal"), wall_s=number(r.summary.get("wall_s")),
            evals_to_target=float(hit.get(str(r.path), math.inf)), auc=area_under_curve(r.columns, budget), auc_budget=budget,
        ))  # fmt: skip
    return pd.DataFrame(rows)


def tidy(runs: list[Run], runs_df: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """One row per run and generation: the run's labels and settings beside its convergence.csv's columns."""
    lengths = np.array([len(r.columns["nevals"]) for r in runs])
    columns = list(dict.fromkeys(c for r in runs for c in r.columns))
    data = {k: np.repeat(runs_df[k].to_numpy(), lengths) for k in ("run", "configuration", "instance")}
    for c in columns:
        data[c] = np.concatenate([r.columns[c] if c in r.columns else np.full(n, np.nan) for r, n in zip(runs, lengths)])
    for k in keys:
        data[k] = np.repeat(runs_df[k].to_numpy(), lengths)
    return pd.DataFrame(data)


def _summary(runs_df: pd.DataFrame, ert_all: pd.DataFrame, rule: TargetRule) -> pd.DataFrame:
    """Per configuration, pooled over its runs (and instances)."""
    wide = ert_all.pivot(index="configuration", columns="level", values=["success_rate", "ert"]) if len(ert_all) else None
    out = []
    for label, g in runs_df.groupby("configuration", sort=False):
        reached = g["evals_to_target"][np.isfinite(g["evals_to_target"])]
        cost, val, ratio = quartiles(g.final_cost), quartiles(g.val_rms_mm), quartiles(g.final_over_initial)
        row = dict(configuration=label, runs=len(g), instances=g["instance"].nunique(),
                   final_cost_median=cost[0], final_cost_q1=cost[1], final_cost_q3=cost[2],
                   final_over_ref_median=quartiles(g.final_over_ref)[0],
                   val_rms_mm_median=val[0], val_rms_mm_q1=val[1], val_rms_mm_q3=val[2], final_over_initial_median=ratio[0],
                   primary_target=rule.primary(), evals_to_target_median=float(np.median(reached)) if len(reached) else math.inf,
                   success_rate=len(reached) / len(g), nevals_median=float(g["nevals"].median()),
                   wall_s_median=quartiles(g.wall_s)[0], group=int(g["group"].iloc[0]), is_reference=bool(g["is_reference"].iloc[0]))  # fmt: skip
        for level in rule.names():
            if wide is not None and label in wide.index and ("ert", level) in wide.columns:
                row[f"success_{level}"] = float(wide.loc[label, ("success_rate", level)])
                row[f"ert_{level}"] = float(wide.loc[label, ("ert", level)])
            else:
                row[f"success_{level}"] = row[f"ert_{level}"] = math.nan
        row.update(auc_median=quartiles(g.auc)[0], auc_budget=float(g.auc_budget.iloc[0]),
                   evals_to_common_median=quartiles(g[compare.EVALS])[0])
        out.append(row)
    return _best_first(pd.DataFrame(out), float(runs_df["tol"].max()), f"ert_{rule.primary()}")


def _best_first(summary: pd.DataFrame, tol: float, ert: str) -> pd.DataFrame:
    """The configurations best first: by median final / f_ref, medians within the tolerance
    ``tol`` tied (:func:`zrp_ga.report.stats.snap`), then by the median evaluations to the cost
    every run reached (instances where all are tied), then by the expected running time to the
    primary target (column ``ert``), then by the median final / f_ref itself; group by group where
    the runs form groups that never shared an instance (no order across them)."""
    key = summary.assign(_r=stats.snap(summary["final_over_ref_median"].to_numpy(), tol),
                         _e=summary["evals_to_common_median"].fillna(np.inf), _t=summary.get(ert, pd.Series(np.inf, index=summary.index)).fillna(np.inf))  # fmt: skip
    by = ["group"] if "group" in key and key["group"].nunique() > 1 else []
    key = key.sort_values([*by, "_r", "_e", "_t", "final_over_ref_median"], kind="stable", na_position="last")
    return summary.loc[key.index].reset_index(drop=True)


def _per_instance(runs_df: pd.DataFrame, ert_inst: pd.DataFrame, rule: TargetRule, order: list[str]) -> pd.DataFrame:
    """Per instance and configuration (in ``order``): runs, median final cost and its ratio to
    f_ref, success rate and ERT per level."""
    base = (runs_df.groupby(["instance", "configuration"], sort=False)
            .agg(runs=("run", "size"), final_cost_median=("final_cost", "median"),
                 final_over_ref_median=("final_over_ref", "median")).reset_index())  # fmt: skip
    if len(ert_inst):
        wide = ert_inst.pivot(index=["instance", "configuration"], columns="level", values=["success_rate", "ert"])
        wide.columns = [f"{'success' if a == 'success_rate' else 'ert'}_{b}" for a, b in wide.columns]
        base = base.merge(wide.reset_index(), on=["instance", "configuration"], how="left")
    cols = [f"{m}_{level}" for m in ("success", "ert") for level in rule.names() if f"{m}_{level}" in base]
    position = base["configuration"].map({c: i for i, c in enumerate(order)})
    base = base.assign(position=position).sort_values(["instance", "position"], kind="stable").reset_index(drop=True)
    return base[["instance", "configuration", "runs", "final_cost_median", "final_over_ref_median", *cols]]


def rank_scores(runs_df: pd.DataFrame, asked: dict[str, dict]) -> tuple[pd.DataFrame, list[str], pd.Series]:
    """(N instances, k configurations) median over runs of each instance's question (the
    final-cost score, non-finite: +inf; or the evaluations when the instance is tied), on the
    instances where every configuration ran; the instances left out for lacking one; each
    instance's tolerance in the scores' units."""
    column = runs_df["instance"].map({i: q["column"] for i, q in asked.items()})
    score = np.where(column == compare.SCORE, runs_df["score"], runs_df[compare.EVALS])
    score = np.where(np.isfinite(score.astype(float)), score, np.inf)
    table = runs_df.assign(s=score).pivot_table(index="instance", columns="configuration", values="s", aggfunc="median", sort=False)
    complete = table.notna().all(axis=1)
    tol = pd.Series({i: q["tol"] for i, q in asked.items()})
    return table[complete], list(table.index[~complete]), tol


def friedman_by_group(runs_df: pd.DataFrame, asked: dict[str, dict]) -> list[dict]:
    """Friedman's test across instances in each group of two or more configurations (or why
    not, in ``note``): {group, result or None, note}."""
    out: list[dict[str, Any]] = []
    for group, g in runs_df.groupby("group", sort=True):
        scores, incomplete, tol = rank_scores(g, asked)
        k, n = g["configuration"].nunique(), len(scores)
        if k < 2:
            out.append(dict(group=int(group), result=None, note="one configuration: nothing to rank"))
            continue
        if n < 2:
            why = "one instance" if g["instance"].nunique() < 2 else f"{n} instance(s) on which every configuration ran"
            out.append(dict(group=int(group), result=None, note=f"{why}: ranks across instances need two or more"))
            continue
        result = stats.friedman(scores, tol=tol)
        result["left_out"] = incomplete
        note = f" ({len(incomplete)} instance(s) without every configuration left out)" if incomplete else ""
        out.append(dict(group=int(group), result=result, note=note))
    return out


def build_tables(runs: list[Run], rule: TargetRule | None = None, budgets: tuple[int, ...] | None = None,
                 where: Path | None = None) -> dict:  # fmt: skip
    """Every table of the report, as DataFrames (and the Friedman results), keyed by name;
    ``rule``: how targets and the tolerance are set (default: the default levels); ``budgets``:
    the fixed budgets (default: from the runs, :func:`zrp_ga.report.targets.default_budgets`);
    ``where``: the report's folder, which the runs' paths in the tables are relative to."""
    rule = rule or TargetRule()
    budgets = tuple(budgets) if budgets else targets.default_budgets(runs)
    labels, shown = configurations(runs)
    keys = list(dict.fromkeys(k for s in shown.values() for k in s))
    refs = reference.reference_configurations(runs, labels)
    floors = targets.floors(runs, rule)
    hits = targets.hits(runs, labels, floors, rule)
    runs_df = _per_run(runs, labels, shown, keys, floors, hits[hits["level"] == rule.primary()], refs)
    runs_df["group"] = runs_df["configuration"].map(design.groups(runs_df))
    asked = compare.questions(runs, runs_df)
    ert_inst = targets.ert(hits, ["configuration", "instance", "level", "target"])
    ert_all = targets.ert(hits, ["configuration", "level"])
    budget_inst = targets.fixed_budget(runs, labels, floors, budgets)
    budget_all = (budget_inst.groupby(["configuration", "budget"], sort=False)
                  .agg(instances=("instance", "size"), median_cost_over_ref=("median_cost_over_ref", lambda v: float(v.median())
                       if v.notna().all() else math.nan)).reset_index())  # fmt: skip
    summary = _summary(runs_df, ert_all, rule)
    ref = reference.table(runs, labels, floors)
    factors, factor_medians = compare.factorial(runs_df, keys, asked)
    by_group = friedman_by_group(runs_df, asked)
    largest = max(by_group, key=lambda f: (f["result"] is not None, runs_df["group"].eq(f["group"]).sum()))
    lm_val = ref[ref["reference"] == reference.NAMES["lm"]].set_index("instance")["val_rms_mm"].to_dict()
    t = dict(
        labels=labels, shown=shown, keys=keys, floors=floors, hits=hits, runs=runs_df, questions=asked,
        summary=summary, per_instance=_per_instance(runs_df, ert_inst, rule, list(summary["configuration"])),
        ert=pd.concat([ert_all.assign(instance="all", target=np.nan), ert_inst], ignore_index=True)[
            ["configuration", "instance", "level", "target", "runs", "successes", "success_rate", "ert"]],
        ecdf=targets.ecdf(hits), fixed_budget=budget_inst, fixed_budget_all=budget_all, budgets=budgets,
        statistics=compare.validation(runs_df, lm_val, rule.resolution()), factors=factors, factor_medians=factor_medians,
        interactions=compare.interactions(runs_df, keys, asked), within=compare.within_instances(runs_df, asked),
        friedman_groups=by_group, friedman=largest["result"], friedman_note=largest["note"], reference=ref,
        answer=reference.answer(runs, labels, runs_df, floors, ref, list(summary["configuration"])),
        seed_drew_instance=design.seed_drew_instance(runs_df), rule=rule,
    )  # fmt: skip
    t["tidy"] = tidy(runs, runs_df, keys)
    if where is not None:
        _relative_runs(t, where)
    return t


def _relative_runs(t: dict, where: Path) -> None:
    """The runs' paths in the tables made relative to the report's folder ``where``."""
    names = {p: os.path.relpath(p, where) for p in t["runs"]["run"]}
    for key in ("runs", "tidy", "hits"):
        t[key]["run"] = t[key]["run"].map(lambda p: names.get(p, p))
