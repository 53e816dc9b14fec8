"""``zrp-ga-report DIR...``: tables, statistics and figures from finished runs.

Reads only the files runs wrote (convergence.csv, summary.json, best_params.csv,
initial_population.csv, status.json, the sweep manifest and Hydra's overrides.yaml) and never
re-runs anything, so a report can be redrawn at any time, also of a sweep still running.

Outputs, in ``--out`` (default ``report`` beside the first DIR):

- ``runs.csv``: one row per run (its settings, final cost, validation error, evaluations);
  ``tidy.csv``: one row per run and generation, one column per overridden setting;
- ``summary.csv``/``summary.md``: per configuration the number of runs, median and interquartile
  range of the final cost and of the final validation error, the final/initial cost ratio,
  evaluations to reach the target cost (median over the runs that reached it), success rate,
  and the area under the convergence curve;
- ``statistics.csv``/``statistics.md``: Kruskal-Wallis across configurations, pairwise
  Mann-Whitney U with Holm's correction and the Vargha-Delaney effect size A12, for the final
  cost and the final validation error; ``factors.csv``: the same test per setting, pooling the others;
- figures, PNG and PDF: convergence curves of single runs (the paper's Fig. 2: the median run
  of each of the four best configurations), the median and
  interquartile band per configuration against evaluations, the empirical distribution of
  evaluations to reach the target, and box plots of the final validation error;
- ``table2_initial_population.md`` and ``table3_best_params.md`` of the median run of the best
  configuration.

The target cost is ``--target`` or, by default, 1.05 times the lowest final cost of all runs.
The area under the curve is the mean of log10(best cost so far) over the evaluations from 0 to
the smallest final evaluation count of all runs (lower is better: good early and good late).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import sys
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import yaml  # noqa: E402
from scipy import stats  # noqa: E402

from zrp_ga.hydra_callbacks import MANIFEST, read_manifest  # noqa: E402

IGNORED_KEYS = ("hydra", "experiment", "progress", "checkpoint_every")


@dataclasses.dataclass
class Run:
    path: Path
    overrides: dict[str, str]
    summary: dict
    convergence: pd.DataFrame


# --- finding runs ----------------------------------------------------------------------------------
def _parse_overrides(items: list[str] | str) -> dict[str, str]:
    tokens = items.split() if isinstance(items, str) else list(items)
    out = {}
    for token in tokens:
        key, _, value = token.lstrip("+~").partition("=")
        if not key.startswith(IGNORED_KEYS):
            out[key] = value
    return out


def _run_overrides(path: Path) -> dict[str, str]:
    f = path / ".hydra" / "overrides.yaml"
    return _parse_overrides(yaml.safe_load(f.read_text()) or []) if f.exists() else {}


def _load(path: Path, overrides: dict[str, str]) -> tuple[Run | None, str | None]:
    """The run in ``path``, or why it is left out."""
    if not (path / "summary.json").exists():
        status = "no summary.json"
        if (path / "status.json").exists():
            status = json.loads((path / "status.json").read_text()).get("status", status)
        return None, f"not finished ({status})"
    return Run(path, overrides, json.loads((path / "summary.json").read_text()), pd.read_csv(path / "convergence.csv")), None


def find_runs(paths: list[str | Path]) -> tuple[list[Run], list[tuple[str, str]]]:
    """Runs under ``paths`` (run directories, sweep directories, or folders holding them) and
    the ones left out, with the reason: failed, still running, interrupted."""
    runs, skipped, seen = [], [], set()

    def visit(path: Path) -> None:
        if path in seen or not path.is_dir():
            return
        seen.add(path)
        if (path / MANIFEST).exists():
            for job in read_manifest(path).itertuples():
                job_dir = path / str(job.dir)
                seen.add(job_dir)
                if job.status == "done":
                    run, why = _load(job_dir, _parse_overrides(job.overrides))
                elif job.status == "failed":
                    run, why = None, f"failed: {job.error}"
                else:
                    run, why = None, f"still {job.status}"
                runs.append(run) if run else skipped.append((str(job_dir), why))
            return
        if (path / "convergence.csv").exists():
            run, why = _load(path, _run_overrides(path))
            runs.append(run) if run else skipped.append((str(path), why))
            return
        for child in sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith(".")):
            visit(child)

    for p in paths:
        if not Path(p).exists():
            raise ValueError(f"{p}: no such directory")
        visit(Path(p).resolve())
    return runs, skipped


# --- labels ----------------------------------------------------------------------------------------
_WORDS = {
    ("algorithm", "ga"): "GA", ("algorithm", "lm"): "Levenberg-Marquardt", ("algorithm", "cmaes"): "CMA-ES",
    ("refine", "pinv"): "pseudo-inverse step", ("refine", "none"): "no pseudo-inverse step",
}  # fmt: skip
_FAMILIES = ("crossover", "mutation", "inversion", "rotation", "selection")


def describe(key: str, value: str) -> str:
    """A setting in words: ``crossover=sbx`` -> ``sbx crossover``, ``inversion=none`` -> ``no inversion``."""
    if (key, value) in _WORDS:
        return _WORDS[(key, value)]
    if key in _FAMILIES:
        return f"no {key}" if value == "none" else f"{value.replace('_', ' ')} {key}"
    short = {"population.mu": "mu", "population.lambda_": "lambda", "population.max_evals": "budget"}
    return f"{short.get(key, key)} {value}"


def configurations(runs: list[Run]) -> tuple[list[str], list[str]]:
    """A label per run from the settings that vary between runs (seeds aside), and those keys."""
    first = ["algorithm", "refine", "crossover", "mutation", "inversion", "rotation", "selection"]
    keys = sorted({k for r in runs for k in r.overrides} - {"seed"}, key=lambda k: (first.index(k) if k in first else len(first), k))
    values = {k: {r.overrides.get(k, "(default)") for r in runs} for k in keys}
    varying = [k for k in keys if len(values[k]) > 1]
    labels = []
    for r in runs:
        parts = [describe(k, r.overrides.get(k, "(default)")) for k in varying]
        algorithm = r.overrides.get("algorithm", "ga")
        if algorithm in ("lm", "cmaes"):  # GA settings mean nothing to LM and CMA-ES
            parts = [describe("algorithm", algorithm)]
        labels.append(", ".join(parts) if parts else "all runs")
    return labels, varying


# --- numbers ---------------------------------------------------------------------------------------
def evals_to_target(conv: pd.DataFrame, target: float) -> float:
    hit = conv.loc[conv["best"] <= target, "nevals"]
    return float(hit.iloc[0]) if len(hit) else np.inf


def best_so_far(conv: pd.DataFrame, grid: np.ndarray) -> np.ndarray:
    """The best cost seen by each evaluation count of ``grid`` (NaN before the first row)."""
    best = np.minimum.accumulate(conv["best"].to_numpy(dtype=float))
    idx = np.searchsorted(conv["nevals"].to_numpy(), grid, side="right") - 1
    return np.where(idx >= 0, best[np.clip(idx, 0, None)], np.nan)


def area_under_curve(conv: pd.DataFrame, budget: float) -> float:
    """Mean of log10(best so far) over evaluations [first row, ``budget``] (a step function)."""
    e = conv["nevals"].to_numpy(dtype=float)
    b = np.log10(np.minimum.accumulate(conv["best"].to_numpy(dtype=float)))
    keep = e < budget
    edges = np.append(e[keep], budget)
    return float(np.sum(b[keep] * np.diff(edges)) / (budget - e[0])) if budget > e[0] else float(b[0])


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values. By hand: scipy.stats has Benjamini-Hochberg
    (``false_discovery_control``) but not Holm, and statsmodels would be a dependency for six lines."""
    p = np.asarray(p, dtype=float)
    order = np.argsort(p)
    m = len(p)
    adjusted = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(adjusted, 1.0)
    return out


