"""The report's figures, drawn on ``matplotlib.figure.Figure`` objects (no pyplot, no backend
chosen: importing or running the report leaves the user's matplotlib alone; the styles are
applied with ``matplotlib.rc_context``, which restores the user's settings). Each function
draws from tables the report has built from the runs' files, writes the figure in each of the
requested formats and returns its SVG text when the page wants it.

Print and screen. ``paper`` sizes a figure to a column (3.5 in wide) or to a page's text width
(7.16 in: the figures with panels, the critical-difference diagram, the main effects) with
8-9 pt text, and never taller than its content: the files are exactly that size (no tight
bounding box; the layout engine fits the labels and the legend inside). ``screen`` draws the
same figures for the page, 7 in (10 in wide) with 10 pt text. Lines are told apart without
colour: the Okabe-Ito palette (Okabe and Ito 2008, safe for the common colour-vision
deficiencies; its yellow replaced by Tol's wine) with a marker and a dash pattern per line; the
reference (LM) is black.
Legends are compact, below the axes, one short label a line
(:func:`zrp_ga.report.labels.short`). Each figure's layout is computed once and reused for
every format."""

from __future__ import annotations

import contextlib
import io
import math
import textwrap
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator, NullFormatter

from zrp_ga.report.runs import Run

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

COST_LABEL = "best cost (residual 2-norm)"
COST_NOTE = ("The cost is the 2-norm of the residual, which stacks orientation errors (rad) and position errors (m) "
             "as the problem weighs them: it has no single unit.")  # fmt: skip
_PAPER_RC: dict[RcKeyType, Any] = {"font.size": 8, "axes.titlesize": 9, "axes.labelsize": 8, "xtick.labelsize": 8, "ytick.labelsize": 8,
             "legend.fontsize": 8, "legend.title_fontsize": 8, "lines.linewidth": 1.0, "lines.markersize": 3.5,
             "axes.linewidth": 0.6}  # fmt: skip
_SCREEN_RC: dict[RcKeyType, Any] = {"font.size": 10, "axes.titlesize": 10, "axes.labelsize": 10, "xtick.labelsize": 10, "ytick.labelsize": 10,
              "legend.fontsize": 10, "legend.title_fontsize": 10, "lines.linewidth": 1.5, "lines.markersize": 5}  # fmt: skip


class Style(TypedDict):
    """A style's sizes (inches: a column's and a page's width, the axes' height, a legend
    line's height), its matplotlib settings and the characters a legend label holds a line."""

    width: float
    wide: float
    axes: float
    line: float
    rc: dict[RcKeyType, Any]
    chars: int


STYLES = {
    "paper": Style(width=3.5, wide=7.16, axes=1.9, line=0.15, rc=_PAPER_RC, chars=52),
    "screen": Style(width=7.0, wide=10.0, axes=3.2, line=0.19, rc=_SCREEN_RC, chars=90),
}  # fmt: skip
_STYLE = {"name": "paper"}
MAX_LINES = 8  # configurations drawn in one axes before only the best are
# Okabe and Ito's colours without black (the reference's) and without yellow, which fades on white
# paper (under tritanopia most of all): blue, vermillion, bluish green, reddish purple, orange, sky
# blue; then Tol's wine and a grey.
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#882255", "#7F7F7F")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
DASHES = ("-", "--", "-.", ":")
REFERENCE: dict[str, Any] = dict(color="black", ls=(0, (6, 2)), marker="*", lw=1.6)


@contextlib.contextmanager
def style(name: str) -> Iterator[None]:
    """Draw the figures made inside in style ``name`` (``paper`` or ``screen``)."""
    if name not in STYLES:
        raise ValueError(f"unknown style {name!r} (paper, screen)")
    before = _STYLE["name"]
    _STYLE["name"] = name
    try:
        with matplotlib.rc_context({**STYLES[name]["rc"], "pdf.fonttype": 42, "svg.fonttype": "path", "svg.hashsalt": "zrp"}):
            yield
    finally:
        _STYLE["name"] = before


def width(wide: bool = False) -> float:
    """The figure width, inches, of the current style (``wide``: spanning a page's text)."""
    return STYLES[_STYLE["name"]]["wide" if wide else "width"]


