"""Pose selection judged where it matters: the validation error of a calibration on the chosen
poses alone, against the number of poses k, for GA-chosen, exchange-chosen (DETMAX) and random
subsets, beside the calibration on all candidates; which observability index predicts it.

Reads the runs of the two sweeps (their summary.json) and writes the table, the statistics and
the figure into experiments/results/pose_selection; the calibration on all candidates is one
more zrp-ga run per arm (``problem.reference=true``), made here if it is not there yet. Two
things the runs' files do not hold are computed here on the same instances: the error of each
run's calibration over all candidates (the poses it could have used: series B for the UR10), and
``--random`` more random subsets per arm and k, whose indices and validation errors say which
index predicts the validation error (20 random runs per k are too few for that):

    zrp-ga -m experiment=pose_selection_study hydra/launcher=joblib
    zrp-ga -m experiment=pose_selection_random hydra/launcher=joblib
    python experiments/pose_selection.py [--runs multirun/pose_selection] [--out DIR] [--random 100]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from scipy import stats

from zrp_ga import config, report
from zrp_ga.operators import subset
from zrp_ga.run import build, execute

RESULTS = Path(__file__).parent / "results" / "pose_selection"
ARMS = {"pose_selection": "simulated PUMA 560: 500 candidates, full poses",
        "ur10_selection": "real UR10: 1,495 series-B rows, positions; validated on series C"}  # fmt: skip
METHODS = {"ga": "GA (O1)", "exchange": "exchange, DETMAX (O1)", "random_search": "random subset"}
INDICES = ("O1", "O2", "O3", "O4", "A")


def runs_table(root: Path) -> pd.DataFrame:
    """One row per finished run: arm, method, k, seed, the judgement and the indices of its choice."""
    runs, skipped = report.find_runs([root / "study", root / "random"])
    for path, why in skipped:
        print(f"left out {path}: {why}")
    rows = []
    for r in runs:
        s, sel = r.summary, r.summary["selection"]
        rows.append(dict(arm=r.overrides["problem"], method=r.overrides["algorithm"], k=int(r.overrides["problem.k"]),
                         seed=int(r.overrides["seed"]), val_rms_mm=s["validation_rms_mm"]["calibrated"],
                         nominal_val_rms_mm=s["validation_rms_mm"]["nominal"], param_err=s["param_err"]["calibrated"],
                         identified=sel["identified_directions"], directions=sel["identifiable_directions"],
                         final_cost=s["final_cost"], nevals=s["nevals"], wall_s=s["wall_s"], run=str(r.path),
                         **{f"cost_{i}": (sel["indices"][i] if i == "A" else 1.0 / sel["indices"][i]) for i in INDICES}))  # fmt: skip
    return pd.DataFrame(rows).astype({"param_err": float})


def reference(arm: str, root: Path) -> dict:
    """The calibration on all candidates of ``arm`` (a zrp-ga run with ``problem.reference=true``;
    its ``selection.all_candidates``), with the number of candidates."""
    out = root / "reference" / arm
    if not (out / "summary.json").exists():
        over = ["experiment=pose_selection_study", f"problem={arm}", "algorithm=random_search", "problem.reference=true"]
        execute.run(config.load(over), out)
    s = json.loads((out / "summary.json").read_text())["selection"]
    return {**s["all_candidates"], "candidates": s["candidates"]}


def task_of(arm: str):
    """The selection task of ``arm`` as the sweeps built it (the same instance, any k)."""
    over = ["experiment=pose_selection_study", f"problem={arm}"]
    return build.prepare(config.load(over), None).task


def with_candidates_rms(df: pd.DataFrame, tasks: dict) -> pd.DataFrame:
    """``candidates_rms_mm``: each run's calibration (on its chosen poses, again) over all candidates."""
    rms = []
    for r in df.itertuples():
        poses = json.loads((Path(r.run) / "summary.json").read_text())["selection"]["poses"]
        rms.append(tasks[r.arm].candidates_rms_m(np.array(poses)) * 1e3)
    return df.assign(candidates_rms_mm=rms)


