"""The report as one page: ``index.html``, a single self-contained file (the figures inline as
SVG, the style inline, no script, no font or image to fetch: it opens from ``file://`` with no
server and no network) holding the study's design, its conclusions in sentences, every figure
with its caption, the tables, and the versions and command that made it."""

from __future__ import annotations

import datetime
import html
import math
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from zrp_ga.core.fileio import package_versions
from zrp_ga.report import conclusions
from zrp_ga.report import design as study
from zrp_ga.report.common import ALPHA

CSS = """
body{font:15px/1.5 system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;color:#1b1b1b;margin:0;background:#fafafa}
main{max-width:1100px;margin:0 auto;padding:1.5em 2em 4em;background:#fff}
@media (max-width:600px){main{padding:1em .8em 3em}body{font-size:14px}}
h1{font-size:1.6em;margin:.2em 0 .1em}h2{font-size:1.25em;margin-top:1.8em;border-bottom:1px solid #ddd;padding-bottom:.2em}
h3{font-size:1.05em;margin:1.2em 0 .3em}
.lede{color:#444;margin-top:0}
nav{font-size:.9em;margin:.6em 0 1em}nav a{margin-right:1em}
figure{margin:1.2em 0 2em;padding:0}figure svg{max-width:100%;height:auto;display:block}
.first li{font-size:1.05em}
figcaption{font-size:.92em;color:#333;max-width:52em;margin-top:.4em}figcaption b{color:#000}
table{border-collapse:collapse;font-size:.85em;margin:.5em 0 1em}
th,td{border-bottom:1px solid #e3e3e3;padding:.25em .6em;text-align:left;vertical-align:top}
th{background:#f3f3f3;position:sticky;top:0}td:first-child{min-width:14em}td.n{text-align:right;font-variant-numeric:tabular-nums}
.wide{overflow-x:auto;max-width:100%}
details{margin:.4em 0 1em}summary{cursor:pointer;color:#0b57d0}
ul.concl li{margin:.35em 0}
.sig{color:#0a6b2f;font-weight:600}.ns{color:#8a5300;font-weight:600}
code,pre{font:.85em/1.4 ui-monospace,"DejaVu Sans Mono",monospace;background:#f4f4f4;padding:.1em .3em}
pre{padding:.6em;white-space:pre-wrap}
"""


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return f"{int(v):,}" if abs(int(v)) >= 10_000 else str(int(v))
    if isinstance(v, (float, np.floating)):
        if math.isnan(v):
            return ""
        if math.isinf(v):
            return "never" if v > 0 else "-inf"
        return f"{v:.4g}"
    return str(v)


def table(df: pd.DataFrame, caption: str | None = None, max_rows: int | None = None, names: dict | None = None) -> str:
    """``df`` as an HTML table (numbers right-aligned, 4 significant digits; inf: never); more
    than ``max_rows`` rows fold into a details element."""
    names = names or {}
    head = "".join(f"<th>{html.escape(str(names.get(c, c)))}</th>" for c in df.columns)
    numeric = [pd.api.types.is_numeric_dtype(df[c]) and not pd.api.types.is_bool_dtype(df[c]) for c in df.columns]
    rows = []
    for row in df.itertuples(index=False):
        cells = "".join(f"<td{' class=n' if n else ''}>{html.escape(_fmt(v))}</td>" for v, n in zip(row, numeric))
        rows.append(f"<tr>{cells}</tr>")
    body = f'<div class="wide"><table><thead><tr>{head}</tr></thead><tbody>{"".join(rows)}</tbody></table></div>'
    cap = f"<p>{html.escape(caption)}</p>" if caption else ""
    if max_rows is not None and len(df) > max_rows:
        return f"{cap}<details><summary>{len(df)} rows: show</summary>{body}</details>"
    return cap + body


def _versions() -> dict[str, str]:
    out = package_versions(("zrp_ga", "numpy", "scipy", "pandas", "matplotlib"), missing="?")
    out["zrp_ga"] = study.code_version()
    return out


def _run_versions(runs_summaries: list[dict]) -> pd.DataFrame:
    seen: dict[tuple, int] = {}
    for s in runs_summaries:
        v = s.get("versions")
        v = v if isinstance(v, dict) else {}
        key = tuple(sorted((str(k), str(x)) for k, x in v.items()))
        seen[key] = seen.get(key, 0) + 1
    rows = [dict(runs=n, **dict(k)) for k, n in seen.items() if k]
    return pd.DataFrame(rows)


