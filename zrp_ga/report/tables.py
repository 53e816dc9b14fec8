"""The report's tables, built from the runs (definitions in the package docstring)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from zrp_ga.report import stats, targets
from zrp_ga.report.labels import configurations, describe
from zrp_ga.report.runs import Run, number
from zrp_ga.report.targets import TargetRule


def area_under_curve(conv: pd.DataFrame, budget: float) -> float:
    """Mean of log10(best so far) over evaluations [first row, ``budget``] (a step function of
    the rows of ``convergence.csv``); NaN when a cost is not positive and finite."""
    e = conv["nevals"].to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.log10(np.minimum.accumulate(conv["best"].to_numpy(dtype=float)))
    keep = e < budget
    edges = np.append(e[keep], budget)
    value = float(np.sum(b[keep] * np.diff(edges)) / (budget - e[0])) if budget > e[0] else float(b[0])
    return value if math.isfinite(value) else math.nan


def quartiles(x) -> tuple[float, float, float]:
    """Median, first and third quartile of the finite values (NaN when none)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return tuple(float(v) for v in np.percentile(x, [50, 25, 75])) if len(x) else (math.nan,) * 3


def _per_run(runs: list[Run], labels: list[str], shown: dict, keys: list[str], floors: pd.DataFrame,
             primary: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:  # fmt: skip
    """``runs`` (one row per run) and ``tidy`` (one row per run and generation)."""
    reference = floors.set_index("instance")["reference"]
    hit = primary.set_index("run")["hit"]
    budget = min(float(r.convergence["nevals"].iloc[-1]) for r in runs)
    rows, tidy = [], []
    for r, label in zip(runs, labels):
        setting = {k: shown[label].get(k, "") for k in keys}
        ref = float(reference.loc[r.instance])
        rows.append(dict(
            run=str(r.path), configuration=label, instance=r.instance, **setting, seed=r.summary.get("seed"),
            final_cost=r.final_cost, reference=ref, final_over_ref=r.final_cost / ref if ref > 0 else math.nan,
            final_over_initial=number(r.summary.get("final_over_initial")), nevals=r.nevals,
            val_rms_mm=r.validation_mm("calibrated"), val_rms_nominal_mm=r.validation_mm("nominal"),
            wall_s=r.summary.get("wall_s"), evals_to_target=float(hit.get(str(r.path), math.inf)),
            auc=area_under_curve(r.convergence, budget), auc_budget=budget,
        ))  # fmt: skip
        conv = r.convergence.copy()
        for i, (k, v) in enumerate(dict(run=str(r.path), configuration=label, instance=r.instance).items()):
            conv.insert(i, k, v)
        for k, v in setting.items():
            conv[k] = v
        tidy.append(conv)
    return pd.DataFrame(rows), pd.concat(tidy, ignore_index=True)


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
                   success_rate=len(reached) / len(g))  # fmt: skip
        for level in rule.names():
            has = wide is not None and label in wide.index and ("ert", level) in wide.columns
            row[f"success_{level}"] = float(wide.loc[label, ("success_rate", level)]) if has else math.nan
            row[f"ert_{level}"] = float(wide.loc[label, ("ert", level)]) if has else math.nan
        row.update(auc_median=quartiles(g.auc)[0], auc_budget=float(g.auc_budget.iloc[0]))
        out.append(row)
    return pd.DataFrame(out).sort_values(["final_over_ref_median", "final_cost_median"], kind="stable").reset_index(drop=True)


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
    order = [f"{m}_{level}" for m in ("success", "ert") for level in rule.names() if f"{m}_{level}" in base]
    position = base["configuration"].map({c: i for i, c in enumerate(order)})
    base = base.assign(position=position).sort_values(["instance", "position"]).reset_index(drop=True)
    return base[["instance", "configuration", "runs", "final_cost_median", "final_over_ref_median", *order]]