def random_subsets(tasks: dict, ks: list[int], n: int) -> pd.DataFrame:
    """``n`` random subsets per arm and k (seeded by k): their indices, and the validation and
    candidates error of a calibration on each."""
    rows = []
    for arm, task in tasks.items():
        for k in ks:
            X = subset.sample(np.random.default_rng([k, 7]), n, k, task.problem.n_candidates)
            values = task.problem.indices(X)
            for i, S in enumerate(X):
                j = task.judgement(S)
                rows.append(dict(arm=arm, k=k, val_rms_mm=j.val_rms_m[1] * 1e3, candidates_rms_mm=task.candidates_rms_m(S) * 1e3,
                                 **{f"cost_{c}": (values[c][i] if c == "A" else 1.0 / values[c][i]) for c in INDICES}))  # fmt: skip
    return pd.DataFrame(rows)


def _iqr(x: pd.Series) -> tuple[float, float, float]:
    return tuple(np.nanpercentile(x.to_numpy(dtype=float), [50, 25, 75]))


def a12(x: np.ndarray, y: np.ndarray) -> float:
    """Vargha-Delaney A12: P(a value of x is below one of y) + P(tie) / 2 (lower error is better)."""
    u = stats.mannwhitneyu(x, y, alternative="two-sided").statistic
    return 1.0 - u / (len(x) * len(y))


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per arm, k and method: validation error (median and quartiles), error over all candidates,
    parameter error (simulation), the O1 cost, directions identified, evaluations, wall time."""
    rows = []
    for (arm, k, method), g in df.groupby(["arm", "k", "method"], sort=True):
        med, q1, q3 = _iqr(g.val_rms_mm)
        rows.append(dict(arm=arm, k=k, method=method, runs=len(g), val_rms_mm_median=med, val_rms_mm_q1=q1,
                         val_rms_mm_q3=q3, candidates_rms_mm_median=float(np.median(g.candidates_rms_mm)),
                         param_err_median=float(g.param_err.median()), O1_cost_median=float(np.median(g.cost_O1)),
                         identified=f"{int(g.identified.min())}-{int(g.identified.max())} of {int(g.directions.iloc[0])}",
                         nevals_median=float(np.median(g.nevals)), wall_s_median=float(np.median(g.wall_s))))  # fmt: skip
    return pd.DataFrame(rows)


def tests_table(df: pd.DataFrame) -> pd.DataFrame:
    """Mann-Whitney U (two-sided) and A12 on the validation error, per arm and k, for each pair of methods."""
    rows = []
    for (arm, k), g in df.groupby(["arm", "k"], sort=True):
        for a, b in (("ga", "random_search"), ("exchange", "random_search"), ("ga", "exchange")):
            x, y = (g.loc[g.method == m, "val_rms_mm"].to_numpy(dtype=float) for m in (a, b))
            rows.append(dict(arm=arm, k=k, a=a, b=b, n_a=len(x), n_b=len(y),
                             p=stats.mannwhitneyu(x, y, alternative="two-sided").pvalue, a12=a12(x, y)))  # fmt: skip
    return pd.DataFrame(rows)


def correlation_table(groups: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Spearman's rank correlation between each index's cost (1/O1 .. 1/O4, A) and the
    validation error, per arm, k and set of subsets."""
    rows = []
    for name, df in groups.items():
        for (arm, k), g in df.groupby(["arm", "k"], sort=True):
            row = dict(arm=arm, k=k, subsets=name, n=len(g))
            row.update({f"rho_{i}": stats.spearmanr(g[f"cost_{i}"], g.val_rms_mm).statistic for i in INDICES})
            rows.append(row)
    return pd.DataFrame(rows)


