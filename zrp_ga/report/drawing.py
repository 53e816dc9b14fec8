"""Which figures a report draws, on which scale, the caption that tells a reader what each shows
and how to read it, and the description a screen reader reads instead of it
(:mod:`zrp_ga.report.figures` draws them). Every figure is drawn twice from the same data: in
the chosen style into the files (PNG, PDF, SVG: print) and in the screen style for the page."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from zrp_ga.report import compare, figures, targets
from zrp_ga.report.labels import KEY_NOTE, short_labels
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
        lines = {"floor f*": 1.0, **{f"{c:g} x f*": c for c in sorted(rule.levels, reverse=True) if c != 1}}  # the widest first
        return dict(scale={i: float(v) for i, v in f["reference"].items()}, clip=None, lines=lines,
                    ylabel="best cost / floor f*", kind="relative to the floor")  # fmt: skip
    round_off = {i: rule.round_off * float(n) for i, n in f["nominal_cost"].items() if math.isfinite(n) and n > 0}
    if one:
        i = f.index[0]
        lines = {"round-off floor": round_off[i]} if i in round_off and f.loc[i, "round_off"] else {"floor f*": float(f.loc[i, "reference"])}
        if rule.absolute is not None:
            lines[f"target {rule.absolute:g}"] = rule.absolute
        return dict(scale={i: 1.0}, clip=round_off or None, lines=lines, ylabel=figures.COST_LABEL, kind="absolute")
    scale = {i: float(n) if n > 0 else math.nan for i, n in f["nominal_cost"].items()}
    return dict(scale=scale, clip=dict(round_off), lines={"round-off floor": rule.round_off},
                ylabel="best cost / nominal cost", kind="relative to the nominal cost")  # fmt: skip


def _lm(t: dict) -> pd.DataFrame:
    ref = t["reference"]
    return ref[ref["reference"] == "Levenberg-Marquardt"]


def _unrelated(t: dict) -> str:
    """Where the runs form groups that never shared an instance: the sentence that replaces a
    figure's lowest-and-highest (which would compare runs across instances); else ""."""
    n = int(t["runs"]["group"].nunique()) if "group" in t["runs"] else 1
    return f"The configurations form {n} groups that never shared an instance: they are not compared here." if n > 1 else ""


def _names(t: dict) -> dict[str, str]:
    """Each configuration's short label for legends, "(LM, reference)" marked."""
    names = short_labels(t["shown"])
    for c in t["summary"].loc[t["summary"]["is_reference"], "configuration"]:
        names[c] = f"{names.get(c, c)} (reference)"
    return names


def draw(runs: list[Run], t: dict, stage: Path, formats: tuple[str, ...], rule: TargetRule, style: str = "paper",
         max_lines: int = figures.MAX_LINES, page: bool = True,
         meanwhile: Callable[[], None] | None = None) -> tuple[list[dict], list[str]]:  # fmt: skip
    """Every figure of the report: into ``stage`` in ``formats`` and ``style``, and for the page
    in the screen style (``page``). Returns {name, title, caption, alt, svg} in the page's order
    and the configurations drawn (the ``max_lines`` best; references always). ``meanwhile``:
    called while the figures are drawn by other processes (:func:`_each`), or before them."""
    order = list(t["summary"]["configuration"])
    refs = set(t["summary"].loc[t["summary"]["is_reference"], "configuration"])
    shown = [c for c in order if c not in refs][:max_lines] + [c for c in order if c in refs]
    shown = sorted(shown, key=order.index)
    specs = [s for s in (_convergence(runs, t, rule, shown, order), *_ecdf(runs, t, rule, shown, order), _evaluations(t, shown),
                         _main_effects(t), _interactions(t), _ranks(t), _validation(t, shown, order), _fig2(runs, t, rule, order))
             if s is not None]  # fmt: skip
    _backends(formats + (("svg",) if page else ()))
    out = []
    for spec, svg in zip(specs, _each(functools.partial(_render, stage, formats, style, page), specs, meanwhile)):
        reuse = page and spec["name"] in WIDE and style == "paper"
        out.append(dict(name=spec["name"], title=spec["title"], caption=spec["caption"], alt=spec["alt"], svg=svg,
                        scale=1.5 if reuse else 4 / 3))  # fmt: skip
    return out, shown