def rank_scores(runs_df: pd.DataFrame, floors: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """(N instances, k configurations) median over runs of the final cost clipped below at the
    instance's tightest target (non-finite: +inf), on the instances where every configuration
    ran; and the instances left out for lacking one."""
    tightest = floors.set_index("instance").filter(like="target_").min(axis=1)
    clip = runs_df["instance"].map(tightest).fillna(-np.inf)
    score = np.fmax(runs_df["final_cost"].fillna(np.inf), clip)
    table = runs_df.assign(score=score).pivot_table(index="instance", columns="configuration", values="score", aggfunc="median")
    complete = table.notna().all(axis=1)
    return table[complete], list(table.index[~complete])


def _friedman(runs_df: pd.DataFrame, floors: pd.DataFrame) -> tuple[dict | None, str]:
    """Friedman's test across instances, or None and why not."""
    scores, incomplete = rank_scores(runs_df, floors)
    k, n = runs_df["configuration"].nunique(), len(scores)
    if k < 2:
        return None, "one configuration: nothing to rank"
    if n < 2:
        why = "one instance" if runs_df["instance"].nunique() < 2 else f"{n} instance(s) on which every configuration ran"
        return None, f"{why}: ranks across instances need two or more"
    result = stats.friedman(scores)
    result["left_out"] = incomplete
    note = f" ({len(incomplete)} instance(s) without every configuration left out)" if incomplete else ""
    return result, note


def _blocks(df: pd.DataFrame, columns: list[str]) -> pd.Index:
    """Each run's block: its values of ``columns`` (the seed, the other settings, the instance)."""
    if not columns:
        return pd.RangeIndex(len(df))
    return pd.MultiIndex.from_frame(df[columns].astype(str)) if len(columns) > 1 else pd.Index(df[columns[0]].astype(str))


def _seed_blocks(g: pd.DataFrame) -> pd.DataFrame:
    """``g`` with a ``block`` column: the seed, or the run itself when the seed is unknown (then
    no two configurations share a block)."""
    seed = g["seed"].where(g["seed"].notna(), g["run"]).astype(str)
    return g.assign(block=seed)


def within_instances(runs_df: pd.DataFrame) -> pd.DataFrame:
    """Per instance: the configurations compared on the final cost, paired by seed when they share
    their seeds (:func:`zrp_ga.report.stats.compare_design`); the omnibus p-values Holm-adjusted
    over the instances (``p_holm`` of the rows ``a == "all"``); confidence intervals for the
    pairs holding the instance's best configuration (lowest median final cost), named in ``best``."""
    out = []
    for instance, g in runs_df.groupby("instance", sort=False):
        g = _seed_blocks(g)
        groups = {lab: pd.Series(h["final_cost"].to_numpy(dtype=float), index=h["block"]) for lab, h in g.groupby("configuration", sort=False)}
        if len(groups) < 2:
            continue
        best = g.groupby("configuration", sort=False)["final_cost"].median().idxmin()
        t = stats.compare_design(groups, best=best)
        t.insert(0, "instance", instance)
        t.insert(1, "best", best)
        out.append(t)
    if not out:
        return pd.DataFrame(columns=["instance", "best", *stats.DESIGN_COLUMNS])
    df = pd.concat(out, ignore_index=True)
    omnibus = df["a"] == "all"
    if omnibus.any():
        df.loc[omnibus, "p_holm"] = stats.holm(df.loc[omnibus, "p"].to_numpy())
    return df


def factorial(runs_df: pd.DataFrame, keys: list[str]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The main effect of each setting over the others, per instance and across instances
    (``instance`` "all"): the values of the setting compared on final cost / f_ref, paired by the
    other settings and the seed (and the instance, across instances) when every value ran on the
    same such blocks, else as independent runs; per setting, the omnibus p-values (with two
    values: the one pair's) are Holm-adjusted over the instances (the row "all" is not). Returns the tests and the median
    final / f_ref per (setting, instance, value)."""
    tests, medians = [], []
    for key in keys:
        having = runs_df[runs_df[key] != ""]
        if having[key].nunique() < 2:
            continue
        others = [k for k in keys if k != key]
        per_setting = []
        for instance, g in [*having.groupby("instance", sort=False), ("all", having)]:
            g = _seed_blocks(g)
            block_cols = others + ["block"] + (["instance"] if instance == "all" else [])
            index = _blocks(g, block_cols)
            values = g["final_over_ref"].to_numpy(dtype=float)
            groups = {}
            for v in sorted(g[key].unique(), key=str):
                mask = (g[key] == v).to_numpy()
                groups[describe(key, str(v))] = pd.Series(values[mask], index=index[mask])
                medians.append(dict(setting=key, instance=instance, value=describe(key, str(v)), runs=int(mask.sum()),
                                    median_final_over_ref=float(np.nanmedian(values[mask])) if mask.any() else math.nan))  # fmt: skip
            if len(groups) < 2:
                continue
            best = min(groups, key=lambda k: np.nanmedian(groups[k].to_numpy()))
            t = stats.compare_design(groups, best=best)
            t.insert(0, "setting", key)
            t.insert(1, "instance", instance)
            t.insert(2, "best", best)
            per_setting.append(t)
        if per_setting:
            df = pd.concat(per_setting, ignore_index=True)
            sel = (df["a"] == "all") & (df["instance"] != "all")
            if not sel.any():  # two values: one pair per instance, corrected over the instances
                sel = (df["a"] != "all") & (df["instance"] != "all")
            if sel.any():
                df.loc[sel, "p_holm"] = stats.holm(df.loc[sel, "p"].to_numpy())
            tests.append(df)
    columns = ["setting", "instance", "best", *stats.DESIGN_COLUMNS]
    return (pd.concat(tests, ignore_index=True) if tests else pd.DataFrame(columns=columns),
            pd.DataFrame(medians, columns=["setting", "instance", "value", "runs", "median_final_over_ref"]))  # fmt: skip


def build_tables(runs: list[Run], rule: TargetRule | None = None, budgets: tuple[int, ...] = targets.BUDGETS) -> dict:
    """Every table of the report, as DataFrames (and the Friedman result), keyed by name;
    ``rule``: how targets are set (default: the default levels)."""
    rule = rule or TargetRule()
    labels, shown = configurations(runs)
    keys = list(dict.fromkeys(k for s in shown.values() for k in s))
    floors = targets.floors(runs, rule)
    hits = targets.hits(runs, labels, floors, rule)
    runs_df, tidy = _per_run(runs, labels, shown, keys, floors, hits[hits["level"] == rule.primary()])
    ert_inst = targets.ert(hits, ["configuration", "instance", "level", "target"])
    ert_all = targets.ert(hits, ["configuration", "level"])
    budget_inst = targets.fixed_budget(runs, labels, floors, budgets)
    budget_all = (budget_inst.groupby(["configuration", "budget"], sort=False)
                  .agg(instances=("instance", "size"), median_cost_over_ref=("median_cost_over_ref", "median")).reset_index())  # fmt: skip
    groups = {m: {lab: g[m].to_numpy(dtype=float) for lab, g in runs_df.groupby("configuration", sort=False)}
              for m in ("final_cost", "final_over_ref", "val_rms_mm")}  # fmt: skip
    statistics = pd.concat([stats.compare(v, m) for m, v in groups.items()], ignore_index=True)
    friedman, friedman_note = _friedman(runs_df, floors)
    summary = _summary(runs_df, ert_all, rule)
    factors, factor_medians = factorial(runs_df, keys)
    return dict(
        labels=labels, shown=shown, keys=keys, floors=floors, hits=hits, runs=runs_df, tidy=tidy,
        summary=summary, per_instance=_per_instance(runs_df, ert_inst, rule, list(summary["configuration"])),
        ert=pd.concat([ert_all.assign(instance="all", target=np.nan), ert_inst], ignore_index=True)[
            ["configuration", "instance", "level", "target", "runs", "successes", "success_rate", "ert"]],
        ecdf=targets.ecdf(hits), fixed_budget=budget_inst, fixed_budget_all=budget_all, statistics=statistics,
        factors=factors, factor_medians=factor_medians, within=within_instances(runs_df), friedman=friedman,
        friedman_note=friedman_note,
    )  # fmt: skip