def figure(summary: pd.DataFrame, refs: dict[str, dict], path: Path) -> None:
    """Validation RMS error against k: median and interquartile range per method, one panel per
    arm, the calibration on all candidates and (if within the axes) the nominal arm as lines."""
    fig, axes = plt.subplots(1, len(ARMS), figsize=(11, 4.2))
    for ax, (arm, title) in zip(axes, ARMS.items()):
        s, ref = summary[summary.arm == arm], refs[arm]
        for j, (method, label) in enumerate(METHODS.items()):
            m = s[s.method == method].sort_values("k")
            x = m.k.to_numpy() * (1 + 0.04 * (j - 1))  # side by side on the log axis
            err = [m.val_rms_mm_median - m.val_rms_mm_q1, m.val_rms_mm_q3 - m.val_rms_mm_median]
            ax.errorbar(x, m.val_rms_mm_median, yerr=err, marker="o", ms=4, capsize=3, label=f"{label}: median, IQR")
        ax.axhline(ref["val_rms_mm"], ls="--", color="k", lw=1, label=f"all {ref['candidates']:,} candidates: {ref['val_rms_mm']:.3g} mm")
        lo, hi = 0.9 * min(s.val_rms_mm_q1.min(), ref["val_rms_mm"]), 1.1 * s.val_rms_mm_q3.max()
        nominal = ref["nominal_val_rms_mm"]
        ax.axhline(nominal, ls=":", color="grey", lw=1,
                   label=f"nominal arm: {nominal:.3g} mm" + ("" if lo <= nominal <= hi else " (off the axis)"))  # fmt: skip
        ax.set_ylim(lo, hi)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(sorted(s.k.unique()), [str(k) for k in sorted(s.k.unique())])
        ax.set_xticks([], minor=True)
        ax.set_xlabel("poses chosen, k")
        ax.set_ylabel("validation RMS position error, mm")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def markdown(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    from zrp_ga.report.common import markdown as table

    return table(df, floatfmt)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=Path, default=Path("multirun/pose_selection"))
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument("--random", type=int, default=100, help="random subsets per arm and k for the index question")
    parser.add_argument("--reuse", action="store_true",
                        help="take runs.csv and random_subsets.csv from --out (written by an earlier call) instead of recomputing")  # fmt: skip
    args = parser.parse_args()
    refs = {arm: reference(arm, args.runs) for arm in ARMS}
    if args.reuse:
        df, sample = pd.read_csv(args.out / "runs.csv"), pd.read_csv(args.out / "random_subsets.csv")
    else:
        tasks = {arm: task_of(arm) for arm in ARMS}
        df = with_candidates_rms(runs_table(args.runs), tasks)
        sample = random_subsets(tasks, sorted(df.k.unique()), args.random)
    summary, tests = summary_table(df), tests_table(df)
    rho = correlation_table({"random subsets (sample)": sample, "runs of the sweeps": df})
    args.out.mkdir(parents=True, exist_ok=True)
    df.to_csv(args.out / "runs.csv", index=False)
    sample.to_csv(args.out / "random_subsets.csv", index=False)
    figure(summary, refs, args.out / "val_rms_vs_k.png")
    ref_rows = pd.DataFrame([dict(arm=a, candidates=r["candidates"], val_rms_mm=r["val_rms_mm"], candidates_rms_mm=r["fit_rms_mm"],
                                  param_err=r["param_err"], nominal_val_rms_mm=r["nominal_val_rms_mm"], O1_cost=1.0 / r["indices"]["O1"])
                             for a, r in refs.items()])  # fmt: skip
    text = ["# Pose selection: validation error against k", "",
            "Commands: `zrp-ga -m experiment=pose_selection_study hydra/launcher=joblib`, "
            f"`zrp-ga -m experiment=pose_selection_random hydra/launcher=joblib`, `python experiments/pose_selection.py --random {args.random}`.",
            "Errors in mm; `candidates_rms_mm`: the calibration's RMS error over all candidates (for the UR10: series B).", "",
            "## Calibration on all candidates", "", markdown(ref_rows),
            "## Per arm, k and method", "", markdown(summary),
            "## Mann-Whitney U (two-sided) on the validation error; A12 = P(a below b)", "", markdown(tests, ".3g"),
            "## Spearman's rho between each index's cost (1/O1..1/O4, A) and the validation error", "", markdown(rho, ".2f")]  # fmt: skip
    (args.out / "summary.md").write_text("\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    main()