def compare(groups: dict[str, np.ndarray], metric: str) -> pd.DataFrame:
    """Kruskal-Wallis across groups, then Mann-Whitney U for every pair, Holm-adjusted, with A12
    = P(a run of A ends lower than a run of B) + P(tie) / 2."""
    groups = {k: v[np.isfinite(v)] for k, v in groups.items()}
    groups = {k: v for k, v in groups.items() if len(v)}
    rows = []
    if len(groups) >= 2:
        try:
            h, p = stats.kruskal(*groups.values())
        except ValueError:  # every value equal
            h, p = 0.0, 1.0
        rows.append(dict(metric=metric, test="Kruskal-Wallis", a="all", b="all", statistic=h, p=p, p_holm=p,
                         a12=np.nan, n_a=sum(map(len, groups.values())), n_b=np.nan))  # fmt: skip
    pairs = []
    for a, b in itertools.combinations(groups, 2):
        x, y = groups[a], groups[b]
        u, p = stats.mannwhitneyu(x, y, alternative="two-sided")
        pairs.append(dict(metric=metric, test="Mann-Whitney U", a=a, b=b, statistic=u, p=p,
                          a12=1.0 - u / (len(x) * len(y)), n_a=len(x), n_b=len(y)))  # fmt: skip
    if pairs:
        for row, ph in zip(pairs, holm([r["p"] for r in pairs])):
            row["p_holm"] = ph
    return pd.DataFrame(rows + pairs, columns=["metric", "test", "a", "b", "statistic", "p", "p_holm", "a12", "n_a", "n_b"])


