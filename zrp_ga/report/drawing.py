"""Which figures a report draws, on which scale, and the caption that tells a reader what each
shows and how to read it (:mod:`zrp_ga.report.figures` draws them)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from zrp_ga.report import figures, targets
from zrp_ga.report.runs import Run
from zrp_ga.report.targets import TargetRule


def median_runs(runs: list[Run], labels: list[str], order: list[str]) -> list[tuple[str, Run]]:
    """For each configuration (in ``order``) that has runs, its run with the median final cost."""
    out = []
    for label in order:
        members = sorted((r for r, lab in zip(runs, labels) if lab == label), key=lambda r: (math.isnan(r.final_cost), r.final_cost))
        if members:
            out.append((label, members[(len(members) - 1) // 2]))
    return out


def fig2_instance(floors: pd.DataFrame) -> str:
    """The instance Fig. 2 draws: the one with the most runs (the first in name order on ties)."""
    f = floors.sort_values(["runs", "instance"], ascending=[False, True], kind="stable")
    return str(f["instance"].iloc[0])


def scale_of(floors: pd.DataFrame, rule: TargetRule) -> dict:
    """How the convergence curves are drawn: relative to the floor f* where every instance's
    floor means something (not round-off), absolute with one instance otherwise, else relative
    to each instance's nominal cost; the lines to draw and the label."""
    f = floors.set_index("instance")
    one = len(f) == 1
    meaningful = bool((~f["round_off"]).all() and (f["reference"] > 0).all() and np.isfinite(f["reference"]).all())
    if meaningful and rule.absolute is None:
        lines = {"floor f*": 1.0, **{f"{c:g} x f*": c for c in rule.levels if c != 1}}
        return dict(scale={i: float(v) for i, v in f["reference"].items()}, clip=None, lines=lines,
                    ylabel="best cost / floor f* of its instance", kind="relative to the floor")  # fmt: skip
    round_off = {i: rule.round_off * float(n) for i, n in f["nominal_cost"].items() if math.isfinite(n) and n > 0}
    if one:
        i = f.index[0]
        lines = {"round-off floor": round_off[i]} if i in round_off and f.loc[i, "round_off"] else {"floor f*": float(f.loc[i, "reference"])}
        if rule.absolute is not None:
            lines[f"target {rule.absolute:g}"] = rule.absolute
        return dict(scale={i: 1.0}, clip=round_off or None, lines=lines, ylabel=figures.COST_LABEL, kind="absolute")
    scale = {i: float(n) if n > 0 else math.nan for i, n in f["nominal_cost"].items()}
    return dict(scale=scale, clip={i: v for i, v in round_off.items()}, lines={"round-off floor": rule.round_off},
                ylabel="best cost / nominal cost of its instance", kind="relative to the nominal cost")  # fmt: skip


