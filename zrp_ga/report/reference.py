"""The reference to beat on each instance, as COCO draws the best of 2009: Levenberg-Marquardt
(the least-squares solver a calibration engineer would use first) and, where it ran beside
another algorithm, CMA-ES; and the practical answer against LM: how close the best
configuration gets to it, in cost, in validation error and in evaluations, and how often.

LM's figures come from its runs in the report (``algorithm=lm``) or else from the floor record
the runs carry (summary.json's ``floor``, written with ``objective=over_floor``: LM's cost,
evaluations ``lm_nevals`` and validation error ``lm_val_rms_mm`` on the instance). Without
either there is no reference, and f* is the best run itself."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from zrp_ga.report import stats
from zrp_ga.report.runs import Run, number
from zrp_ga.report.targets import first_hit

NAMES = {"lm": "Levenberg-Marquardt", "cmaes": "CMA-ES"}
COLUMNS = ["instance", "reference", "source", "runs", "cost", "over_ref", "val_rms_mm", "nevals", "evals_to_floor", "reached"]


def algorithm(run: Run) -> str:
    """The run's algorithm as Hydra names it (ga, lm, cmaes, ...)."""
    return str(run.choices.get("algorithm") or run.summary.get("algorithm") or "?").lower()


def reference_configurations(runs: list[Run], labels: list[str]) -> set[str]:
    """The configurations that are references: LM's, and CMA-ES's where another algorithm (not
    LM) ran too (else CMA-ES is what the study is about)."""
    algos = {lab: algorithm(r) for r, lab in zip(runs, labels)}
    others = {a for a in algos.values() if a not in NAMES}
    return {lab for lab, a in algos.items() if a == "lm" or (a == "cmaes" and others)}


def _floor_record(group: list[Run]) -> dict | None:
    """LM's figures from the runs' floor records (the lowest cost's), None without any."""
    records = [r.summary["floor"] for r in group if isinstance(r.summary.get("floor"), dict)]
    records = [f for f in records if math.isfinite(number(f.get("cost")))]
    return min(records, key=lambda f: number(f.get("cost"))) if records else None


def table(runs: list[Run], labels: list[str], floors: pd.DataFrame) -> pd.DataFrame:
    """Per instance and reference: runs, median final cost and its ratio to f_ref, median
    validation error (mm), median evaluations made, median evaluations to reach the floor (within
    the instance's tolerance) and the share of runs that did."""
    f = floors.set_index("instance")
    refs = reference_configurations(runs, labels)
    rows = []
    for instance in f.index:
        ref, tol = float(f.loc[instance, "reference"]), float(f.loc[instance, "tolerance"])
        on = [(r, lab) for r, lab in zip(runs, labels) if r.instance == instance]
        for key, name in NAMES.items():
            mine = [r for r, lab in on if lab in refs and algorithm(r) == key]
            if mine:
                hit = np.array([first_hit(r.evals, r.best, (1 + tol) * ref) for r in mine])
                ok = np.isfinite(hit)
                rows.append(dict(instance=instance, reference=name, source="its runs in this report", runs=len(mine),
                                 cost=float(np.median([r.final_cost for r in mine])),
                                 over_ref=float(np.median([r.final_cost for r in mine])) / ref if ref > 0 else math.nan,
                                 val_rms_mm=float(np.nanmedian([r.validation_mm("calibrated") for r in mine]))
                                 if any(math.isfinite(r.validation_mm("calibrated")) for r in mine) else math.nan,
                                 nevals=float(np.median([r.nevals for r in mine])),
                                 evals_to_floor=float(np.median(hit[ok])) if ok.any() else math.inf, reached=float(ok.mean())))  # fmt: skip
            elif key == "lm" and (record := _floor_record([r for r, _ in on])) is not None:
                cost = number(record.get("cost"))
                rows.append(dict(instance=instance, reference=name, source="the runs' floor record (objective=over_floor)", runs=1,
                                 cost=cost, over_ref=cost / ref if ref > 0 else math.nan,
                                 val_rms_mm=number(record.get("lm_val_rms_mm")), nevals=number(record.get("lm_nevals")),
                                 evals_to_floor=number(record.get("lm_nevals")), reached=1.0))  # fmt: skip
    return pd.DataFrame(rows, columns=COLUMNS)