def styles(n: int) -> list[dict]:
    """Colour, dash pattern and marker of ``n`` lines: each differs from the others in colour
    and marker (up to eight), and in dashes from its neighbours."""
    return [dict(color=PALETTE[i % len(PALETTE)], ls=DASHES[i % len(DASHES)], marker=MARKERS[i % len(MARKERS)]) for i in range(n)]


def save(fig: Figure, out: Path, name: str, formats: tuple[str, ...], page: bool = False) -> str:
    """``fig`` as ``out/name.<ext>`` for each format, its layout computed once for all; returns
    its SVG with the text as text when ``page`` (for the report's page), else ""."""
    engine = fig.get_layout_engine()
    if engine is not None:  # the layout alone, not a draw of every artist as well (draw_without_rendering)
        engine.execute(fig)
    # No layout engine from here on: the layout stays as computed and each format draws the figure
    # once. (With "none" matplotlib keeps a placeholder engine, and savefig draws the whole figure
    # twice, once without output, whenever a figure has an engine; the rc settings say that None
    # means none, not the user's default layout.)
    with matplotlib.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)
    for ext in formats:
        fig.savefig(out / f"{name}.{ext}", dpi=200, metadata={"Date": None} if ext in ("svg", "pdf") else None)
    if not page:
        return ""
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": name}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    return text[text.index("<svg"):]


def wrap(label: str, chars: int | None = None) -> str:
    """A label broken into lines that fit the style's width beside a legend's line sample."""
    return textwrap.fill(label, chars or STYLES[_STYLE["name"]]["chars"], subsequent_indent="  ")