def _mark(sentence: str) -> str:
    """A sentence as HTML, its verdicts marked."""
    text = html.escape(sentence)
    text = re.sub(r"\b(no significant difference|not significantly|do not differ significantly|makes no significant difference|"
                  r"undecided|equivalent)\b", r'<span class="ns">\1</span>', text)  # fmt: skip
    return re.sub(r"\b(the configurations differ|the ranks differ|matters|better than|worse than)\b", r'<span class="sig">\1</span>', text)


def _svg(svg: str, name: str, title: str, alt: str, scale: float = 4 / 3) -> str:
    """An SVG of matplotlib's (drawn in the screen style), ready to sit inline: its ids prefixed
    with the figure's name (two figures never share an id), drawn at ``scale`` px a point (its
    size: 4/3, a 7 in figure 672 px wide; a page-wide print figure 1.5) but never wider than the
    page, described for screen readers by
    its title and ``alt`` (what it shows, in words: ``<title>`` and ``<desc>``)."""
    m = re.search(r'<svg[^>]*\bwidth="([0-9.]+)pt"', svg)
    if m:
        svg = re.sub(r'(<svg[^>]*?)\s(width|height)="[0-9.]+pt"', r"\1", svg, count=1)
        svg = re.sub(r'(<svg[^>]*?)\s(width|height)="[0-9.]+pt"', r"\1", svg, count=1)
        svg = svg.replace("<svg ", f'<svg style="width:min(100%,{float(m.group(1)) * scale:.0f}px)" ', 1)
    svg = re.sub(r'\bid="([^"]+)"', lambda m: f'id="{name}-{m.group(1)}"', svg)
    svg = re.sub(r'url\(#([^)]+)\)', lambda m: f"url(#{name}-{m.group(1)})", svg)
    svg = re.sub(r'href="#([^"]+)"', lambda m: f'href="#{name}-{m.group(1)}"', svg)
    head = svg.index(">", svg.index("<svg")) + 1
    described = f'<title id="{name}-title">{html.escape(title)}</title><desc id="{name}-desc">{html.escape(alt)}</desc>'
    svg = svg[:head] + described + svg[head:]
    return svg.replace("<svg ", f'<svg role="img" aria-labelledby="{name}-title {name}-desc" ', 1)


def design(t: dict, runs) -> str:
    """The study's design: instances, configurations, seeds, budgets, groups, runs found and left out."""
    floors, r = t["floors"], t["runs"]
    dims = {x.instance: len(x.summary.get("best_genome") or {}) for x in runs}
    inst = floors[["instance", "runs", "nominal_cost", "floor", "floor_source", "round_off", "reference", "tolerance"]].copy()
    inst.insert(2, "genes", inst["instance"].map(dims))
    inst.insert(3, "seeds", inst["instance"].map(r.groupby("instance")["seed"].nunique()))
    conf = r.groupby("configuration", sort=False).agg(group=("group", "first"), runs=("run", "size"), instances=("instance", "nunique"),
                                                       seeds=("seed", "nunique"), evaluations_min=("nevals", "min"),
                                                       evaluations_max=("nevals", "max")).reset_index()  # fmt: skip
    conf = conf.set_index("configuration").reindex(t["summary"]["configuration"]).reset_index()
    if conf["group"].nunique() < 2:
        conf = conf.drop(columns="group")
    seeds = sorted({s for s in r["seed"].dropna().tolist()}, key=lambda s: (str(type(s)), s))
    seed_text = ", ".join(map(str, seeds)) if len(seeds) <= 20 else f"{len(seeds)} seeds, {seeds[0]} to {seeds[-1]}"
    budgets = sorted(set(r["nevals"]))
    budget_text = ", ".join(f"{b:,}" for b in budgets) if len(budgets) <= 6 else f"{budgets[0]:,} to {budgets[-1]:,}"
    left = t["left_out"]
    parts = [
        f"<p>{conclusions.count(len(r), 'run')} found: {conclusions.count(conf.shape[0], 'configuration')} on "
        f"{conclusions.count(len(floors), 'instance')}, seeds {html.escape(seed_text or 'none recorded')}; evaluations per run: "
        f"{budget_text}. Settings that tell the configurations apart: {html.escape(', '.join(t['keys']) or 'none')}.</p>",
        "<h3>Instances</h3>",
        table(inst, names={"nominal_cost": "nominal cost", "floor": "floor f*", "floor_source": "f* from", "round_off": "round-off",
                           "reference": "f_ref", "tolerance": "tolerance / f_ref"}, max_rows=30),
        "<p>f* is Levenberg-Marquardt's cost on the instance where the runs carry it (else the lowest final cost: then the best run "
        "is at 1 x f* by definition); where it is below 1e-9 of the nominal cost it is round-off and f_ref = 1e-9 x the nominal "
        "cost, else f_ref = f*. Final costs closer than the tolerance x f_ref are the same result in every test (at least the "
        "targets' resolution and the round-off floor).</p>",
        "<h3>Configurations</h3>", table(conf, max_rows=16),
        "<h3>Runs left out</h3>",
        table(left, max_rows=20) if len(left) else "<p>None: every run found finished and its files read whole.</p>",
    ]
    for note in t.get("notes", []):
        parts.append(f"<p>Note: {html.escape(note)}</p>")
    return "\n".join(parts)