def answer(runs: list[Run], labels: list[str], runs_df: pd.DataFrame, floors: pd.DataFrame, ref: pd.DataFrame,
           order: list[str]) -> dict | None:  # fmt: skip
    """The practical answer against LM, None without an LM reference: the best configuration
    (first of ``order`` that is not a reference), on the instances where both ran: its median
    final cost over LM's (and the range of the per-instance medians), validation error against
    LM's, how many of its runs come within the tolerance of LM's cost and their median
    evaluations against LM's; over every non-reference run: how many come within 1.1 x LM's
    cost and the closest."""
    lm = ref[ref["reference"] == NAMES["lm"]].set_index("instance")
    refs = reference_configurations(runs, labels)
    best = next((c for c in order if c not in refs), None)
    if not len(lm) or best is None:
        return None
    f = floors.set_index("instance")
    rows = []
    for i, (r, lab) in enumerate(zip(runs, labels)):
        if lab in refs or r.instance not in lm.index:
            continue
        inst = r.instance
        cost = max(float(lm.loc[inst, "cost"]), float(f.loc[inst, "reference"]))  # round-off: the round-off floor
        tol = float(f.loc[inst, "tolerance"])
        rows.append(dict(row=i, configuration=lab, instance=inst, ratio=r.final_cost / cost if cost > 0 else math.nan,
                         within=r.final_cost <= (1 + tol) * cost, hit=first_hit(r.evals, r.best, (1 + tol) * cost),
                         val=r.validation_mm("calibrated"), nevals=r.nevals, tol=tol))  # fmt: skip
    df = pd.DataFrame(rows)
    mine = df[df["configuration"] == best] if len(df) else df
    if not len(mine):
        return None
    per = mine.groupby("instance")["ratio"].median()
    lm_on = lm.loc[sorted(set(mine["instance"]))]
    hits = mine.loc[mine["within"], "hit"]
    return dict(**_against(mine),
        best=best, instances=int(mine["instance"].nunique()), runs=len(mine), ratio=float(mine["ratio"].median()),
        ratio_lo=float(per.min()), ratio_hi=float(per.max()), val=float(mine["val"].median()), tol=float(mine["tol"].max()),
        lm_val=float(lm_on["val_rms_mm"].median()), within=int(mine["within"].sum()),
        evals=float(hits.median()) if len(hits) else math.nan, nevals=float(mine["nevals"].median()),
        lm_evals=float(lm_on["nevals"].median()), lm_source=str(lm_on["source"].iloc[0]),
        round_off=bool(f.loc[list(lm_on.index), "round_off"].any()), all_runs=len(df),
        all_within_11=int((df["ratio"] <= 1.1).sum()), closest=float(df["ratio"].min()),
    )  # fmt: skip


def _against(mine: pd.DataFrame) -> dict:
    """The best configuration's runs against LM's cost, one verdict: d = 1 - final / LM's cost
    per run (positive: lower than LM), Wilcoxon's signed-rank test with differences within the
    instance's tolerance as zeros, TOST at +-tolerance; every run within it: equivalent."""
    d = 1.0 - mine["ratio"].to_numpy(dtype=float)
    d = d[np.isfinite(d)]
    tol = float(mine["tol"].max())
    if not len(d):
        return dict(test="", p=math.nan, p_equivalence=math.nan, verdict=stats.UNDECIDED, tied=False)
    r = stats._paired_pairs(d[None, :], tol)
    verdict = stats.verdict(bool(r["tied"][0]), float(r["p"][0]), float(r["direction"][0]), float(r["p_eq"][0]))
    return dict(test=stats.ALL_TIED if r["tied"][0] else "Wilcoxon signed-rank (one sample: final / LM's cost - 1)",
                p=float(r["p"][0]), p_equivalence=float(r["p_eq"][0]), verdict=verdict, tied=bool(r["tied"][0]))  # fmt: skip