def _iqr(x: np.ndarray) -> tuple[float, float, float]:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return tuple(np.percentile(x, [50, 25, 75])) if len(x) else (np.nan,) * 3


# --- the report ------------------------------------------------------------------------------------
def build_tables(runs: list[Run], target: float | None = None) -> dict[str, pd.DataFrame]:
    labels, varying = configurations(runs)
    target = target if target is not None else 1.05 * min(r.summary["final_cost"] for r in runs)
    budget = min(float(r.convergence["nevals"].iloc[-1]) for r in runs)
    per_run = []
    tidy = []
    for r, label in zip(runs, labels):
        row = dict(run=str(r.path), configuration=label, **{k: r.overrides.get(k, "(default)") for k in varying},
                   seed=r.summary.get("seed"), final_cost=r.summary["final_cost"],
                   final_over_initial=r.summary["final_over_initial"], nevals=r.summary["nevals"],
                   val_rms_mm=r.summary["validation_rms_mm"]["calibrated"],
                   val_rms_nominal_mm=r.summary["validation_rms_mm"]["nominal"], wall_s=r.summary["wall_s"],
                   evals_to_target=evals_to_target(r.convergence, target),
                   auc=area_under_curve(r.convergence, budget))  # fmt: skip
        per_run.append(row)
        conv = r.convergence.copy()
        conv.insert(0, "configuration", label)
        conv.insert(0, "run", str(r.path))
        for k in varying:
            conv[k] = r.overrides.get(k, "(default)")
        tidy.append(conv)
    runs_df = pd.DataFrame(per_run)
    summary = []
    for label, g in runs_df.groupby("configuration", sort=False):
        reached = g["evals_to_target"][np.isfinite(g["evals_to_target"])]
        cost, val, ratio = _iqr(g.final_cost), _iqr(g.val_rms_mm), _iqr(g.final_over_initial)
        summary.append(dict(
            configuration=label, runs=len(g), final_cost_median=cost[0], final_cost_q1=cost[1], final_cost_q3=cost[2],
            val_rms_mm_median=val[0], val_rms_mm_q1=val[1], val_rms_mm_q3=val[2], final_over_initial_median=ratio[0],
            evals_to_target_median=float(np.median(reached)) if len(reached) else np.inf,
            success_rate=len(reached) / len(g), auc_median=float(np.median(g.auc)), target=target, auc_budget=budget,
        ))  # fmt: skip
    summary_df = pd.DataFrame(summary).sort_values("final_cost_median", kind="stable").reset_index(drop=True)
    groups = {m: {lab: g[m].to_numpy(dtype=float) for lab, g in runs_df.groupby("configuration", sort=False)}
              for m in ("final_cost", "val_rms_mm")}  # fmt: skip
    statistics = pd.concat([compare(groups["final_cost"], "final_cost"), compare(groups["val_rms_mm"], "val_rms_mm")])
    factors = []
    for k in varying:
        by_value = {describe(k, v): g["final_cost"].to_numpy(dtype=float) for v, g in runs_df.groupby(k, sort=True)}
        f = compare(by_value, "final_cost")
        f.insert(0, "setting", k)
        factors.append(f)
    factors_df = pd.concat(factors) if factors else pd.DataFrame()
    return dict(runs=runs_df, tidy=pd.concat(tidy, ignore_index=True), summary=summary_df,
                statistics=statistics.reset_index(drop=True), factors=factors_df, labels=labels)  # fmt: skip


def _save(fig, out: Path, name: str) -> None:
    fig.tight_layout()
    for ext in ("png", "pdf"):
        fig.savefig(out / f"{name}.{ext}", dpi=150)
    plt.close(fig)


COST_LABEL = "best cost (2-norm of the residual; m and rad)"