def _backends(formats: tuple[str, ...]) -> None:
    """The modules that write ``formats`` imported here, once, rather than by each drawing process."""
    from matplotlib.backend_bases import get_registered_canvas_class

    for ext in dict.fromkeys(formats):
        try:
            get_registered_canvas_class(ext)
        except (ImportError, ValueError):  # savefig says what is wrong, where it is called
            pass


def _render(stage: Path, formats: tuple[str, ...], style: str, page: bool, spec: dict) -> str:
    """One figure into ``stage`` in ``formats`` and ``style``; its SVG for the page (screen style)
    when ``page``."""
    reuse = page and spec["name"] in WIDE and style == "paper"  # a page-wide print figure is screen-sized already
    with figures.style(style):
        svg: str = spec["draw"](stage, formats, reuse)
    if page and not reuse:
        with figures.style("screen"):
            svg = spec["draw"](stage, (), True)
    return svg


_WORK: list[Callable[[], str]] = []  # what the forked drawing processes do (inherited, never pickled)


def _one(k: int) -> str:
    return _WORK[k]()


def _each(work: Callable[[dict], str], specs: list[dict], meanwhile: Callable[[], None] | None = None) -> list[str]:
    """``work(spec)`` of each spec, in their order: on the cores this process may use, each
    figure drawn by a forked process (the figures' closures are inherited, not pickled; each
    writes its own files) while this one calls ``meanwhile``; one after the other, after
    ``meanwhile``, where there is one core or no ``fork`` (Windows, macOS' default)."""
    import multiprocessing
    import os

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    if cores < 2 or len(specs) < 2 or "fork" not in multiprocessing.get_all_start_methods() or multiprocessing.current_process().daemon:
        if meanwhile is not None:
            meanwhile()
        return [work(spec) for spec in specs]
    import gc

    _WORK[:] = [functools.partial(work, spec) for spec in specs]
    # What exists now (the runs, the tables) lives until the figures are drawn: the collector
    # leaves it alone, so that neither this process nor a child walks it again (nor copies a
    # child's inherited pages by touching them).
    frozen = gc.get_freeze_count()
    gc.freeze()
    pool = multiprocessing.get_context("fork").Pool(min(cores, len(specs)), initializer=_plain_signals)
    try:
        drawn = pool.map_async(_one, range(len(specs)), chunksize=1)
        if meanwhile is not None:
            meanwhile()
        figures = drawn.get()
    except BaseException:
        pool.terminate()  # the children take SIGTERM as its default (_plain_signals)
        raise
    else:
        # Done: the children end on their own (close, join). A process that handles SIGTERM
        # itself (zrp-ga turns it into Ctrl-C; a caller may have a handler of its own) hands
        # that handler to the forked children, and a child still starting could outlive the
        # pool's SIGTERM: the join would wait for it forever.
        pool.close()
        pool.join()
        return figures
    finally:
        _WORK.clear()
        if not frozen:  # a caller's own frozen objects stay frozen
            gc.unfreeze()


def _plain_signals() -> None:
    """In a drawing child: the default SIGTERM and no SIGINT (the parent handles Ctrl-C)."""
    import signal

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


WIDE = ("ecdf_by_instance", "main_effects", "critical_difference")  # drawn a page wide: on screen as they are, enlarged


def _spec(name: str, title: str, caption: str, alt: str, draw: Callable) -> dict:
    return dict(name=name, title=title, caption=caption, alt=alt, draw=draw)


def _which(shown: list[str], order: list[str]) -> tuple[str, str]:
    k, n = len(shown), len(order)
    if k >= n:
        return "", ""
    return (f" ({k} best of {n} configurations)",
            f"The {k} best of the {n} configurations by median final cost / f_ref are drawn (more lines would not be told apart); "
            "every configuration is in the tables. ")  # fmt: skip


