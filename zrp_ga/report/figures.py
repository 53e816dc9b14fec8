"""The report's figures, drawn on ``matplotlib.figure.Figure`` objects (no pyplot, no backend
chosen: importing or running the report leaves the user's matplotlib alone). Each function
draws from tables the report has built from the runs' files."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from zrp_ga.report.runs import Run

COST_LABEL = "best cost (2-norm of the residual; m and rad)"


def save(fig: Figure, out: Path, name: str, formats: tuple[str, ...]) -> None:
    """``fig`` as ``out/name.<ext>`` for each format (the figures lay themselves out: constrained
    layout; the bounding box is the drawing's own, which keeps labels drawn outside the axes,
    such as the critical-difference diagram's long configuration names)."""
    for ext in formats:
        fig.savefig(out / f"{name}.{ext}", dpi=150, bbox_inches="tight")


def _legend_below(ax, n: int) -> None:
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False, ncol=1 if n > 4 else 2)


def convergence_runs(chosen: list[tuple[str, Run]], out: Path, formats: tuple[str, ...]) -> None:
    """The paper's Fig. 2: best cost per generation of single runs (one per configuration)."""
    fig = Figure(figsize=(6.5, 4.2), layout="constrained")
    ax = fig.subplots()
    values = []
    for label, run in chosen:
        conv = run.convergence
        best = conv["best"].where(np.isfinite(conv["best"]))
        ratio = run.summary.get("final_over_initial")
        note = f": final/initial {ratio:.3g}" if isinstance(ratio, (int, float)) else ""
        ax.plot(conv["gen"], best, marker="o", ms=2.5, label=f"{label}{note}")
        values.extend(best[best > 0].dropna())
    if values and max(values) / min(values) > 10:  # costs spanning a decade or more
        ax.set_yscale("log")
    ax.set_xlabel("generation (iteration)")
    ax.set_ylabel(COST_LABEL)
    ax.set_title("Convergence of single runs (the median run of each configuration)", fontsize=8)
    ax.legend(fontsize=7)
    save(fig, out, "fig2_convergence", formats)


def curves(runs: list[Run], grid: np.ndarray, scale: dict[str, float]) -> np.ndarray:
    """(R, G) best cost of each run within each budget of ``grid`` divided by ``scale`` of its
    instance (a run that stopped earlier keeps its final best; NaN on non-finite costs)."""
    out = np.full((len(runs), len(grid)), np.nan)
    for i, r in enumerate(runs):
        idx = np.searchsorted(r.evals, grid, side="right") - 1
        values = np.where(idx >= 0, r.best[np.clip(idx, 0, None)], np.nan) / scale[r.instance]
        out[i] = np.where(np.isfinite(values), values, np.nan)
    return out


def convergence_by_configuration(runs: list[Run], labels: list[str], shown: list[str], scale: dict[str, float],
                                 ylabel: str, note: str, out: Path, formats: tuple[str, ...]) -> None:  # fmt: skip
    """Median and interquartile band of the best cost (divided by ``scale`` per instance) per
    configuration against evaluations."""
    top = max(int(r.evals[-1]) for r in runs)
    grid = np.unique(np.geomspace(1, max(top, 2), 200).round())
    fig = Figure(figsize=(7.5, 4.5 + 0.18 * len(shown)), layout="constrained")
    ax = fig.subplots()
    for label in shown:
        members = [r for r, lab in zip(runs, labels) if lab == label]
        values = curves(members, grid, scale)
        values[:, grid > max(int(r.evals[-1]) for r in members)] = np.nan  # drawn up to the longest run
        with warnings.catch_warnings():  # a budget where every run's cost is NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            q1, med, q3 = np.nanpercentile(values, [25, 50, 75], axis=0)
        (line,) = ax.plot(grid, med, label=f"{label} ({len(values)} runs)")
        ax.fill_between(grid, q1, q3, color=line.get_color(), alpha=0.2)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("evaluations")
    ax.set_ylabel(ylabel)
    ax.set_title("Median and interquartile range of the best cost" + note, fontsize=9)
    _legend_below(ax, len(shown))
    save(fig, out, "convergence_by_configuration", formats)


def ecdf(curves_: pd.DataFrame, shown: list[str], ends: dict[str, float], what: str, note: str, out: Path,
         formats: tuple[str, ...]) -> None:  # fmt: skip
    """The fixed-target ECDF per configuration (rows of :func:`zrp_ga.report.targets.ecdf`), each
    drawn up to ``ends`` (its longest run, marked x as COCO does)."""
    fig = Figure(figsize=(7.5, 4.5 + 0.18 * len(shown)), layout="constrained")
    ax = fig.subplots()
    for label in shown:
        c = curves_[curves_["configuration"] == label]
        end = max(ends[label], c["evaluations"].max())
        (line,) = ax.step(np.r_[c["evaluations"], end], np.r_[c["fraction"], c["fraction"].iloc[-1]], where="post", label=label)
        ax.plot([end], [c["fraction"].iloc[-1]], "x", color=line.get_color())
    ax.set_xscale("log")
    ax.set_ylim(-0.01, 1.02)
    ax.set_xlabel("evaluations")
    ax.set_ylabel("fraction of (run, target) pairs hit")
    ax.set_title(f"Targets reached within n evaluations: {what}" + note, fontsize=8)
    _legend_below(ax, len(shown))
    save(fig, out, "ecdf_evals_to_target", formats)