_P = {"p_holm": "p (Holm)", "effect_lo": "CI low", "effect_hi": "CI high", "p_equivalence_holm": "p TOST (Holm)"}
_PAIR_COLS = ["test", "a", "b", "p", "p_holm", "p_equivalence_holm", "effect", "effect_lo", "effect_hi", "verdict"]


def _summary_table(t: dict) -> str:
    rule, s = t["rule"], t["summary"]
    cols = ["configuration", "runs", "instances", "final_over_ref_median", "final_cost_median", "final_cost_q1", "final_cost_q3",
            "val_rms_mm_median", "nevals_median", "wall_s_median", *[f"success_{n}" for n in rule.names()],
            *[f"ert_{n}" for n in rule.names()]]  # fmt: skip
    cols = [c for c in cols if c in s and not (c.startswith("val_") and s[c].isna().all())]
    if "group" in s and s["group"].nunique() > 1:
        cols.insert(1, "group")
    names = {"final_over_ref_median": "final / f_ref, median", "final_cost_median": "final cost, median", "final_cost_q1": "Q1",
             "final_cost_q3": "Q3", "val_rms_mm_median": "validation RMS mm, median", "nevals_median": "evaluations, median",
             "wall_s_median": "wall s, median",
             **{f"success_{n}": f"hit {n}" for n in rule.names()}, **{f"ert_{n}": f"ERT {n}" for n in rule.names()}}  # fmt: skip
    ref = t["reference"]
    parts = ["<h3>Per configuration</h3>",
             table(s[cols], "Pooled over instances and runs, best first" + (" within each group (the groups never shared an instance: "
                   "the table does not rank across them)" if "group" in s and s["group"].nunique() > 1 else "") + ". hit c: share of runs reaching c x f_ref; ERT c: expected "
                   "evaluations to reach it (all evaluations spent over the successes; never: no run did).", max_rows=60, names=names)]  # fmt: skip
    if len(ref):
        parts += ["<h3>The reference</h3>",
                  table(ref, "Per instance, the reference's median final cost, its ratio to f_ref, validation RMS error (mm), "
                        "evaluations made and to reach the floor (within the tolerance), and the share of its runs that did.",
                        max_rows=30, names={"over_ref": "cost / f_ref", "val_rms_mm": "validation RMS mm",
                                            "evals_to_floor": "evaluations to the floor"})]  # fmt: skip
    return "\n".join(parts)