def _convergence(runs: list[Run], t: dict, rule: TargetRule, shown: list[str], order: list[str]) -> dict:
    s, names = scale_of(t["floors"], rule), _names(t)
    top = max(int(r.evals[-1]) for r in runs)
    grid = np.unique(np.geomspace(1, max(top, 2), 160).round())
    bands = {}
    for label in shown:
        members = [r for r, lab in zip(runs, t["labels"]) if lab == label]
        bands[names.get(label, label)] = (grid, figures.band(members, grid, s["scale"], s["clip"]), len(members))
    lm = _lm(t)
    reference = None
    if s["kind"] == "relative to the floor" and len(lm) and not any(t["summary"]["is_reference"]):
        reference = (float(lm["nevals"].median()), float(lm["over_ref"].median()))
    note, which = _which(shown, order)
    how = {
        "relative to the floor": "Costs are divided by each instance's floor f* (Levenberg-Marquardt's cost on it where the runs "
                                 "carry it, which noise keeps above zero), so that 1 is the best any method reaches; dotted lines "
                                 "mark the target levels that do not merge with another.",
        "absolute": f"Costs are absolute; costs below the floor are drawn at it (the line). {figures.COST_NOTE}",
        "relative to the nominal cost": "Costs are divided by each instance's nominal cost (the uncalibrated model's), since "
                                        "its floor is round-off; costs below the round-off floor (1e-9 of it) are drawn at it.",
    }[s["kind"]]  # fmt: skip
    ends = {lab: float(b[1][1][np.isfinite(b[1][1])][-1]) if np.isfinite(b[1][1]).any() else math.nan for lab, b in bands.items()}
    ranked = sorted((v, k) for k, v in ends.items() if math.isfinite(v))
    alt = (f"Line chart, both axes logarithmic: the median best cost ({s['ylabel']}) of each of {len(bands)} configurations against "
           f"evaluations, 1 to {top:,}. " + (f"{_unrelated(t)} " if _unrelated(t) else f"At the end the lowest median is {ranked[0][1]} at "
           f"{ranked[0][0]:.3g} and the highest {ranked[-1][1]} at {ranked[-1][0]:.3g}. " if ranked else "")
           + (f"LM, the reference, reaches {reference[1]:.3g} in {reference[0]:,.0f} evaluations." if reference else ""))  # fmt: skip
    counts = {n for _, _, n in bands.values()}
    runs_said = f"{counts.pop()} runs each" if len(counts) == 1 else "the number of runs in brackets"
    bands_said = "the interquartile range (band" + (", drawn for the best configuration only" if len(bands) > 4 else "") + ")"
    return _spec("convergence_by_configuration", "Convergence of each configuration",
                 f"The median over runs (line; {runs_said}) and {bands_said} of the best cost found within n evaluations, against "
                 f"n on a log axis. {how} {KEY_NOTE}. "
                 + ("The black star is LM, the reference: its evaluations and its cost. " if reference else "")
                 + f"{which}Lower and further left is better; bands that overlap mean the runs overlap.", alt,
                 lambda out, fmts, page: figures.convergence_by_configuration(bands, s["ylabel"], s["lines"], reference, note, out,
                                                                              fmts, page))  # fmt: skip


