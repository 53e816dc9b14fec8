"""The report's figures, drawn on ``matplotlib.figure.Figure`` objects (no pyplot, no backend
chosen: importing or running the report leaves the user's matplotlib alone; the styles are
applied with ``matplotlib.rc_context``, which restores the user's settings). Each function
draws from tables the report has built from the runs' files and returns the figure's SVG text
for the report's page besides writing it in each of the requested formats.

Styles: ``paper`` sizes a figure to a paper's column (3.5 in wide; the critical-difference
diagram and the per-instance panels to the full text width, 7 in) with 8-9 pt text; ``screen``
to 7 in with 10 pt text."""

from __future__ import annotations

import contextlib
import io
import math
import textwrap
import warnings
from collections.abc import Iterator
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from zrp_ga.report.runs import Run

COST_LABEL = "best cost (residual 2-norm)"
COST_NOTE = ("The cost is the 2-norm of the residual, which stacks orientation errors (rad) and position errors (m) "
             "as the problem weighs them: it has no single unit.")  # fmt: skip
STYLES = {
    "paper": dict(width=3.5, wide=7.0, rc={"font.size": 8, "axes.titlesize": 9, "axes.labelsize": 8, "xtick.labelsize": 8,
                                           "ytick.labelsize": 8, "legend.fontsize": 8, "legend.title_fontsize": 8,
                                           "lines.linewidth": 1.0, "lines.markersize": 3, "axes.linewidth": 0.6}),
    "screen": dict(width=7.0, wide=7.0, rc={"font.size": 10, "axes.titlesize": 10, "axes.labelsize": 10, "xtick.labelsize": 10,
                                            "ytick.labelsize": 10, "legend.fontsize": 9, "legend.title_fontsize": 9,
                                            "lines.linewidth": 1.4, "lines.markersize": 4}),
}  # fmt: skip
_STYLE = {"name": "paper"}
MAX_LINES = 8  # configurations drawn in one axes before only the best are


@contextlib.contextmanager
def style(name: str) -> Iterator[None]:
    """Draw the figures made inside in style ``name`` (``paper`` or ``screen``)."""
    if name not in STYLES:
        raise ValueError(f"unknown style {name!r} (paper, screen)")
    before = _STYLE["name"]
    _STYLE["name"] = name
    try:
        with matplotlib.rc_context({**STYLES[name]["rc"], "pdf.fonttype": 42, "svg.fonttype": "path"}):
            yield
    finally:
        _STYLE["name"] = before


def width(wide: bool = False) -> float:
    """The figure width, inches, of the current style (``wide``: spanning a page's text)."""
    return STYLES[_STYLE["name"]]["wide" if wide else "width"]


def save(fig: Figure, out: Path, name: str, formats: tuple[str, ...]) -> str:
    """``fig`` as ``out/name.<ext>`` for each format (the bounding box is the drawing's own, which
    keeps labels drawn outside the axes); returns its SVG with text as text (for the page)."""
    for ext in formats:
        fig.savefig(out / f"{name}.{ext}", dpi=200, bbox_inches="tight", metadata={"Date": None} if ext in ("svg", "pdf") else None)
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": name}):
        fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    text = buf.getvalue()
    return text[text.index("<svg"):]


def wrap(label: str, paper: int = 44) -> str:
    """A label broken into lines that fit the style's width (a paper's column holds about 44
    characters of 8 pt text beside a legend's line sample)."""
    return textwrap.fill(label, paper if _STYLE["name"] == "paper" else 2 * paper, subsequent_indent="  ")


def _height(labels: list[str], axes: float = 2.3) -> float:
    """A figure's height, inches: ``axes`` for the axes and their labels, and room for a legend
    of ``labels`` below them (each wrapped)."""
    lines = sum(wrap(lab).count("\n") + 1 for lab in labels) + 1
    return axes + 0.16 * lines * (1.0 if _STYLE["name"] == "paper" else 1.2)


def _legend_below(ax, n: int, title: str | None = None) -> None:
    handles, labels = ax.get_legend_handles_labels()
    ax.legend(handles, [wrap(lab) for lab in labels], loc="upper center", bbox_to_anchor=(0.5, -0.18), frameon=False, ncol=1,
              title=wrap(title) if title else None, alignment="left")  # fmt: skip