def _comparisons(t: dict) -> list[str]:
    parts = []
    w = t["within"]
    if len(w):
        omni = w[w["a"] == "all"][["instance", "metric", "best", "design", "test", "statistic", "p", "p_holm", "n_a", "verdict"]]
        best_pairs = w[(w["a"] != "all") & ((w["a"] == w["best"]) | (w["b"] == w["best"]))]
        parts += ["<h3>Within each instance</h3>",
                  table(omni, "The omnibus test per instance (Friedman when the configurations share seeds, Kruskal-Wallis "
                        "otherwise; values within the tolerance tied), Holm-corrected over the instances; n: blocks or runs.",
                        names={"p_holm": "p (Holm)", "n_a": "n"}, max_rows=30),
                  table(best_pairs[["instance", "metric", *_PAIR_COLS]], "The best configuration of each instance against every other: one "
                        "verdict per pair, from a's side (equivalent when every run is within the tolerance, else better or worse "
                        "when the difference test says so, else equivalent when TOST says so, else undecided); p-values "
                        f"Holm-corrected over all pairs of the instance; effect: P(a ends lower than b), with its 95% bootstrap "
                        f"interval. Significance level {ALPHA:g}.", max_rows=25, names=_P)]  # fmt: skip
    f, med = t["factors"], t["factor_medians"]
    if len(f):
        wide = med.pivot_table(index=["setting", "value"], columns="instance", values="median_final_over_ref", sort=False).reset_index()
        parts += ["<h3>Each setting over the others</h3>",
                  table(wide, "Median final cost / f_ref of each value of each setting, per instance and over all (pooling the other "
                        "settings).", max_rows=40),
                  table(f[["setting", "instance", "best", "design", *_PAIR_COLS]], "The tests: paired by the other settings and the "
                        "seed when every value ran on the same such blocks; per setting, omnibus p-values Holm-corrected over the "
                        "instances, pairwise ones over the pairs.", max_rows=30, names=_P)]  # fmt: skip
    ix = t["interactions"]
    if len(ix):
        parts += ["<h3>Interactions</h3>", table(ix, "Each pair of settings on each instance: the aligned rank transform's F test "
                                                 "of their interaction, Holm-corrected over every pair and instance.", max_rows=20,
                                                 names=_P)]  # fmt: skip
    v = t["statistics"]
    if len(v):
        pairs = v[(v["a"] != "all") & ((v["a"] == v["best"]) | (v["b"] == v["best"]))]
        parts += ["<h3>Validation error</h3>", table(pairs[["instance", "metric", *_PAIR_COLS]], "The configuration with the "
                                                     "lowest median validation error of each instance against every other, as "
                                                     "the final costs are compared.", max_rows=20, names=_P)]  # fmt: skip
    return parts


def tables(t: dict) -> str:
    rule, s = t["rule"], t["summary"]
    parts = [_summary_table(t), *_comparisons(t)]
    ert = t["ert"][t["ert"]["instance"] == "all"].pivot(index="configuration", columns="level", values="ert")
    ert = ert.reindex(index=[c for c in s["configuration"] if c in ert.index], columns=rule.names()).reset_index()
    parts += ["<h3>Expected running time</h3>", table(ert, "ERT in evaluations per target level, pooled over instances.", max_rows=30)]
    fb = t["fixed_budget_all"].pivot(index="configuration", columns="budget", values="median_cost_over_ref")
    fb = fb.reindex([c for c in s["configuration"] if c in fb.index])
    fb.columns = [f"{b:,} evaluations" for b in fb.columns]
    parts += ["<h3>Fixed budgets</h3>", table(fb.reset_index(), "Median over instances of the median over runs of the best cost "
                                                                "within the budget / f_ref; blank where a run stopped by its own "
                                                                "budget before it (no number for a budget never run).", max_rows=30)]  # fmt: skip
    for f in t.get("friedman_groups", []):
        fr = f["result"]
        if fr is not None:
            ranks = fr["mean_ranks"].rename("mean rank").reset_index()
            group = f" (group {f['group']})" if len(t["friedman_groups"]) > 1 else ""
            parts += [f"<h3>Ranks across instances{group}</h3>",
                      table(ranks, f"{fr['test']} over {fr['instances']} instances: statistic {fr['statistic']:.3g}, p = "
                            f"{fr['p']:.3g}; Nemenyi CD {fr['cd']:.2f}.", max_rows=30)]  # fmt: skip
    return "\n".join(parts)