def _ecdf(runs: list[Run], t: dict, rule: TargetRule, shown: list[str], order: list[str]) -> list[dict]:
    floors, labels = t["floors"], t["labels"]
    tg = targets.ecdf_targets(runs, floors)
    if not tg or rule.absolute is not None:
        return []
    hits = targets.runtime_hits(runs, labels, tg)
    dims = {r.instance: max(targets.dimension(r), 1) for r in runs}
    start = 1.0 / max(dims.values())
    agg = targets.ecdf(hits, start)
    per = {i: targets.ecdf(h, start) for i, h in hits.groupby("instance", sort=True)}
    ends = hits.groupby("configuration")["nevals"].max().to_dict()
    ran = set(hits["configuration"])
    ecdf_shown = [c for c in shown if c in ran]
    ref_f = dict(zip(floors["instance"], floors["reference"].astype(float)))
    t["ecdf_targets"] = pd.DataFrame([dict(instance=i, k=j, target=v, over_ref=v / ref_f[i]) for i, arr in tg.items()
                                      for j, v in enumerate(arr)])  # fmt: skip
    lm, names = _lm(t), _names(t)
    reference = {}
    if len(lm) and not any(t["summary"]["is_reference"]) and floors["by_lm"].all():
        reference = {i: float(e) / dims.get(i, 1) for i, e in zip(lm["instance"], lm["nevals"]) if i in tg}
        reference["all"] = float(np.median(list(reference.values()))) if reference else math.nan
    note, which = _which(ecdf_shown, order)
    finals = {c: float(g["fraction"].iloc[-1]) for c, g in agg.groupby("configuration")}
    ranked = sorted(((v, names.get(k, k)) for k, v in finals.items() if k in ecdf_shown), reverse=True)
    genes = sorted(set(dims.values()))
    base = (f"Runtime ECDF as COCO draws it: for {targets.ECDF_TARGETS} targets per instance, their distances to the floor f_ref "
            "log-spaced from the instance's starting cost f0 (the median first cost of its runs) down to the tightest level, "
            "1.01 x f_ref (target k = f_ref + (f0 - f_ref) r^k), the fraction of (run, target) pairs reached within a budget, the "
            f"budget in evaluations divided by the genome's length ({', '.join(map(str, genes))} genes). x: the longest run. "
            + ("The black dashed step is LM, the reference: it reaches every target by its last evaluation (its path is not "
               "recorded). " if reference else "")
            + "Higher and further left is better; the value at the right end tells how close to the floor the runs came (1: every "
              "target, down to 1.01 x f_ref). ")  # fmt: skip
    alt = (f"Step chart: the fraction of the {targets.ECDF_TARGETS} targets per instance reached against evaluations per gene, one "
           "line per configuration. " + (_unrelated(t) or (f"At the end of its runs {ranked[0][1]} reaches {ranked[0][0]:.2f} of the "
           f"targets, {ranked[-1][1]} {ranked[-1][0]:.2f}." if ranked else "")))  # fmt: skip
    n = targets.ECDF_TARGETS
    specs = [_spec("ecdf_evals_to_target", "Targets reached, over all instances",
                   base + ("Aggregated over the instances, each weighing the same. " if len(per) > 1 else "") + which, alt,
                   lambda out, fmts, page: figures.ecdf(agg, ecdf_shown, names, ends, reference, n, note, out, fmts, page))]  # fmt: skip
    if len(per) > 1:
        specs.append(_spec("ecdf_by_instance", "Targets reached, instance by instance",
                           base + "One panel per instance: where the aggregate hides a difference, it shows here.",
                           alt.replace("Step chart:", f"Step charts, one per instance ({len(per)}):"),
                           lambda out, fmts, page: figures.ecdf_by_instance(per, ecdf_shown, names, ends, reference, n, out, fmts,
                                                                            page)))  # fmt: skip
    return specs


def _evaluations(t: dict, shown: list[str]) -> dict | None:
    """Where every run ends within the tolerance (an instance's question is evaluations): the
    evaluations each run took to reach the cost all reached, a box per configuration."""
    r = t["runs"]
    tied = [i for i, q in t["questions"].items() if q["tied"]]
    if not tied:
        return None
    names = _names(t)
    sub = r[r["instance"].isin(tied)]
    data = {names.get(c, c): sub.loc[sub["configuration"] == c, compare.EVALS].to_numpy(dtype=float) for c in shown}
    data = {k: v[np.isfinite(v)] for k, v in data.items() if np.isfinite(v).any()}
    if not data:
        return None
    meds = sorted((float(np.median(v)), k) for k, v in data.items())
    alt = (f"Box plots, one per configuration, of the evaluations each run took to reach the cost every run reached, on "
           f"{len(tied)} instance(s). " + (_unrelated(t) or f"Lowest median: {meds[0][1]}, {meds[0][0]:,.0f}; highest: {meds[-1][1]}, "
           f"{meds[-1][0]:,.0f}."))  # fmt: skip
    return _spec("evaluations_boxplot", "Evaluations to reach the floor",
                 f"Every run ends within the tolerance of every other on {', '.join(tied)}, so final costs tell nothing apart: "
                 "this is what still differs, the evaluations each run took to reach the cost every run reached (box: quartiles, "
                 "line: median, whiskers: 1.5 IQR; every run a point; log axis). Lower is better.", alt,
                 lambda out, fmts, page: figures.boxplot(data, "evaluations to reach it", None, "", "", "evaluations_boxplot", out,
                                                         fmts, page, log=True))  # fmt: skip


