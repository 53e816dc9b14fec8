"""The report's comparisons, equivalence before difference (:mod:`zrp_ga.report.stats`): the
question each instance asks, the configurations within each instance, each setting over the
others, the settings' interactions and the validation errors.

**The question of an instance.** Final costs are compared as ``score`` = (final cost / f_ref)
/ tolerance (the instance's tolerance relative to f_ref), so that one unit is the tolerance on
every instance and two runs closer than 1 are the same result. When every run of an instance
ends within the tolerance of every other (all at the floor, typically), final costs tell
nothing apart: the instance's question becomes the evaluations each run took to reach the
cost every run reached (``evals_to_common``), compared exactly."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd

from zrp_ga.report import stats
from zrp_ga.report.common import ALPHA
from zrp_ga.report.labels import describe
from zrp_ga.report.runs import Run
from zrp_ga.report.targets import first_hit

SCORE, EVALS = "score", "evals_to_common"
COLUMNS = ["metric", *stats.DESIGN_COLUMNS]


def questions(runs: list[Run], runs_df: pd.DataFrame) -> dict[str, dict]:
    """Per instance: ``metric`` (words), ``column`` of ``runs_df`` it compares, ``tol`` (in that
    column's units), ``tied`` (every final within the tolerance), ``at_floor`` (and all within it
    of f_ref) and ``level`` (the cost every run reached, over f_ref). Fills ``runs_df``'s
    ``evals_to_common`` for the runs of tied instances."""
    out = {}
    runs_df[EVALS] = np.nan
    for instance, g in runs_df.groupby("instance", sort=False):
        ratio, tol = g["final_over_ref"].to_numpy(dtype=float), float(g["tol"].iloc[0])
        tied = bool(len(ratio) >= 2 and np.isfinite(ratio).all() and np.ptp(ratio) <= tol)  # one run ties with nothing
        if not tied:
            out[instance] = dict(metric="final cost / f_ref", column=SCORE, tol=1.0, tied=False, at_floor=False, level=math.nan)
            continue
        ends = [float(runs[i].best[-1]) for i in g["row"]]
        reached = max(ends)
        runs_df.loc[g.index, EVALS] = [first_hit(runs[i].evals, runs[i].best, reached) for i in g["row"]]
        level = float(np.max(ratio))
        at_floor = bool(level <= 1.0 + tol)
        what = "the floor" if at_floor else f"{level:.3g} x f_ref"
        out[instance] = dict(metric=f"evaluations to reach {what} (every run's final cost)", column=EVALS, tol=0.0, tied=True,
                             at_floor=at_floor, level=level)  # fmt: skip
    return out


def _seed_blocks(g: pd.DataFrame) -> pd.Series:
    """Each run's block: its seed, or the run itself when the seed is unknown (then no two
    configurations share a block)."""
    return g["seed"].where(g["seed"].notna(), g["run"]).astype(str)


def _holm_over(df: pd.DataFrame, sel: pd.Series) -> None:
    """Holm over the rows ``sel`` of ``df`` (p and TOST's p), and their verdicts again."""
    if not sel.any():
        return
    df.loc[sel, "p_holm"] = stats.holm(df.loc[sel, "p"].to_numpy())
    pairs = sel & (df["a"] != "all")
    if pairs.any():
        df.loc[pairs, "p_equivalence_holm"] = stats.holm(df.loc[pairs, "p_equivalence"].to_numpy())
    for i in df.index[sel]:
        row = df.loc[i]
        if row["a"] == "all":
            df.loc[i, "verdict"] = stats.EQUIVALENT if row["verdict"] == stats.EQUIVALENT else (
                "differ" if row["p_holm"] < ALPHA else stats.UNDECIDED)  # fmt: skip
        else:
            df.loc[i, "verdict"] = stats.verdict(row["test"] == stats.ALL_TIED, row["p_holm"], row["direction"],
                                                 row["p_equivalence_holm"])  # fmt: skip


def within_instances(runs_df: pd.DataFrame, asked: dict[str, dict]) -> pd.DataFrame:
    """Per instance: the configurations compared on the instance's question (``question`` True),
    paired by seed when they share their seeds (:func:`zrp_ga.report.stats.compare_design`); the
    omnibus p-values Holm-adjusted over the instances; confidence intervals for the pairs
    holding the instance's best configuration (lowest median), named in ``best``. Where every
    run ties (the question is evaluations) the final costs' verdicts are there too (``question``
    False): equivalent, every run within the tolerance."""
    out = []
    for instance, g in runs_df.groupby("instance", sort=False):
        q = asked[instance]
        block = _seed_blocks(g)
        if g.groupby("configuration").size().max() < 2 or g["configuration"].nunique() < 2:  # one run each: nothing to test within
            continue
        asks = [(q["column"], q["tol"], q["metric"], True)]
        if q["tied"]:
            asks.append((SCORE, 1.0, "final cost / f_ref", False))
        for column, tol, metric, question in asks:
            groups = {lab: pd.Series(h[column].to_numpy(dtype=float), index=block[h.index])
                      for lab, h in g.groupby("configuration", sort=False)}  # fmt: skip
            best = g.groupby("configuration", sort=False)[q["column"]].median().idxmin()
            t = stats.compare_design(groups, best=best, tol=tol, ci=question)
            for i, (name, value) in enumerate((("instance", instance), ("best", best), ("metric", metric), ("question", question))):
                t.insert(i, name, value)
            out.append(t)
    if not out:
        return pd.DataFrame(columns=["instance", "best", "metric", "question", *stats.DESIGN_COLUMNS])
    df = pd.concat(out, ignore_index=True)
    _holm_over(df, (df["a"] == "all") & df["question"].astype(bool))
    return df


def _factor_scope(g: pd.DataFrame, key: str, others: list[str], column: str, tol: float, across: bool) -> tuple[dict, str]:
    """The groups of one setting's values in one scope, indexed by block (the other settings, the
    seed, and the instance across instances), and the best value (lowest median)."""
    cols = [*others, "block", *(["instance"] if across else [])]
    g = g.assign(block=_seed_blocks(g))
    index = pd.MultiIndex.from_frame(g[cols].astype(str)) if len(cols) > 1 else pd.Index(g[cols[0]].astype(str))
    values = g[column].to_numpy(dtype=float)
    groups = {}
    for v in sorted(g[key].unique(), key=str):
        mask = (g[key] == v).to_numpy()
        groups[describe(key, str(v))] = pd.Series(values[mask], index=index[mask])
    best = min(groups, key=lambda k: np.nanmedian(groups[k].to_numpy()) if np.isfinite(groups[k]).any() else np.inf)
    return groups, best


def _every_value_ran(having: pd.DataFrame, key: str) -> pd.DataFrame:
    """The runs of the instances on which every value of setting ``key`` ran: across instances a
    setting's values are compared only there, never a value on one instance against another
    value on another (a folder of unrelated runs)."""
    values = having[key].nunique()
    ran = having.groupby("instance", sort=False)[key].nunique()
    return having[having["instance"].isin(ran.index[ran == values])]


def factorial(runs_df: pd.DataFrame, keys: list[str], asked: dict[str, dict]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The main effect of each setting over the others, per instance and across instances
    (``instance`` "all"), on each instance's question (across instances: the final-cost score,
    or the evaluations when every instance is tied), paired by the other settings and the seed
    (and the instance) when every value ran on the same such blocks. Only for two or more
    settings that vary (with one, the configurations are its values: :func:`within_instances`
    answers). Per setting, the omnibus p-values (with two values: the one pair's) are
    Holm-adjusted over the instances. Returns the tests and the median final / f_ref per
    (setting, instance, value)."""
    varying = [k for k in keys if runs_df.loc[runs_df[k] != "", k].nunique() >= 2]
    tests, medians = [], []
    all_tied = bool(asked) and all(q["tied"] for q in asked.values())
    q_all = (dict(column=EVALS, tol=0.0, metric="evaluations to reach every run's final cost") if all_tied
             else dict(column=SCORE, tol=1.0, metric="final cost / f_ref"))  # fmt: skip
    for key in varying if len(varying) >= 2 else []:
        having = runs_df[runs_df[key] != ""]
        others = [k for k in keys if k != key]
        per_setting = []
        shared = _every_value_ran(having, key)
        scopes = [*having.groupby("instance", sort=False)] + ([("all", shared)] if shared["instance"].nunique() > 1 else [])
        for instance, g in scopes:  # across instances only where there are several: else it is the one instance again
            q = asked.get(instance, q_all)
            groups, best = _factor_scope(g, key, others, q["column"], q["tol"], instance == "all")
            if len(groups) < 2:  # one value here: nothing to set it against (no line in the main effects either)
                continue
            for v, h in g.groupby(key, sort=True):
                medians.append(dict(setting=key, instance=instance, value=describe(key, str(v)), runs=len(h),
                                    median_final_over_ref=float(h["final_over_ref"].median()),
                                    median=float(h[q["column"]].median()), metric=q["metric"]))  # fmt: skip
            t = stats.compare_design(groups, best=best, tol=q["tol"])
            for i, (name, value) in enumerate((("setting", key), ("instance", instance), ("best", best), ("metric", q["metric"]))):
                t.insert(i, name, value)
            per_setting.append(t)
        if per_setting:
            df = pd.concat(per_setting, ignore_index=True)
            sel = (df["a"] == "all") & (df["instance"] != "all")
            if not sel.any():  # two values: one pair per instance, corrected over the instances
                sel = (df["a"] != "all") & (df["instance"] != "all")
            _holm_over(df, sel)
            tests.append(df)
    columns = ["setting", "instance", "best", *COLUMNS]
    return (pd.concat(tests, ignore_index=True) if tests else pd.DataFrame(columns=columns),
            pd.DataFrame(medians, columns=["setting", "instance", "value", "runs", "median_final_over_ref", "median", "metric"]))  # fmt: skip


def interactions(runs_df: pd.DataFrame, keys: list[str], asked: dict[str, dict]) -> pd.DataFrame:
    """Per pair of varying settings and per instance, their interaction on the instance's
    question (:func:`zrp_ga.report.stats.interaction`), Holm-adjusted over every (pair,
    instance); ``found``: p (Holm) below the significance level."""
    varying = [k for k in keys if runs_df.loc[runs_df[k] != "", k].nunique() >= 2]
    rows = []
    for a, b in itertools.combinations(varying, 2):
        for instance, g in runs_df.groupby("instance", sort=False):
            g = g[(g[a] != "") & (g[b] != "")]
            if g[a].nunique() < 2 or g[b].nunique() < 2:  # a setting held on this instance: no interaction to test
                continue
            q = asked[instance]
            if q["tied"] and q["column"] == EVALS and g[EVALS].nunique() < 2:
                continue
            f, p = stats.interaction(g[q["column"]].to_numpy(dtype=float), g[a].to_numpy(), g[b].to_numpy())
            rows.append(dict(setting_a=a, setting_b=b, instance=instance, metric=q["metric"], test="aligned rank transform",
                             F=f, p=p))  # fmt: skip
    df = pd.DataFrame(rows, columns=["setting_a", "setting_b", "instance", "metric", "test", "F", "p"])
    df["p_holm"] = stats.holm(df["p"].to_numpy()) if len(df) else []
    df["found"] = df["p_holm"] < ALPHA
    return df


def validation(runs_df: pd.DataFrame, reference_mm: dict[str, float], tolerance: float) -> pd.DataFrame:
    """Per instance with validation poses: the configurations compared on their validation RMS
    error (mm), as the final costs are, errors closer than ``tolerance`` x the reference's
    (LM's; else the instance's median) tied. The best: the lowest median error."""
    out = []
    for instance, g in runs_df.dropna(subset=["val_rms_mm"]).groupby("instance", sort=False):
        block = _seed_blocks(g)
        groups = {lab: pd.Series(h["val_rms_mm"].to_numpy(dtype=float), index=block[h.index])
                  for lab, h in g.groupby("configuration", sort=False)}  # fmt: skip
        if len(groups) < 2:
            continue
        scale = reference_mm.get(instance, math.nan)
        scale = scale if math.isfinite(scale) and scale > 0 else float(g["val_rms_mm"].median())
        best = g.groupby("configuration", sort=False)["val_rms_mm"].median().idxmin()
        t = stats.compare_design(groups, best=best, tol=tolerance * scale)
        t.insert(0, "instance", instance)
        t.insert(1, "best", best)
        t.insert(2, "metric", f"validation RMS, mm (tied within {tolerance * scale:.3g} mm)")
        out.append(t)
    return pd.concat(out, ignore_index=True) if out else pd.DataFrame(columns=["instance", "best", *COLUMNS])