def validation_boxplot(runs_df: pd.DataFrame, shown: list[str], note: str, out: Path, formats: tuple[str, ...]) -> bool:
    """Box plots of the final validation error per configuration; False (nothing drawn) when
    no run has a validation set."""
    data = {lab: runs_df.loc[runs_df.configuration == lab, "val_rms_mm"].dropna().to_numpy() for lab in shown}
    data = {lab: v for lab, v in data.items() if len(v)}
    if not data:
        return False
    fig = Figure(figsize=(7.5, 1.5 + 0.45 * len(data)), layout="constrained")
    ax = fig.subplots()
    names = list(data)[::-1]
    ax.boxplot([data[n] for n in names], orientation="horizontal", tick_labels=names)
    nominal = runs_df["val_rms_nominal_mm"].dropna()
    if len(nominal):
        ax.axvline(nominal.median(), ls="--", color="grey", label=f"nominal robot, median {nominal.median():.3g} mm")
        ax.legend(fontsize=7, loc="lower right")
    ax.set_xlabel("RMS position error on validation poses, mm")
    fig.suptitle("Final validation error per configuration" + note, fontsize=9)
    ax.tick_params(axis="y", labelsize=7)
    save(fig, out, "validation_error_boxplot", formats)
    return True


def critical_difference(result: dict, out: Path, formats: tuple[str, ...]) -> None:
    """Demšar's critical-difference diagram: mean ranks on an axis (1 = best, left), and a bar
    under each largest group of configurations whose ranks lie within the critical difference
    of Nemenyi's test (no difference detected among them)."""
    ranks = result["mean_ranks"]  # sorted, best first
    k, cd = len(ranks), result["cd"]
    names, r = list(ranks.index), ranks.to_numpy()
    cliques = []
    for i in range(k):
        j = int(np.searchsorted(r, r[i] + cd, side="right")) - 1  # the last within CD of r[i]
        if j > i and not any(a <= i and j <= b for a, b in cliques):
            cliques.append((i, j))
    half = (k + 1) // 2
    fig = Figure(figsize=(8, 1.6 + 0.3 * max(half, k - half) + 0.15 * len(cliques)), layout="constrained")
    ax = fig.subplots()
    ax.set_xlim(0.5, k + 0.5)
    ax.hlines(0, 1, k, color="k")
    for t in range(1, k + 1):
        ax.vlines(t, 0, 0.08, color="k")
        ax.text(t, 0.12, str(t), ha="center", va="bottom", fontsize=8)
    for n, (name, x) in enumerate(zip(names, r)):
        left = n < half
        y = -0.35 - 0.3 * (n if left else k - 1 - n)
        edge = 0.5 if left else k + 0.5
        ax.plot([x, x, edge], [0, y, y], color="k", lw=0.8)
        ax.text(edge + (0.05 if not left else -0.05), y, f"{name} ({x:.2f})", ha="right" if left else "left", va="center", fontsize=7,
                clip_on=False)  # fmt: skip
    for m, (i, j) in enumerate(cliques):
        ax.hlines(-0.12 - 0.08 * m, r[i] - 0.03, r[j] + 0.03, color="k", lw=3)
    ax.plot([1, 1 + cd], [0.45, 0.45], color="C3", lw=2)
    ax.text(1 + cd / 2, 0.5, f"CD = {cd:.2f}", ha="center", va="bottom", fontsize=8, color="C3")
    ax.set_ylim(-0.45 - 0.3 * max(half, k - half), 0.8)
    ax.axis("off")
    ax.set_title(f"Mean ranks over {result['instances']} instances ({result['test']} p = {result['p']:.3g}; "
                 f"bars: no difference by Nemenyi's test at {result['alpha']:g})", fontsize=8)  # fmt: skip
    save(fig, out, "critical_difference", formats)


def pose_error_figure(run_dir: str | Path) -> Figure:
    """Per-pose position errors before and after calibration, one panel per set of poses, drawn
    from a measured run's ``pose_errors.csv`` (a ``matplotlib.figure.Figure``, no backend chosen)."""
    table = pd.read_csv(Path(run_dir) / "pose_errors.csv")
    errors = {k: (g["nominal_mm"].to_numpy(), g["calibrated_mm"].to_numpy()) for k, g in table.groupby("set", sort=False)}
    fig = Figure(figsize=(8, 2.8 * len(errors)), layout="constrained")
    axes = fig.subplots(len(errors), 1, squeeze=False)
    for ax, (label, (before, after)) in zip(axes[:, 0], errors.items()):
        idx = np.arange(1, len(before) + 1)
        ax.plot(idx, before, ".", ms=2.5, alpha=0.6, label=f"nominal, registered (RMS {np.sqrt(np.mean(before**2)):.3g} mm)")
        ax.plot(idx, after, ".", ms=2.5, alpha=0.6, label=f"calibrated (RMS {np.sqrt(np.mean(after**2)):.3g} mm)")
        ax.set_xlabel(f"pose of the {label} set")
        ax.set_ylabel("position error, mm")
        ax.legend(fontsize=7, markerscale=3)
    return fig