def _main_effects(t: dict) -> dict | None:
    m = t["factor_medians"]
    if not len(m):
        return None
    metric = str(m["metric"].iloc[-1])
    ylabel = "median final / f_ref" if metric.startswith("final") else "median evaluations"
    if metric.startswith("final"):
        m = m.assign(median=m["median_final_over_ref"])
    allm = m[m["instance"] == "all"]
    best = allm.loc[allm.groupby("setting")["median"].idxmin()] if len(allm) else allm
    alt = ("Line charts, one panel per setting: the median " + ylabel.removeprefix("median ") + " of each of its values, pooled over "
           "the other settings, a thin line per instance and a thick line across instances. Across instances the best value is "
           + "; ".join(f"{row.setting}: {row.value} ({row.median:.3g})" for row in best.itertuples()) + ".")  # fmt: skip
    return _spec("main_effects", "Each setting over the others (main effects)",
                 f"For each setting, the median {ylabel.removeprefix('median ')} of the runs with each of its values, pooled over every "
                 "other setting and the seeds: thin lines per instance, the thick black line across instances (the median of the "
                 "instances' medians). A flat line: the setting does not matter; the tests are in the tables.", alt,
                 lambda out, fmts, page: figures.main_effects(m, ylabel, out, fmts, page))  # fmt: skip


def _interactions(t: dict, top: int = 3) -> dict | None:
    ix = t["interactions"]
    found = ix[ix["found"]] if len(ix) else ix
    if not len(found):
        return None
    pairs = found.groupby(["setting_a", "setting_b"], sort=False)["p_holm"].min().sort_values().index[:top]
    r = t["runs"]
    cells = []
    for a, b in pairs:
        per = r.groupby(["instance", a, b], sort=False)["final_over_ref"].median().reset_index()
        c = per.groupby([a, b], sort=False)["final_over_ref"].median().reset_index()
        cells.append((a, b, c.rename(columns={a: "a", b: "b", "final_over_ref": "median"})))
    alt = ("Line charts, one per pair of settings whose interaction the tests find (" + "; ".join(f"{a} and {b}" for a, b in pairs)
           + "): the median final / f_ref against the first setting's values, a line per value of the second. Lines that are not "
             "parallel show the interaction.")  # fmt: skip
    return _spec("interactions", "Interactions between settings",
                 "For each pair of settings whose interaction the aligned rank transform finds (Holm over every pair and instance), "
                 "the median final / f_ref (median over the instances of each instance's median) of each combination: parallel "
                 "lines mean no interaction, crossing lines mean the best value of one setting depends on the other.", alt,
                 lambda out, fmts, page: figures.interaction_plots(cells, "median final / f_ref", out, fmts, page))  # fmt: skip


def _ranks(t: dict) -> dict | None:
    f = t["friedman"]
    if f is None or f["configurations"] < 3 or not f["p"] < f["alpha"]:
        if f is not None:
            t["cd_note"] = (f"No critical-difference diagram: {f['test']} finds no difference in ranks (p = {f['p']:.2g})"
                            if f["configurations"] >= 3 else "No critical-difference diagram: two configurations, the sign test says it all")  # fmt: skip
        return None
    more = f["configurations"] > 12
    names = _names(t)
    ranks = f["mean_ranks"]
    inside = int((ranks <= ranks.iloc[0] + f["cd"]).sum())
    alt = (f"Dot chart of the mean ranks of {f['configurations']} configurations over {f['instances']} instances (1 best). Best: "
           f"{names.get(ranks.index[0], ranks.index[0])} at {ranks.iloc[0]:.2f}; worst: {names.get(ranks.index[-1], ranks.index[-1])} "
           f"at {ranks.iloc[-1]:.2f}; {inside} lie within the critical difference {f['cd']:.2f} of the best.")  # fmt: skip
    return _spec("critical_difference", "Ranks across instances",
                 f"The mean rank of each configuration over the {f['instances']} instances (rank 1: the lowest median on an instance; "
                 f"medians within the tolerance tie). Friedman's test says the ranks differ (p = {f['p']:.2g}); Nemenyi's critical "
                 f"difference CD = {f['cd']:.2f} is how far apart two mean ranks must be for the test to tell the configurations "
                 "apart. " + ("Configurations in the shaded band cannot be told apart from the best. " if more else
                              "Configurations joined by a bar cannot be told apart. "), alt,
                 lambda out, fmts, page: figures.critical_difference(f, out, fmts, names=names, page=page))  # fmt: skip