def _styles(n: int) -> list[dict]:
    """Colour and line style of ``n`` lines, told apart in grey print too (ten colours, then
    dashed and dotted)."""
    return [dict(color=f"C{i % 10}", ls=("-", "--", ":", "-.")[i // 10 % 4]) for i in range(n)]


def _ylim_positive(ax, values: list[float]) -> None:
    v = np.asarray([x for x in values if x > 0 and math.isfinite(x)])
    if len(v) and v.max() / v.min() > 10:
        ax.set_yscale("log")


def convergence_runs(chosen: list[tuple[str, Run]], total: int, instance: str, floor: float, round_off: bool, out: Path,
                     formats: tuple[str, ...]) -> str:  # fmt: skip
    """The paper's Fig. 2: the best cost per generation of the median run of each configuration
    in ``chosen`` (of ``total``) on ``instance``; costs below ``floor`` (the round-off floor
    when ``round_off``, else LM's floor f*) are drawn at it, and the floor as a line."""
    fig = Figure(figsize=(width(), _height([lab for lab, _ in chosen] + ["floor"])), layout="constrained")
    ax = fig.subplots()
    values = []
    for (label, run), st in zip(chosen, _styles(len(chosen))):
        conv = run.convergence
        best = conv["best"].where(np.isfinite(conv["best"])).to_numpy(dtype=float)
        if math.isfinite(floor) and floor > 0:
            best = np.maximum(best, floor)
        ax.plot(conv["gen"], best, marker="o" if len(conv) <= 30 else None, ms=2, label=label, **st)
        values.extend(best[np.isfinite(best)])
    if math.isfinite(floor) and floor > 0:
        what = "round-off floor (1e-9 x nominal cost)" if round_off else "floor f* (LM's cost)"
        ax.axhline(floor, color="k", ls=(0, (1, 2)), lw=0.8, label=what)
        values.append(floor)
    _ylim_positive(ax, values)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("generation")
    ax.set_ylabel(COST_LABEL)
    shown = f"all {total} configurations" if len(chosen) == total else f"the {len(chosen)} best of {total} configurations"
    _legend_below(ax, len(chosen), f"median run of {shown}")
    return save(fig, out, "fig2_convergence", formats)


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
                                 ylabel: str, lines: dict[str, float], note: str, out: Path, formats: tuple[str, ...],
                                 clip: dict[str, float] | None = None) -> str:  # fmt: skip
    """Median and interquartile band of the best cost (divided by ``scale`` per instance; below
    ``clip`` per instance drawn at it) per configuration against evaluations; ``lines``:
    horizontal lines to draw, {label: y}."""
    top = max(int(r.evals[-1]) for r in runs)
    grid = np.unique(np.geomspace(1, max(top, 2), 200).round())
    fig = Figure(figsize=(width(), _height([f"{lab} (10 runs)" for lab in shown] + list(lines)[:2])), layout="constrained")
    ax = fig.subplots()
    for label, st in zip(shown, _styles(len(shown))):
        members = [r for r, lab in zip(runs, labels) if lab == label]
        values = curves(members, grid, scale)
        if clip:
            values = np.fmax(values, np.array([clip.get(r.instance, -np.inf) for r in members])[:, None])
        values[:, grid > max(int(r.evals[-1]) for r in members)] = np.nan  # drawn up to the longest run
        with warnings.catch_warnings():  # a budget where every run's cost is NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            q1, med, q3 = np.nanpercentile(values, [25, 50, 75], axis=0)
        ax.plot(grid, med, label=f"{label} ({len(values)} runs)", **st)
        ax.fill_between(grid, q1, q3, color=st["color"], alpha=0.15, lw=0)
    for i, (text, y) in enumerate(lines.items()):  # the first solid, the others (targets) dotted, named once
        dotted = i > 0
        names = text if not dotted else ("targets: " + ", ".join(list(lines)[1:]) if i == 1 else None)
        ax.axhline(y, color="k" if not dotted else "0.45", lw=0.7, ls=(0, (1, 2)) if dotted else "-", label=names, zorder=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("evaluations")
    ax.set_ylabel(ylabel)
    _legend_below(ax, len(shown), "median, band: interquartile range" + note)
    return save(fig, out, "convergence_by_configuration", formats)


def _ecdf_axes(ax, curves_: pd.DataFrame, shown: list[str], ends: dict[str, float], legend: bool) -> None:
    for label, st in zip(shown, _styles(len(shown))):
        c = curves_[curves_["configuration"] == label]
        if not len(c):
            continue
        end = max(ends.get(label, 0.0), c["evaluations"].max())
        ax.step(np.r_[c["evaluations"], end], np.r_[c["fraction"], c["fraction"].iloc[-1]], where="post",
                label=label if legend else None, **st)  # fmt: skip
        ax.plot([end], [c["fraction"].iloc[-1]], "x", color=st["color"])
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.02)


def ecdf(aggregated: pd.DataFrame, per_instance: dict[str, pd.DataFrame], shown: list[str], ends: dict[str, float],
         targets: int, note: str, out: Path, formats: tuple[str, ...]) -> list[tuple[str, str]]:  # fmt: skip
    """The fixed-target runtime ECDFs (COCO's), budgets in evaluations per gene: aggregated over
    the instances (``ecdf_evals_to_target``) and one panel per instance
    (``ecdf_by_instance``, when there are several); each curve drawn up to ``ends`` (its longest
    run, marked x). Returns (name, SVG) per figure."""
    fig = Figure(figsize=(width(), _height(shown)), layout="constrained")
    ax = fig.subplots()
    _ecdf_axes(ax, aggregated, shown, ends, True)
    ax.set_xlabel("evaluations / genes")
    ax.set_ylabel(f"fraction of {targets} targets hit")
    _legend_below(ax, len(shown), note.strip(" ()") or None)
    drawn = [("ecdf_evals_to_target", save(fig, out, "ecdf_evals_to_target", formats))]
    if len(per_instance) > 1:
        n = len(per_instance)
        cols = 3 if n > 4 else 2
        rows = math.ceil(n / cols)
        fig = Figure(figsize=(width(wide=True), 1.9 * rows + 0.4 + 0.16 * math.ceil(len(shown) / 2)), layout="constrained")
        axes = fig.subplots(rows, cols, sharex=True, sharey=True, squeeze=False).ravel()
        for k, (ax, (instance, c)) in enumerate(zip(axes, per_instance.items())):
            _ecdf_axes(ax, c, shown, ends, k == 0)
            ax.set_title(instance, fontsize="medium")
        for ax in axes[n:]:
            ax.set_visible(False)
        for k, ax in enumerate(axes[:n]):
            if k + cols >= n:  # the lowest panel of its column
                ax.set_xlabel("evaluations / genes")
                ax.xaxis.set_tick_params(labelbottom=True)
            if k % cols == 0:
                ax.set_ylabel(f"fraction of {targets}\ntargets hit")
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, [wrap(lab) for lab in labels], loc="outside lower center", frameon=False, ncol=2 if len(shown) > 1 else 1)
        drawn.append(("ecdf_by_instance", save(fig, out, "ecdf_by_instance", formats)))
    return drawn


def validation_boxplot(runs_df: pd.DataFrame, shown: list[str], note: str, out: Path, formats: tuple[str, ...],
                       points_up_to: int = 40) -> str | None:  # fmt: skip
    """Box plots of the final validation error per configuration, every run drawn as a point
    when a box holds at most ``points_up_to`` runs; the nominal robot's error as a line when it
    lies near the data, else in the axis label. None (nothing drawn) when no run has a
    validation set."""
    data = {lab: runs_df.loc[runs_df.configuration == lab, "val_rms_mm"].dropna().to_numpy() for lab in shown}
    data = {lab: v for lab, v in data.items() if len(v)}
    if not data:
        return None
    names = list(data)[::-1]
    ticks = [wrap(n, 30) for n in names]
    fig = Figure(figsize=(width(), 1.0 + sum(0.14 * (t.count("\n") + 1) + 0.1 for t in ticks)), layout="constrained")
    ax = fig.subplots()
    ax.boxplot([data[n] for n in names], orientation="horizontal", tick_labels=[""] * len(names), widths=0.6, showfliers=False,
               medianprops={"color": "C3"})  # fmt: skip
    rng = np.random.default_rng(0)
    for i, n in enumerate(names, start=1):
        if len(data[n]) <= points_up_to:
            ax.plot(data[n], i + rng.uniform(-0.18, 0.18, len(data[n])), "o", ms=2.2, color="k", alpha=0.6, mec="none")
    ax.set_yticks(range(1, len(names) + 1), ticks)
    nominal = runs_df["val_rms_nominal_mm"].dropna()
    xlabel = "RMS position error on validation poses, mm"
    if len(nominal):
        hi = max(float(np.max(v)) for v in data.values())
        if nominal.median() <= 1.5 * hi:
            ax.axvline(nominal.median(), ls="--", color="grey", lw=0.8)
            ax.annotate("nominal robot", (nominal.median(), 1), xycoords=("data", "axes fraction"), rotation=90, va="top",
                        ha="right", fontsize="small", color="grey")  # fmt: skip
        else:
            xlabel += f"\n(nominal robot: median {nominal.median():.3g} mm, off the scale)"
    ax.set_xlabel(xlabel)
    if note:
        ax.set_title(note.strip(" ()"), fontsize="medium")
    return save(fig, out, "validation_error_boxplot", formats)


def critical_difference(result: dict, out: Path, formats: tuple[str, ...], top: int = 12) -> str:
    """The mean ranks across instances (1 = best) with Nemenyi's critical difference. Up to
    ``top`` configurations: Demšar's diagram (labels left and right, a bar under each group
    that the test cannot tell apart). More: one row per configuration, sorted by mean rank,
    with the band [best, best + CD] shaded: a configuration in the band cannot be told apart
    from the best; the rows stay readable at any number of configurations."""
    ranks = result["mean_ranks"]  # sorted, best first
    k, cd = len(ranks), result["cd"]
    names, r = list(ranks.index), ranks.to_numpy()
    title = f"{result['test']}: p = {result['p']:.2g}; Nemenyi CD = {cd:.2f} at {result['alpha']:g}"
    if k > top:
        fig = Figure(figsize=(width(wide=True), 0.9 + 0.16 * k), layout="constrained")
        ax = fig.subplots()
        y = np.arange(k)
        ax.axvspan(r[0], r[0] + cd, color="C0", alpha=0.15, lw=0, label=f"within CD of the best ({int((r <= r[0] + cd).sum())})")
        inside = r <= r[0] + cd
        ax.plot(r[inside], y[inside], "o", color="C0", ms=3.5)
        ax.plot(r[~inside], y[~inside], "o", color="k", ms=3.5, mfc="white")
        ax.set_yticks(y, [f"{n}  ({x:.1f})" for n, x in zip(names, r)])
        ax.set_ylim(k - 0.5, -0.5)
        ax.set_xlim(0.5, k + 0.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(axis="x", lw=0.3, alpha=0.5)
        ax.set_xlabel(f"mean rank over {result['instances']} instances (1 = best of {k})")
        ax.legend(loc="upper right", frameon=True)
        ax.set_title(title, fontsize="medium")
        return save(fig, out, "critical_difference", formats)
    cliques = []
    for i in range(k):
        j = int(np.searchsorted(r, r[i] + cd, side="right")) - 1  # the last within CD of r[i]
        if j > i and not any(a <= i and j <= b for a, b in cliques):
            cliques.append((i, j))
    half = (k + 1) // 2
    rows = max(half, k - half)
    fig = Figure(figsize=(width(wide=True), 1.0 + 0.22 * rows + 0.08 * len(cliques)), layout="constrained")
    ax = fig.subplots()
    ax.set_xlim(0.5, k + 0.5)
    ax.hlines(0, 1, k, color="k", lw=0.8)
    for t in range(1, k + 1):
        ax.vlines(t, 0, 0.08, color="k", lw=0.8)
        ax.text(t, 0.12, str(t), ha="center", va="bottom")
    step = 0.3
    for n, (name, x) in enumerate(zip(names, r)):
        left = n < half
        yy = -0.25 - 0.08 * len(cliques) - step * (n if left else k - 1 - n)
        edge = 0.5 if left else k + 0.5
        ax.plot([x, x, edge], [0, yy, yy], color="k", lw=0.6)
        ax.text(edge + (-0.1 if left else 0.1), yy, f"{name} ({x:.2f})", ha="right" if left else "left", va="center", clip_on=False)
    for m, (i, j) in enumerate(cliques):
        ax.hlines(-0.1 - 0.08 * m, r[i] - 0.03, r[j] + 0.03, color="k", lw=2.5)
    ax.plot([1, 1 + cd], [0.5, 0.5], color="C3", lw=1.5)
    ax.text(1 + cd / 2, 0.55, f"CD = {cd:.2f}", ha="center", va="bottom", color="C3")
    ax.set_ylim(-0.35 - 0.08 * len(cliques) - step * rows, 0.85)
    ax.axis("off")
    ax.set_title(title + " (bars: not told apart)", fontsize="medium")
    return save(fig, out, "critical_difference", formats)


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