def height(legend: list[str], axes: float | None = None, title: bool = False) -> float:
    """A figure's height, inches: the style's axes height (or ``axes``) and room for a legend of
    ``legend`` labels below them (in :func:`columns` columns, each wrapped), and for its title."""
    n = columns(legend)
    lines = math.ceil(sum(wrap(lab, STYLES[_STYLE["name"]]["chars"] // n).count("\n") + 1 for lab in legend) / n) + bool(title)
    s = STYLES[_STYLE["name"]]
    return (axes or s["axes"]) + 0.4 + s["line"] * 1.2 * lines


def columns(labels: list[str], wide: bool = False) -> int:
    """How many legend columns the labels fit in: two (four on a page-wide figure) when each
    is short, else one."""
    chars = STYLES[_STYLE["name"]]["chars"] * (2 if wide else 1)
    longest = max((len(lab) for lab in labels), default=0)
    return max(1, min(4 if wide else 2, int(chars // (longest + 8)), len(labels)))


def legend_below(fig: Figure, ax, title: str | None = None) -> None:
    """The axes' lines named below the plot, compact: two columns when the labels are short,
    long dashes visible."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        n = columns(labels)
        fig.legend(handles, [wrap(lab, STYLES[_STYLE["name"]]["chars"] // n) for lab in labels], loc="outside lower center",
                   frameon=False, ncols=n, title=wrap(title) if title else None, alignment="left", handlelength=2.8,
                   labelspacing=0.25, borderaxespad=0.2, columnspacing=1.0, handletextpad=0.5)  # fmt: skip


def _plain(v: float, _pos=None) -> str:
    """A tick label without mathtext: 0.01, 1, 100, 1,000, 1e+06 (typesetting 10^k as math costs
    a parse per label and per draw)."""
    if v <= 0 or not math.isfinite(v):
        return ""
    return f"{v:,.0f}" if 1 <= v < 1e5 and v == round(v) else f"{v:g}"


def log_axis(ax, which: str = "x") -> None:
    """A log axis labelled with plain numbers at its decades (no minor labels)."""
    axis = ax.xaxis if which == "x" else ax.yaxis
    (ax.set_xscale if which == "x" else ax.set_yscale)("log")
    axis.set_major_formatter(FuncFormatter(_plain))
    axis.set_minor_formatter(NullFormatter())


def _log_if_wide(ax, values: list[float]) -> None:
    """A log y axis when the values span more than a decade; its labels as plain numbers (2, 3,
    5, 10 rather than 2 x 10^0) when they span less than three."""
    v = np.asarray([x for x in values if x > 0 and math.isfinite(x)])
    if len(v) and v.max() / v.min() > 10:
        log_axis(ax, "y")
        if v.max() / v.min() < 1000:
            ax.yaxis.set_minor_formatter(FuncFormatter(lambda y, _: _plain(y) if f"{y:g}"[0] in "25" else ""))


def target_lines(ax, lines: dict[str, float]) -> None:
    """The floor (solid, first; the axis extended to show it) and the target levels (dotted,
    labelled at the left edge, where the curves are still high), the levels that would merge
    with a drawn one (closer than 4% of the axis's height) left out."""
    first = next(iter(lines.values()), math.nan)
    lo, hi = ax.get_ylim()
    if math.isfinite(first) and first > 0 and first < lo:
        ax.set_ylim(first / 1.5 if ax.get_yscale() == "log" else first - 0.05 * (hi - first), hi)
        lo, hi = ax.get_ylim()
    span = math.log10(hi / lo) if ax.get_yscale() == "log" and lo > 0 else hi - lo
    where = (lambda y: math.log10(y)) if ax.get_yscale() == "log" else (lambda y: y)
    drawn: list[float] = []
    for i, (text, y) in enumerate(lines.items()):
        if not (math.isfinite(y) and y > 0 and lo <= y <= hi) or any(abs(where(y) - d) < 0.04 * span for d in drawn):
            continue
        ax.axhline(y, color="k" if i == 0 else "0.4", lw=0.7, ls="-" if i == 0 else (0, (1, 2)), zorder=1)
        ax.annotate(text, (0.0, y), xycoords=("axes fraction", "data"), xytext=(3, 1.5), textcoords="offset points",
                    ha="left", va="bottom", fontsize="small", color="0.25")  # fmt: skip
        drawn.append(where(y))


def convergence_runs(chosen: list[tuple[str, Run]], total: int, instance: str, floor: float, round_off: bool, out: Path,
                     formats: tuple[str, ...], page: bool = False) -> str:  # fmt: skip
    """The paper's Fig. 2: the best cost per generation of the median run of each configuration
    in ``chosen`` (of ``total``; labels as the legend shows them) on ``instance``; costs below
    ``floor`` (the round-off floor when ``round_off``, else LM's floor f*) are drawn at it, and
    the floor as a line."""
    shown = f"all {total} configurations" if len(chosen) == total else f"the {len(chosen)} best of {total} configurations"
    title = f"median run of {shown}"
    fig = Figure(figsize=(width(), height([lab for lab, _ in chosen], title=True)), layout="constrained")
    ax = fig.subplots()
    values: list[float] = []
    for (label, run), st in zip(chosen, styles(len(chosen))):
        best = np.where(np.isfinite(run.columns["best"]), run.columns["best"], np.nan)
        if math.isfinite(floor) and floor > 0:
            best = np.maximum(best, floor)
        ax.plot(run.columns["gen"], best, label=label, markevery=max(1, len(best) // 8), **st)
        values.extend(best[np.isfinite(best)])
    if math.isfinite(floor) and floor > 0:
        values.append(floor)
    _log_if_wide(ax, values)
    if math.isfinite(floor) and floor > 0:
        target_lines(ax, {"round-off floor (1e-9 x nominal cost)" if round_off else "floor f* (LM's cost)": floor})
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("generation")
    ax.set_ylabel(COST_LABEL)
    legend_below(fig, ax, title)
    return save(fig, out, "fig2_convergence", formats, page)


def curves(runs: list[Run], grid: np.ndarray, scale: dict[str, float]) -> np.ndarray:
    """(R, G) best cost of each run within each budget of ``grid`` divided by ``scale`` of its
    instance (a run that stopped earlier keeps its final best; NaN on non-finite costs)."""
    out = np.full((len(runs), len(grid)), np.nan)
    for i, r in enumerate(runs):
        idx = np.searchsorted(r.evals, grid, side="right") - 1
        values = np.where(idx >= 0, r.best[np.clip(idx, 0, None)], np.nan) / scale[r.instance]
        out[i] = np.where(np.isfinite(values), values, np.nan)
    return out


def band(runs: list[Run], grid: np.ndarray, scale: dict[str, float], clip: dict[str, float] | None) -> np.ndarray:
    """(3, G) first quartile, median and third quartile over ``runs`` of :func:`curves` (below
    ``clip`` per instance drawn at it), up to the longest of the runs."""
    values = curves(runs, grid, scale)
    if clip:
        values = np.fmax(values, np.array([clip.get(r.instance, -np.inf) for r in runs])[:, None])
    values[:, grid > max(int(r.evals[-1]) for r in runs)] = np.nan
    with warnings.catch_warnings():  # a budget where every run's cost is NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanpercentile(values, [25, 50, 75], axis=0)


def convergence_by_configuration(bands: dict[str, tuple[np.ndarray, np.ndarray, int]], ylabel: str, lines: dict[str, float],
                                 reference: tuple[float, float] | None, note: str, out: Path, formats: tuple[str, ...],
                                 page: bool = False) -> str:  # fmt: skip
    """Median and interquartile band per configuration against evaluations: ``bands`` {label:
    (grid, (3, G) quartiles, runs)}, the reference (LM's evaluations and cost, drawn as a black
    star) when known; ``lines``: the floor and the target levels, {label: y}."""
    counts = {n for _, _, n in bands.values()}
    names = {label: label if len(counts) == 1 else f"{label} ({n})" for label, (_, _, n) in bands.items()}
    fig = Figure(figsize=(width(), height([*names.values(), *(["LM, the reference"] if reference else [])])), layout="constrained")
    ax = fig.subplots()
    for k, ((label, (grid, q, _)), st) in enumerate(zip(bands.items(), styles(len(bands)))):
        ax.plot(grid, q[1], label=names[label], markevery=_every(grid, 9), **st)
        if k == 0 or len(bands) <= 4:  # more bands would hide each other: the best's only
            ax.fill_between(grid, q[0], q[2], color=st["color"], alpha=0.15, lw=0)
    if reference is not None:
        ax.plot([reference[0]], [reference[1]], ls="none", ms=9, label="LM, the reference",
                **{k: v for k, v in REFERENCE.items() if k not in ("ls", "lw")})  # fmt: skip
    log_axis(ax, "x")
    log_axis(ax, "y")
    target_lines(ax, lines)
    ax.set_xlabel("evaluations")
    ax.set_ylabel(ylabel)
    legend_below(fig, ax)
    return save(fig, out, "convergence_by_configuration", formats, page)


def _every(x: np.ndarray, n: int = 7) -> np.ndarray:
    """About ``n`` marker positions, evenly spaced in log x (computed once, not at each draw)."""
    lx = np.log10(np.maximum(np.asarray(x, dtype=float), 1e-300))
    want = np.linspace(lx[0], lx[-1], n)
    return np.unique(np.clip(np.searchsorted(lx, want), 0, len(x) - 1))


def _ecdf_axes(ax, curves_: pd.DataFrame, shown: list[str], ends: dict[str, float], legend: bool, names: dict[str, str],
               reference: float | None) -> None:  # fmt: skip
    left, right = curves_["evaluations"].min(), max([*ends.values(), curves_["evaluations"].max()])
    for label, st in zip(shown, styles(len(shown))):
        c = curves_[curves_["configuration"] == label]
        if not len(c):
            continue
        end = max(ends.get(label, 0.0), c["evaluations"].max())
        x, y = np.r_[c["evaluations"], end], np.r_[c["fraction"], c["fraction"].iloc[-1]]
        ax.step(x, y, where="post", label=names.get(label, label) if legend else None, markevery=_every(x), **st)
        ax.plot([end], [y[-1]], "x", color=st["color"], ms=6)
    if reference is not None and math.isfinite(reference):
        ax.step([min(left, reference / 2), reference, max(right, reference * 2)], [0, 1, 1], where="post", color="black",
                ls=REFERENCE["ls"], lw=REFERENCE["lw"], label="LM, the reference" if legend else None)  # fmt: skip
    log_axis(ax, "x")
    ax.set_ylim(-0.02, 1.02)


def ecdf(aggregated: pd.DataFrame, shown: list[str], names: dict[str, str], ends: dict[str, float], reference: dict[str, float],
         targets: int, note: str, out: Path, formats: tuple[str, ...], page: bool = False) -> str:  # fmt: skip
    """The fixed-target runtime ECDF (COCO's) aggregated over the instances, budgets in
    evaluations per gene (``ecdf_evals_to_target``); each curve drawn up to ``ends`` (its
    longest run, marked x); LM's step at its evaluations per gene (``reference["all"]``)."""
    fig = Figure(figsize=(width(), height([names.get(s, s) for s in shown] + ["LM, the reference"] * bool(reference))),
                 layout="constrained")  # fmt: skip
    ax = fig.subplots()
    _ecdf_axes(ax, aggregated, shown, ends, True, names, reference.get("all"))
    ax.set_xlabel("evaluations / genes")
    ax.set_ylabel(f"fraction of {targets} targets hit")
    legend_below(fig, ax)
    return save(fig, out, "ecdf_evals_to_target", formats, page)


def ecdf_by_instance(per_instance: dict[str, pd.DataFrame], shown: list[str], names: dict[str, str], ends: dict[str, float],
                     reference: dict[str, float], targets: int, out: Path, formats: tuple[str, ...], page: bool = False) -> str:  # fmt: skip
    """:func:`ecdf` one panel per instance (``ecdf_by_instance``)."""
    n = len(per_instance)
    labels = [names.get(c, c) for c in shown] + ["LM, the reference"] * bool(reference)
    fig, axes, cols = _panels(n, len(labels), legend_cols=columns(labels, wide=True))
    for k, (ax, (instance, c)) in enumerate(zip(axes, per_instance.items())):
        _ecdf_axes(ax, c, shown, ends, k == 0, names, reference.get(instance))
        ax.set_title(instance, fontsize="medium")
        if k + cols >= n:
            ax.set_xlabel("evaluations / genes")
            ax.xaxis.set_tick_params(labelbottom=True)
        if k % cols == 0:
            ax.set_ylabel(f"fraction of {targets}\ntargets hit")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", frameon=False, ncols=columns(labels, wide=True), handlelength=2.8,
               labelspacing=0.25, columnspacing=1.0)  # fmt: skip
    return save(fig, out, "ecdf_by_instance", formats, page)


def _panels(n: int, legend: int, sharey: bool = True, sharex: bool = True, legend_cols: int = 2) -> tuple[Figure, np.ndarray, int]:
    """A figure of ``n`` panels (two or three a row, page-wide; one: a column wide) with room
    for ``legend`` labels below in ``legend_cols`` columns."""
    cols = 3 if n > 4 else 2 if n > 1 else 1
    rows = math.ceil(n / cols)
    panel = 1.55 if _STYLE["name"] == "paper" else 2.6
    below = STYLES[_STYLE["name"]]["line"] * 1.2 * math.ceil(legend / legend_cols)
    fig = Figure(figsize=(width(wide=n > 1), panel * rows + 0.45 + below), layout="constrained")
    axes = fig.subplots(rows, cols, sharex=sharex, sharey=sharey, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes, cols


def boxplot(data: dict[str, np.ndarray], xlabel: str, reference: float | None, reference_label: str, title: str, name: str,
            out: Path, formats: tuple[str, ...], page: bool = False, points_up_to: int = 40, log: bool = False) -> str:  # fmt: skip
    """Box plots of one number per run, a box per configuration (best at the top), every run a
    point when a box holds at most ``points_up_to``; the reference as a black dashed line."""
    names = list(data)[::-1]
    ticks = [wrap(n, 32) for n in names]
    rows = sum(0.14 * (t.count("\n") + 1) + 0.1 for t in ticks) * (1.0 if _STYLE["name"] == "paper" else 1.4)
    fig = Figure(figsize=(width(), 1.0 + rows), layout="constrained")
    ax = fig.subplots()
    ax.boxplot([data[n] for n in names], orientation="horizontal", tick_labels=[""] * len(names), widths=0.6, showfliers=False,
               medianprops={"color": PALETTE[1], "lw": 1.5})  # fmt: skip
    rng = np.random.default_rng(0)
    for i, n in enumerate(names, start=1):
        if len(data[n]) <= points_up_to:
            ax.plot(data[n], i + rng.uniform(-0.18, 0.18, len(data[n])), "o", ms=2.2, color="k", alpha=0.6, mec="none")
    ax.set_yticks(range(1, len(names) + 1), ticks)
    if log:
        log_axis(ax, "x")
    if reference is not None and math.isfinite(reference):
        ax.axvline(reference, color="black", ls=REFERENCE["ls"], lw=1.0)
        ax.annotate(reference_label, (reference, 1), xycoords=("data", "axes fraction"), va="bottom", ha="center", fontsize="small")
    ax.set_xlabel(xlabel)
    if title:
        ax.set_title(wrap(title, 40), fontsize="medium")
    return save(fig, out, name, formats, page)


def critical_difference(result: dict, out: Path, formats: tuple[str, ...], top: int = 12, names: dict[str, str] | None = None,
                        page: bool = False) -> str:  # fmt: skip
    """The mean ranks across instances (1 = best) with Nemenyi's critical difference. Up to
    ``top`` configurations: Demšar's diagram (labels left and right, a bar under each group
    that the test cannot tell apart). More: one row per configuration (two columns of rows
    above 24), sorted by mean rank, with the band [best, best + CD] shaded: a configuration in
    the band cannot be told apart from the best."""
    ranks = result["mean_ranks"]
    names = names or {}
    if len(ranks) > top:
        return _rank_strip(result, [names.get(n, n) for n in ranks.index], out, formats, page)
    return _demsar(result, [names.get(n, n) for n in ranks.index], out, formats, page)


def _rank_strip(result: dict, names: list[str], out: Path, formats: tuple[str, ...], page: bool) -> str:
    r, cd, k = result["mean_ranks"].to_numpy(), result["cd"], len(result["mean_ranks"])
    cols = 2 if k > 24 else 1
    per = math.ceil(k / cols)
    row = 0.118 if _STYLE["name"] == "paper" else 0.2
    fig = Figure(figsize=(width(wide=True), 0.75 + row * per), layout="constrained")
    axes = fig.subplots(1, cols, sharex=True, squeeze=False)[0]
    inside = r <= r[0] + cd
    for c, ax in enumerate(axes):
        sl = slice(c * per, min(k, (c + 1) * per))
        y = np.arange(sl.stop - sl.start)
        ax.axvspan(r[0], r[0] + cd, color=PALETTE[0], alpha=0.15, lw=0)
        ax.plot(r[sl][inside[sl]], y[inside[sl]], "o", color=PALETTE[0], ms=3.5)
        ax.plot(r[sl][~inside[sl]], y[~inside[sl]], "o", color="k", ms=3.5, mfc="white")
        ax.set_yticks(y, [f"{n}  ({x:.1f})" for n, x in zip(names[sl], r[sl])])
        ax.set_ylim(per - 0.5, -0.5)
        ax.set_xlim(0.5, k + 0.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True, nbins=4))
        ax.grid(axis="x", lw=0.3, alpha=0.5)
        ax.set_xlabel(f"mean rank over {result['instances']} instances")
    fig.suptitle(f"{result['test']}: p = {result['p']:.2g}; Nemenyi CD = {cd:.2f}; shaded: within CD of the best "
                 f"({int(inside.sum())} of {k}); filled: inside", fontsize="medium")  # fmt: skip
    return save(fig, out, "critical_difference", formats, page)


def _demsar(result: dict, names: list[str], out: Path, formats: tuple[str, ...], page: bool) -> str:
    r, cd, k = result["mean_ranks"].to_numpy(), result["cd"], len(result["mean_ranks"])
    cliques: list[tuple[int, int]] = []
    for i in range(k):
        j = int(np.searchsorted(r, r[i] + cd, side="right")) - 1  # the last within CD of r[i]
        if j > i and not any(a <= i and j <= b for a, b in cliques):
            cliques.append((i, j))
    half = (k + 1) // 2
    rows = max(half, k - half)
    fig = Figure(figsize=(width(wide=True), 0.9 + 0.2 * rows + 0.08 * len(cliques)), layout="constrained")
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
    ax.plot([1, 1 + cd], [0.5, 0.5], color=PALETTE[1], lw=1.5)
    ax.text(1 + cd / 2, 0.55, f"CD = {cd:.2f}", ha="center", va="bottom", color=PALETTE[1])
    ax.set_ylim(-0.35 - 0.08 * len(cliques) - step * rows, 0.85)
    ax.axis("off")
    ax.set_title(f"{result['test']}: p = {result['p']:.2g}; Nemenyi CD = {cd:.2f} at {result['alpha']:g} (bars: not told apart)",
                 fontsize="medium")  # fmt: skip
    return save(fig, out, "critical_difference", formats, page)


def main_effects(medians: pd.DataFrame, ylabel: str, out: Path, formats: tuple[str, ...], page: bool = False) -> str:
    """Each setting's values pooled over the others (``medians``: setting, instance, value,
    median; instance "all" across instances): a panel per setting, a thin line per instance
    (marker and dashes of its own), the thick black line across instances."""
    settings = list(dict.fromkeys(medians["setting"]))
    instances = [i for i in dict.fromkeys(medians["instance"]) if i != "all"]
    fig, axes, cols = _panels(len(settings), len(instances) + 1, sharey=True, sharex=False, legend_cols=min(4, len(instances) + 1))
    for k, (ax, key) in enumerate(zip(axes, settings)):
        m = medians[medians["setting"] == key]
        values = list(dict.fromkeys(m["value"]))
        x = np.arange(len(values))
        for inst, st in zip(instances, styles(len(instances))):
            y = m[m["instance"] == inst].set_index("value").reindex(values)["median"].to_numpy(dtype=float)
            ax.plot(x, y, lw=0.8, alpha=0.85, label=inst if k == 0 else None, **st)
        y = m[m["instance"] == "all"].set_index("value").reindex(values)["median"].to_numpy(dtype=float)
        ax.plot(x, y, color="black", lw=2.2, marker="o", label="across instances" if k == 0 else None)
        ticks = [v.removesuffix(" " + key) for v in values]
        ax.set_xticks(x, [wrap("none" if v == "no" else v, 12) for v in ticks], fontsize="small")
        ax.set_title(key, fontsize="medium")
        ax.set_xlim(-0.4, len(values) - 0.6)
        if k % cols == 0:
            ax.set_ylabel(ylabel)
    _log_if_wide(axes[0], list(medians["median"].to_numpy(dtype=float)))
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", frameon=False, ncols=min(4, len(labels)), handlelength=3.2)
    return save(fig, out, "main_effects", formats, page)


def interaction_plots(cells: list[tuple[str, str, pd.DataFrame]], ylabel: str, out: Path, formats: tuple[str, ...],
                      page: bool = False) -> str:  # fmt: skip
    """Interaction plots: per pair of settings (a, b, table with columns a, b, median), a
    panel with a's values on the x axis and a line per value of b; parallel lines: no
    interaction."""
    fig, axes, cols = _panels(len(cells), 0, sharey=False, sharex=False)
    for k, (ax, (a, b, c)) in enumerate(zip(axes, cells)):
        xs = list(dict.fromkeys(c["a"]))
        for (v, g), st in zip(c.groupby("b", sort=False), styles(c["b"].nunique())):
            y = g.set_index("a").reindex(xs)["median"].to_numpy(dtype=float)
            ax.plot(np.arange(len(xs)), y, label=f"{b}: {str(v).replace('_', ' ')}", **st)
        ax.set_xticks(np.arange(len(xs)), [wrap(str(x).replace("_", " "), 12) for x in xs], fontsize="small")
        ax.set_xlabel(a)
        if k % cols == 0:
            ax.set_ylabel(ylabel)
        _log_if_wide(ax, list(c["median"].to_numpy(dtype=float)))
        ax.legend(fontsize="small", frameon=False, handlelength=2.6)
    return save(fig, out, "interactions", formats, page)


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
