"""Which settings matter on which instance: each swept setting's effect, instance by instance.

    python experiments/suite_factors.py REPORT_DIR [--out FILE]

Reads the ``runs.csv`` that ``zrp-ga-report`` wrote for a suite sweep (one row per run: the
instance, each swept setting, ``final_over_ref`` = final cost over the instance's floor) and
writes, for every setting and instance, the median of final/floor at each of the setting's
values, the Kruskal-Wallis test between them (scipy.stats.kruskal) and the best value; then the
same pooled over instances, where final/floor (not the raw cost, whose scale differs between
instances) is compared. A setting "matters" on an instance when p < 0.05 after Holm's
correction over the instances (statsmodels is not a dependency: Holm's step-down is four
lines, written below).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from zrp_ga.report.cli import markdown

NOT_SETTINGS = {"run", "configuration", "instance", "seed", "final_cost", "reference", "final_over_ref",
                "final_over_initial", "nevals", "val_rms_mm", "val_rms_nominal_mm", "wall_s", "evals_to_target",
                "auc", "auc_budget"}  # fmt: skip


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p values."""
    order = np.argsort(p)
    adjusted = np.maximum.accumulate((len(p) - np.arange(len(p))) * p[order])
    out = np.empty_like(p)
    out[order] = np.minimum(adjusted, 1.0)
    return out


def effects(runs: pd.DataFrame, setting: str) -> pd.DataFrame:
    """One row per instance (and one pooled): median final/floor per value, Kruskal-Wallis p."""
    rows = []
    for instance, group in [*runs.groupby("instance", sort=False), ("all (pooled)", runs)]:
        by = {str(v): g["final_over_ref"].to_numpy() for v, g in group.groupby(setting)}
        p = stats.kruskal(*by.values()).pvalue if len(by) > 1 else np.nan
        medians = {v: float(np.median(x)) for v, x in by.items()}
        rows.append({"instance": instance, **{f"median {v}": m for v, m in medians.items()}, "p": p,
                     "best": min(medians, key=medians.get)})  # fmt: skip
    df = pd.DataFrame(rows)
    per_instance = df["instance"] != "all (pooled)"
    df["p_holm"] = np.nan
    df.loc[per_instance, "p_holm"] = holm(df.loc[per_instance, "p"].to_numpy())
    df["matters"] = np.where(per_instance, df["p_holm"] < 0.05, df["p"] < 0.05)
    return df


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path, help="a zrp-ga-report output directory (its runs.csv)")
    parser.add_argument("--out", type=Path, default=None, help="markdown file (default REPORT/factors_by_instance.md)")
    args = parser.parse_args()
    runs = pd.read_csv(args.report / "runs.csv")
    settings = [c for c in runs.columns if c not in NOT_SETTINGS and runs[c].nunique() > 1]
    lines = [f"# Settings by instance ({len(runs)} runs, {runs['instance'].nunique()} instances)\n",
             f"Command: `python experiments/suite_factors.py {args.report}`. Median of final cost / floor per "
             "value; Kruskal-Wallis p per instance, Holm-corrected over the instances (p_holm); pooled: all "
             "instances together on final / floor.\n"]  # fmt: skip
    for setting in settings:
        df = effects(runs, setting)
        lines += [f"## {setting}\n", markdown(df), ""]
    best = runs.groupby(["instance", "configuration"], sort=False)["final_over_ref"].median().reset_index()
    top = best.loc[best.groupby("instance", sort=False)["final_over_ref"].idxmin()]
    lines += ["## Best configuration per instance (median final / floor)\n", markdown(top), ""]
    out = args.out or args.report / "factors_by_instance.md"
    out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