def _validation(t: dict, shown: list[str], order: list[str]) -> dict | None:
    r, names = t["runs"], _names(t)
    data = {names.get(c, c): r.loc[r["configuration"] == c, "val_rms_mm"].dropna().to_numpy() for c in shown}
    data = {k: v for k, v in data.items() if len(v)}
    if not data:
        return None
    lm = _lm(t)
    ref = float(lm["val_rms_mm"].median()) if len(lm) and lm["val_rms_mm"].notna().any() and not any(t["summary"]["is_reference"]) else None
    nominal = r["val_rms_nominal_mm"].dropna()
    _, which = _which(shown, order)
    meds = sorted((float(np.median(v)), k) for k, v in data.items())
    xlabel = "validation RMS error, mm" + (f"\n(nominal robot: {nominal.median():.3g} mm)" if len(nominal) else "")
    alt = (f"Box plots of the validation RMS error (mm), one per configuration. {_unrelated(t)}" if _unrelated(t) else
            f"Box plots of the validation RMS error (mm), one per configuration: lowest median {meds[0][1]} at {meds[0][0]:.3g} mm, "
            f"highest {meds[-1][1]} at {meds[-1][0]:.3g} mm" + (f"; LM, the reference, {ref:.3g} mm." if ref is not None else "."))  # fmt: skip
    return _spec("validation_error_boxplot", "Validation error",
                 "The RMS position error of each run's calibrated model on poses it was not calibrated on (box: quartiles, line: "
                 "median, whiskers: 1.5 IQR; every run a point)" + ("; the dashed line is LM, the reference" if ref is not None else "")
                 + ". " + which, alt,
                 lambda out, fmts, page: figures.boxplot(data, xlabel, ref, "LM", "", "validation_error_boxplot", out,
                                                         fmts, page))  # fmt: skip


def _fig2(runs: list[Run], t: dict, rule: TargetRule, order: list[str]) -> dict:
    floors, labels, names = t["floors"], t["labels"], _names(t)
    instance = fig2_instance(floors)
    on = [(r, lab) for r, lab in zip(runs, labels) if r.instance == instance]
    present = [c for c in order if c in {lab for _, lab in on}]
    chosen = median_runs([r for r, _ in on], [lab for _, lab in on], present[: figures.MAX_LINES])
    named = [(names.get(lab, lab), run) for lab, run in chosen]
    row = floors.set_index("instance").loc[instance]
    round_off = bool(row["round_off"])
    floor = float(rule.round_off * row["nominal_cost"]) if round_off else float(row["reference"])
    t["fig2"] = dict(instance=instance, chosen=chosen)
    what = ("the round-off floor, 1e-9 of the nominal cost: lower costs are round-off and are drawn at it" if round_off
            else "the floor f*" + (", Levenberg-Marquardt's cost" if bool(row["by_lm"]) else ", the best run's cost"))  # fmt: skip
    alt = (f"Line chart: the best cost per generation of the median run of each of {len(chosen)} configurations on {instance}; "
           f"the floor at {floor:.3g}.")
    return _spec("fig2_convergence", "Single runs (the paper's Fig. 2)",
                 f"The best cost per generation of one run per configuration on {instance}: the run with the median final cost. The "
                 f"dotted line is {what}. {figures.COST_NOTE} "
                 + (f"The {len(chosen)} best of the {len(present)} configurations are drawn. " if len(chosen) < len(present) else ""), alt,
                 lambda out, fmts, page: figures.convergence_runs(named, len(present), instance, floor, round_off, out, fmts, page))  # fmt: skip