def median_runs(runs: list[Run], labels: list[str], order: list[str]) -> list[tuple[str, Run]]:
    """For each configuration (in ``order``), its run with the median final cost."""
    out = []
    for label in order:
        members = sorted((r for r, lab in zip(runs, labels) if lab == label), key=lambda r: r.summary["final_cost"])
        out.append((label, members[(len(members) - 1) // 2]))
    return out


def plot_runs(chosen: list[tuple[str, Run]], out: Path) -> None:
    """The paper's Fig. 2: best cost per generation of single runs (one per configuration)."""
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    lo, hi = np.inf, 0.0
    for label, run in chosen:
        conv = run.convergence
        ratio = run.summary["final_over_initial"]
        ax.plot(conv["gen"], conv["best"], marker="o", ms=2.5, label=f"{label}: final/initial {ratio:.3g}")
        lo, hi = min(lo, conv["best"].min()), max(hi, conv["best"].max())
    if hi / max(lo, 1e-300) > 10:  # costs spanning a decade or more
        ax.set_yscale("log")
    ax.set_xlabel("generation (iteration)")
    ax.set_ylabel(COST_LABEL)
    ax.set_title("Convergence of single runs (the median run of each configuration; the paper: 0.241)", fontsize=8)
    ax.legend(fontsize=7)
    _save(fig, out, "fig2_convergence")


def plot_configurations(runs: list[Run], labels: list[str], tables: dict, out: Path, max_lines: int = 10) -> list[str]:
    """Median and interquartile band per configuration, the ECDF of evaluations to the target,
    box plots of validation error. With many configurations, the ``max_lines`` best are drawn."""
    order = list(tables["summary"]["configuration"])
    shown = order[:max_lines]
    top = max(float(r.convergence["nevals"].iloc[-1]) for r in runs)
    grid = np.unique(np.geomspace(1, top, 300).round())
    note = f" ({len(shown)} best of {len(order)} configurations)" if len(shown) < len(order) else ""
    fig, ax = plt.subplots(figsize=(7.5, 4.5 + 0.18 * len(shown)))
    for label in shown:
        curves = np.array([best_so_far(r.convergence, grid) for r, lab in zip(runs, labels) if lab == label])
        with warnings.catch_warnings():  # grid points before a run's first row are NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            q1, med, q3 = np.nanpercentile(curves, [25, 50, 75], axis=0)
        (line,) = ax.plot(grid, med, label=f"{label} ({len(curves)} runs)")
        ax.fill_between(grid, q1, q3, color=line.get_color(), alpha=0.2)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("evaluations")
    ax.set_ylabel(COST_LABEL)
    ax.set_title("Median and interquartile range of the best cost" + note, fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
    _save(fig, out, "convergence_by_configuration")

    target = float(tables["summary"]["target"].iloc[0])
    fig, ax = plt.subplots(figsize=(7.5, 4.5 + 0.18 * len(shown)))
    for label in shown:
        e = np.sort(tables["runs"].loc[tables["runs"].configuration == label, "evals_to_target"].to_numpy())
        frac = np.arange(1, len(e) + 1) / len(e)
        finite = np.isfinite(e)
        if finite.any():  # a step at each run's hit, held to the largest budget
            ax.step(np.r_[e[finite][0], e[finite], top], np.r_[0, frac[finite], frac[finite][-1]], where="post", label=label)
        else:
            ax.plot([], [], label=f"{label} (never)")
    ax.set_xscale("log")
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("evaluations to reach the target cost")
    ax.set_ylabel("fraction of runs")
    ax.set_title(f"Runs that reached the target cost {target:.4g} within n evaluations" + note, fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
    _save(fig, out, "ecdf_evals_to_target")

    fig, ax = plt.subplots(figsize=(7.5, 0.5 + 0.45 * len(shown) + 1))
    data = [tables["runs"].loc[tables["runs"].configuration == lab, "val_rms_mm"].to_numpy() for lab in shown]
    ax.boxplot(data[::-1], orientation="horizontal", tick_labels=shown[::-1])
    nominal = float(tables["runs"]["val_rms_nominal_mm"].median())
    ax.axvline(nominal, ls="--", color="grey", label=f"nominal robot, median {nominal:.3g} mm")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_xlabel("RMS position error on validation poses, mm")
    fig.suptitle("Final validation error per configuration" + note, fontsize=9)
    ax.tick_params(axis="y", labelsize=7)
    _save(fig, out, "validation_error_boxplot")
    return shown


def pose_error_figure(run_dir: str | Path):
    """Per-pose position errors before and after calibration, one panel per set of poses, drawn
    from a measured run's ``pose_errors.csv`` (a ``matplotlib.figure.Figure``, no backend chosen)."""
    from matplotlib.figure import Figure

    table = pd.read_csv(Path(run_dir) / "pose_errors.csv")
    errors = {k: (g["nominal_mm"].to_numpy(), g["calibrated_mm"].to_numpy()) for k, g in table.groupby("set", sort=False)}
    fig = Figure(figsize=(8, 2.8 * len(errors)))
    axes = fig.subplots(len(errors), 1, squeeze=False)
    for ax, (label, (before, after)) in zip(axes[:, 0], errors.items()):
        idx = np.arange(1, len(before) + 1)
        ax.plot(idx, before, ".", ms=2.5, alpha=0.6, label=f"nominal, registered (RMS {np.sqrt(np.mean(before**2)):.3g} mm)")
        ax.plot(idx, after, ".", ms=2.5, alpha=0.6, label=f"calibrated (RMS {np.sqrt(np.mean(after**2)):.3g} mm)")
        ax.set_xlabel(f"pose of the {label} set")
        ax.set_ylabel("position error, mm")
        ax.legend(fontsize=7, markerscale=3)
    fig.tight_layout()
    return fig


def _markdown(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        cells = [format(v, floatfmt) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_report(
    paths: list[str | Path], out: str | Path | None = None, target: float | None = None, only: list[str] = ()
) -> dict:
    """Build every table and figure of the runs under ``paths`` into ``out``; returns the tables.
    ``only``: ``KEY=VALUE`` settings a run must have been given to count (e.g. ``refine=none``)."""
    runs, skipped = find_runs(paths)
    wanted = _parse_overrides(list(only))
    runs = [r for r in runs if all(r.overrides.get(k) == v for k, v in wanted.items())]
    if not runs:
        reasons = "; ".join(f"{p}: {why}" for p, why in skipped) or "no convergence.csv found"
        raise ValueError(f"no finished run under {', '.join(map(str, paths))} ({reasons})")
    out = Path(out) if out is not None else Path(paths[0]) / "report"
    out.mkdir(parents=True, exist_ok=True)
    tables = build_tables(runs, target)
    tables["runs"].to_csv(out / "runs.csv", index=False)
    tables["tidy"].to_csv(out / "tidy.csv", index=False)
    tables["summary"].to_csv(out / "summary.csv", index=False)
    tables["statistics"].to_csv(out / "statistics.csv", index=False)
    tables["factors"].to_csv(out / "factors.csv", index=False)
    (out / "summary.md").write_text(_markdown(tables["summary"]))
    (out / "statistics.md").write_text(_markdown(tables["statistics"]))
    if len(tables["factors"]):
        (out / "factors.md").write_text(_markdown(tables["factors"]))
    labels = tables["labels"]
    shown = plot_configurations(runs, labels, tables, out)
    chosen = median_runs(runs, labels, list(tables["summary"]["configuration"])[:4])
    plot_runs(chosen, out)
    one = chosen[0][1]  # Tables 2 and 3: the median run of the best configuration
    (out / "table2_initial_population.md").write_text(_markdown(pd.read_csv(one.path / "initial_population.csv")))
    (out / "table3_best_params.md").write_text(_markdown(pd.read_csv(one.path / "best_params.csv")))
    left_out = pd.DataFrame(skipped, columns=["run", "reason"])
    left_out.to_csv(out / "left_out.csv", index=False)
    tables.update(left_out=left_out, shown=shown, single_run=str(one.path))
    return tables


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="zrp-ga-report", description="Tables, statistics and figures of finished zrp-ga runs.")
    parser.add_argument("dirs", nargs="+", help="run directories, sweep directories, or folders holding them")
    parser.add_argument("--out", default=None, help="report directory (default: DIR/report of the first DIR)")
    parser.add_argument("--target", type=float, default=None, help="target cost (default: 1.05 x the lowest final cost)")
    parser.add_argument("--only", action="append", default=[], metavar="KEY=VALUE",
                        help="keep only the runs given this setting (repeatable), e.g. --only refine=none")
    args = parser.parse_args(argv)
    try:
        tables = write_report(args.dirs, args.out, args.target, args.only)
    except ValueError as exc:
        print(f"zrp-ga-report: error: {exc}", file=sys.stderr)
        sys.exit(2)
    out = args.out or Path(args.dirs[0]) / "report"
    print(f"{len(tables['runs'])} runs in {tables['summary'].shape[0]} configurations; report in {out}")
    for run, why in tables["left_out"].itertuples(index=False):
        print(f"left out {run}: {why}")
    print(_markdown(tables["summary"][["configuration", "runs", "final_cost_median", "val_rms_mm_median", "success_rate"]]))


if __name__ == "__main__":
    main()