def methods(t: dict, command: str, runs, where: Path) -> str:
    """How the runs and the report were made: the commands from the runs' records, the settings
    held fixed and varied, the versions (zrp_ga's with its commit when run from a clone)."""
    cmds = study.commands(runs, where)
    fixed, varied = study.settings(runs)
    lines = []
    for c in cmds:
        if c["command"]:
            run_in = (f" (run in {html.escape(c['where'])}, relative to this page; the command's paths are relative to that folder)"
                      if c["where"] else "")  # fmt: skip
            lines.append(f"<pre>{html.escape(c['command'])}</pre><p>made {conclusions.count(c['runs'], 'run')}{run_in}.</p>")
        else:
            lines.append(f"<p>{conclusions.count(c['runs'], 'run')} made without the command line (no Hydra record: the API).</p>")
    run_versions = _run_versions([x.summary for x in runs])
    versions = _versions()
    return "\n".join([
        "<h3>The runs</h3>", *lines,
        "<h3>Settings varied</h3>", table(varied, max_rows=30) if len(varied) else "<p>None.</p>",
        "<h3>Settings held fixed</h3>", table(fixed, f"{len(fixed)} settings of the runs' resolved configs, the same in every run.",
                                              max_rows=0) if len(fixed) else "<p>None recorded.</p>",
        "<h3>The report</h3>", f"<pre>{html.escape(study.relative_command(command, where))}</pre>",
        "<p>(Its paths relative to this page.)</p>",
        f"<p>Report made with {html.escape(', '.join(f'{k} {v}' for k, v in versions.items()))}. The runs were made with:</p>",
        table(run_versions) if len(run_versions) else "<p>(their summary.json files name no versions)</p>",
    ])  # fmt: skip


def write(path, t: dict, figs: list[dict], runs, command: str, paths: list[str], where: Path | None = None) -> None:
    """Write the page to ``path``; paths on it relative to ``where`` (the report's folder)."""
    where = Path(where or path.parent)
    r = t["runs"]
    title = (f"{conclusions.count(r['configuration'].nunique(), 'configuration')} on "
             f"{conclusions.count(t['floors']['instance'].nunique(), 'instance')}, {conclusions.count(len(r), 'run')}")  # fmt: skip
    said = t["sentences"] if "sentences" in t else conclusions.sentences(t)  # write_report's, made once
    concl = []
    for heading, lines in said.items():
        if lines:
            cls = "concl first" if heading == "In short" else "concl"
            concl.append(f"<h3>{html.escape(heading)}</h3><ul class='{cls}'>" + "".join(f"<li>{_mark(s)}</li>" for s in lines) + "</ul>")
    if t.get("cd_note"):
        concl.append(f"<p>{html.escape(t['cd_note'])}.</p>")
    fig_html = []
    for n, fig in enumerate(figs, start=1):
        fig_html.append(f'<figure id="{fig["name"]}">{_svg(fig["svg"], fig["name"], fig["title"], fig["alt"], fig.get("scale", 4 / 3))}<figcaption><b>Figure {n}. '
                        f'{html.escape(fig["title"])}.</b> {html.escape(fig["caption"])} <i>In words:</i> {html.escape(fig["alt"])}'
                        "</figcaption></figure>")  # fmt: skip
    made = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    shown_paths = ", ".join(os.path.relpath(Path(p).resolve(), where) for p in paths)
    body = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>zrp-ga report: {html.escape(title)}</title><style>{CSS}</style></head>
<body><main>
<h1>zrp-ga report</h1>
<p class="lede">{html.escape(title)}. Made {made} from {html.escape(shown_paths)} (relative to this page).</p>
<nav><a href="#conclusions">Conclusions</a><a href="#design">Design</a><a href="#figures">Figures</a><a href="#tables">Tables</a><a href="#methods">Methods</a></nav>
<h2 id="conclusions">Conclusions</h2>
<p>From the statistics below, at a significance level of {ALPHA:g}; final costs within the tolerance of each other are the same
result. An effect P(A ends lower than B) is the chance that A does better: 0.5 is no effect, 1 always. Lower cost is better. Every
conclusion is also in conclusions.json.</p>
{"".join(concl) or "<p>One configuration: nothing to compare.</p>"}
<h2 id="design">Design</h2>
{design(t, runs)}
<h2 id="figures">Figures</h2>
{"".join(fig_html) or "<p>No figures (--formats none).</p>"}
<h2 id="tables">Tables</h2>
<p>Every table is also in this folder as CSV (and Markdown).</p>
{tables(t)}
<h2 id="methods">Methods: how it was made</h2>
{methods(t, command, runs, where)}
</main></body></html>
"""
    path.write_text(body, encoding="utf-8")