def draw(runs: list[Run], t: dict, stage: Path, formats: tuple[str, ...], rule: TargetRule,
         max_lines: int = figures.MAX_LINES) -> tuple[list[dict], list[str]]:  # fmt: skip
    """Every figure of the report into ``stage``: a list of {name, title, caption, svg} in the
    page's order, and the configurations drawn (the ``max_lines`` best)."""
    order = list(t["summary"]["configuration"])
    shown = order[:max_lines]
    k, n = len(shown), len(order)
    some = k < n
    note = f" ({k} best of {n} configurations)" if some else ""
    which = (f"The {k} best of the {n} configurations by median final cost / f_ref are drawn (more lines would not be "
             "told apart); every configuration is in the tables. ") if some else ""  # fmt: skip
    labels, floors = t["labels"], t["floors"]
    out: list[dict] = []

    s = scale_of(floors, rule)
    svg = figures.convergence_by_configuration(runs, labels, shown, s["scale"], s["ylabel"], s["lines"], note, stage, formats,
                                               clip=s["clip"])  # fmt: skip
    how = {
        "relative to the floor": "Costs are divided by each instance's floor f* (Levenberg-Marquardt's cost on it, which noise "
                                 "keeps above zero), so that 1 is the best any method reaches; dotted lines mark the target levels.",
        "absolute": f"Costs are absolute; costs below the floor are drawn at it (the line). {figures.COST_NOTE}",
        "relative to the nominal cost": "Costs are divided by each instance's nominal cost (the uncalibrated model's), since "
                                        "its floor is round-off; costs below the round-off floor (1e-9 of it) are drawn at it.",
    }[s["kind"]]  # fmt: skip
    out.append(dict(name="convergence_by_configuration", svg=svg, title="Convergence of each configuration",
                    caption=f"The median over runs (line) and the interquartile range (band) of the best cost found within n "
                            f"evaluations, against n on a log axis. {how} {which}Lower and further left is better; bands "
                            "that overlap mean the runs overlap."))  # fmt: skip

    tg = targets.ecdf_targets(runs, floors)
    if tg and rule.absolute is None:
        hits = targets.runtime_hits(runs, labels, tg)
        dims = {r.instance: max(targets.dimension(r), 1) for r in runs}
        start = 1.0 / max(dims.values())
        agg = targets.ecdf(hits, start)
        per = {i: targets.ecdf(h, start) for i, h in hits.groupby("instance", sort=True)}
        ends = (hits.groupby("configuration")["nevals"].max()).to_dict()
        ecdf_shown = [c for c in shown if c in set(hits["configuration"])]
        t["ecdf_targets"] = pd.DataFrame([dict(instance=i, k=j, target=v, over_ref=v / float(floors.set_index("instance").loc[i, "reference"]))
                                          for i, arr in tg.items() for j, v in enumerate(arr)])  # fmt: skip
        drawn = figures.ecdf(agg, per, ecdf_shown, ends, targets.ECDF_TARGETS, note, stage, formats)
        genes = sorted(set(dims.values()))
        per_gene = f"divided by the genome's length ({', '.join(map(str, genes))} genes)"
        base = (f"Runtime ECDF as COCO draws it: for {targets.ECDF_TARGETS} targets per instance, their distances to the floor "
                "f_ref log-spaced from the instance's starting cost f0 (the median first cost of its runs) down to the tightest "
                "level, 1.01 x f_ref (target k = f_ref + (f0 - f_ref) r^k), the fraction of (run, target) pairs reached within a "
                f"budget, the budget in evaluations {per_gene}. x: the longest run. Higher and further left is better; the value "
                "at the right end tells how close to the floor the runs came (1: every target, down to 1.01 x f_ref). ")  # fmt: skip
        for name, svg in drawn:
            if name == "ecdf_evals_to_target":
                out.append(dict(name=name, svg=svg, title="Targets reached, over all instances",
                                caption=base + ("Aggregated over the instances, each weighing the same. " if len(per) > 1 else "")
                                + which))  # fmt: skip
            else:
                out.append(dict(name=name, svg=svg, title="Targets reached, instance by instance",
                                caption=base + "One panel per instance: where the aggregate hides a difference, it shows here."))  # fmt: skip

    f = t["friedman"]
    if f is not None and f["configurations"] >= 3 and f["p"] < f["alpha"]:
        svg = figures.critical_difference(f, stage, formats)
        more = f["configurations"] > 12
        out.append(dict(name="critical_difference", svg=svg, title="Ranks across instances",
                        caption=f"The mean rank of each configuration over the {f['instances']} instances (rank 1: the lowest median "
                                "final cost on an instance; costs within the tightest target of the floor tie). Friedman's test "
                                f"says the ranks differ (p = {f['p']:.2g}); Nemenyi's critical difference CD = {f['cd']:.2f} is how far "
                                "apart two mean ranks must be for the test to tell the configurations apart. "
                                + ("Configurations in the shaded band cannot be told apart from the best. " if more else
                                   "Configurations joined by a bar cannot be told apart. ")))  # fmt: skip
    elif f is not None:
        t["cd_note"] = (f"No critical-difference diagram: {f['test']} finds no difference in ranks (p = {f['p']:.2g})"
                        if f["configurations"] >= 3 else "No critical-difference diagram: two configurations, the sign test says it all")  # fmt: skip

    svg = figures.validation_boxplot(t["runs"], shown, note, stage, formats)
    if svg is not None:
        out.append(dict(name="validation_error_boxplot", svg=svg, title="Validation error",
                        caption="The RMS position error of each run's calibrated model on poses it was not calibrated on "
                                "(box: quartiles, red: median, whiskers: 1.5 IQR; every run a point). " + which))  # fmt: skip

    instance = fig2_instance(floors)
    on = [(r, lab) for r, lab in zip(runs, labels) if r.instance == instance]
    present = [c for c in order if c in {lab for _, lab in on}]
    chosen = median_runs([r for r, _ in on], [lab for _, lab in on], present[:max_lines])
    row = floors.set_index("instance").loc[instance]
    round_off = bool(row["round_off"])
    floor = float(rule.round_off * row["nominal_cost"]) if round_off else float(row["reference"])
    svg = figures.convergence_runs(chosen, len(present), instance, floor, round_off, stage, formats)
    what = ("the round-off floor, 1e-9 of the nominal cost: lower costs are round-off and are drawn at it" if round_off
            else "the floor f*, Levenberg-Marquardt's cost")  # fmt: skip
    out.append(dict(name="fig2_convergence", svg=svg, title="Single runs (the paper's Fig. 2)",
                    caption=f"The best cost per generation of one run per configuration on {instance}: the run with the median "
                            f"final cost. The dotted line is {what}. {figures.COST_NOTE} "
                            + (f"The {len(chosen)} best of the {len(present)} configurations are drawn. " if len(chosen) < len(present) else "")))  # fmt: skip
    t["fig2"] = dict(instance=instance, chosen=chosen)
    return out, shown
