"""The report of finished runs: :func:`write_report` writes every table, figure and the
IOHprofiler export into a temporary folder and moves them into place at the end; :func:`console`
is what ``zrp-ga-report`` (:mod:`zrp_ga.cli.report`) prints.

The paths are checked before pandas, scipy and matplotlib are imported, so that a mistyped
path is reported at once."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from zrp_ga.report.common import LEVELS, ROUND_OFF, ReportError, markdown, write_csv
from zrp_ga.run import directory

if TYPE_CHECKING:

    from zrp_ga.report.runs import Run
    from zrp_ga.report.targets import TargetRule


# Every name the report writes (with .csv/.md/.png/.pdf): one left from an earlier report into the
# same folder that this one does not write is removed, so that the folder never mixes two reports.
STEMS = ("targets", "summary", "per_instance", "ert", "ecdf", "fixed_budget", "ranks", "statistics", "factors", "runs",
         "tidy", "left_out", "fig2_convergence", "convergence_by_configuration", "ecdf_evals_to_target",
         "validation_error_boxplot", "critical_difference", "table2_initial_population", "table3_best_params",
         "ranks_nemenyi", "index", "ecdf_by_instance", "within_instances", "factors_by_instance", "ecdf_targets", "conclusions",
         "reference", "interactions", "main_effects", "evaluations_boxplot")  # fmt: skip
FORMATS = ("png", "pdf")  # the page holds the figures as SVG itself
IOH = "ioh"


def _matches(run: Run, wanted: dict[str, str]) -> bool:
    """Whether ``run`` was given every ``KEY=VALUE`` of ``wanted`` (an override, a Hydra choice, a
    setting of its algorithm or any key of its resolved config)."""
    from zrp_ga.report.labels import flatten, settings

    if not wanted:
        return True
    known = {**flatten(run.summary.get("config") or {}), **settings(run), **run.choices, **run.overrides}
    return all(known.get(k) == v for k, v in wanted.items())


def _existing_ancestor(path: Path) -> Path:
    for p in [path, *path.parents]:
        if p.exists():
            return p
    return Path(".")


@contextlib.contextmanager
def _staging(paths: list[str | Path], out: Path, ioh: Path) -> Iterator[Path]:
    """A temporary folder beside ``out``, removed on the way out; checks first that the ``paths``
    are directories, that ``out`` can be written and that ``ioh`` is new, empty or an earlier
    export (ReportError otherwise)."""
    for p in paths:
        if not Path(p).exists():
            raise ReportError(f"{p}: no such directory")
        if not Path(p).is_dir():
            raise ReportError(f"{p}: not a directory")
    for flag, path in (("--out", out), ("--ioh", ioh)):
        if path.exists() and not path.is_dir():
            raise ReportError(f"{flag} {path}: not a directory")
    if ioh.is_dir() and not _is_ioh_export(ioh):
        raise ReportError(f"{ioh}: holds files that are not an IOHprofiler export (the export would replace them); "
                          "choose another --ioh folder")  # fmt: skip
    where = _existing_ancestor(out.resolve())
    if not where.is_dir():
        raise ReportError(f"--out {out}: {where} is not a directory")
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=where))
    except OSError as exc:
        raise ReportError(f"--out {out}: cannot write in {where} ({exc.strerror})") from None
    try:
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _is_ioh_export(path: Path) -> bool:
    return all(f.name.startswith("IOHprofiler_") and f.suffix in (".json", ".dat") for f in path.rglob("*") if f.is_file())


def _publish(stage: Path, out: Path, ioh: Path) -> None:
    """Move the staged report into ``out`` (files of an earlier report it no longer writes go),
    the IOH export into ``ioh`` (an earlier export there is replaced whole)."""
    out.mkdir(parents=True, exist_ok=True)
    written = {f.name for f in stage.iterdir() if f.is_file()}
    for f in out.iterdir():
        if f.is_file() and f.stem in STEMS and f.name not in written:
            f.unlink()
    for name in written:
        os.replace(stage / name, out / name)
    if ioh.exists():
        shutil.rmtree(ioh)
    ioh.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(str(stage / IOH), ioh)


def _write_tables(t: dict, stage: Path) -> None:
    names = {"targets": "floors", "within_instances": "within"}
    for name in ("targets", "summary", "per_instance", "ert", "ecdf", "fixed_budget", "statistics", "factors", "runs", "tidy",
                 "within_instances", "reference", "interactions"):  # fmt: skip
        write_csv(t[names.get(name, name)], stage / f"{name}.csv")
    for name in ("targets", "summary", "per_instance", "statistics", "reference"):
        df = t[names.get(name, name)]
        if len(df):
            (stage / f"{name}.md").write_text(markdown(df))
    w = t["within"]
    if len(w):
        keep = (w["a"] == "all") | (w["a"] == w["best"]) | (w["b"] == w["best"])
        (stage / "within_instances.md").write_text(
            "Within each instance, on its question (final cost / f_ref, ties within the tolerance; or the evaluations where "
            "every run ties): the omnibus test (Holm over the instances) and the best configuration against each other (Holm "
            "over the instance's pairs, TOST for equivalence); effect = P(a ends lower than b) [95% bootstrap CI]; one verdict "
            "per pair, from a's side\n\n"
            + markdown(w[keep]))  # fmt: skip
    f, med = t["factors"], t["factor_medians"]
    if len(f):
        keep = (f["a"] == "all") | (f["a"] == f["best"]) | (f["b"] == f["best"])
        (stage / "factors.md").write_text(
            "Each setting over the others, on final cost / f_ref, per instance and over all instances; omnibus p-values "
            "Holm-corrected over the instances, pairwise ones over the pairs; effect = P(a ends lower than b) [95% bootstrap CI]\n\n"
            + markdown(f[keep]))  # fmt: skip
        wide = med.pivot_table(index=["setting", "value"], columns="instance", values="median_final_over_ref", sort=False)
        (stage / "factors_by_instance.md").write_text(
            "Median final cost / f_ref of each value of each setting, per instance and over all\n\n" + markdown(wide.reset_index()))
    order = list(t["summary"]["configuration"])
    wide = t["fixed_budget_all"].pivot(index="configuration", columns="budget", values="median_cost_over_ref").reindex(order)
    wide.columns = [f"at {b:,} evaluations" for b in wide.columns]
    (stage / "fixed_budget.md").write_text(
        "Median over instances of the median over runs of (best cost within the budget) / f_ref; nan where a run stopped by "
        "its own budget before it\n\n" + markdown(wide.reset_index()))  # fmt: skip
    import json

    from zrp_ga.report import conclusions

    found = conclusions.records(t)
    compact = json.JSONEncoder(separators=(",", ":")).encode  # json.dumps' own encoder, made once for every record
    lines = ",\n".join(map(compact, found["conclusions"]))
    head = json.dumps({k: v for k, v in found.items() if k not in ("conclusions", "tests")})[:-1]
    (stage / "conclusions.json").write_text(f'{head}, "tests": {json.dumps(found["tests"])},\n"conclusions": [\n{lines}\n]}}\n')
    ert = t["ert"][t["ert"]["instance"] == "all"].pivot(index="configuration", columns="level", values="ert")
    ert = ert.reindex(index=[c for c in order if c in ert.index], columns=t["rule"].names())
    (stage / "ert.md").write_text("ERT (evaluations) per target level, pooled over instances\n\n" + markdown(ert.reset_index()))
    f = t["friedman"]
    if f is not None:
        ranks = f["mean_ranks"].rename("mean_rank").reset_index()
        write_csv(ranks, stage / "ranks.csv")
        write_csv(f["pairs"], stage / "ranks_nemenyi.csv")
        (stage / "ranks.md").write_text(f"{_friedman_line(t)}\n\n" + markdown(ranks) + "\nNemenyi's pairwise p-values:\n\n"
                                        + markdown(f["pairs"]))  # fmt: skip


def _friedman_line(t: dict) -> str:
    f = t["friedman"]
    if f is None:
        return f"Ranks across instances: not computed ({t['friedman_note'].strip()})"
    stat = f"chi2 = {f['statistic']:.3g}" if f["test"] == "Friedman" else f"{f['statistic']:.0f} wins of the first"
    return (f"{f['test']} over {f['instances']} instances and {f['configurations']} configurations: {stat}, "
            f"p = {f['p']:.3g}; Nemenyi critical difference {f['cd']:.2f} ranks{t['friedman_note']}")  # fmt: skip


def _paper_tables(run: Run, stage: Path) -> list[str]:
    """Tables 2 and 3 of one run; the files that could not be read (a FIFO or device among them:
    checked to be regular files first)."""
    import io

    import pandas as pd

    from zrp_ga.report.runs import LeftOut, read_text

    missing = []
    for name, source in (("table2_initial_population", directory.INITIAL_POPULATION), ("table3_best_params", directory.BEST_PARAMS)):
        try:
            (stage / f"{name}.md").write_text(markdown(pd.read_csv(io.StringIO(read_text(run.path / source)))))
        except (OSError, ValueError, LeftOut, pd.errors.ParserError):
            missing.append(str(run.path / source))
    return missing


def write_report(paths: list[str | Path], out: str | Path | None = None, target: float | None = None, only: Sequence[str] = (),
                 levels: tuple[float, ...] = LEVELS, budgets: tuple[int, ...] | None = None,
                 round_off: float = ROUND_OFF, ioh: str | Path | None = None,
                 formats: tuple[str, ...] = FORMATS, style: str = "paper", command: str | None = None,
                 tolerance: float | None = None, latex: bool = False) -> dict:  # fmt: skip
    """Build every table and figure of the runs under ``paths`` into ``out``, the IOHprofiler
    export into ``ioh`` (default ``out/ioh``); returns the tables. ``only``: ``KEY=VALUE``
    settings a run must have been given to count (e.g. ``refine=none``); ``target``: one
    absolute target cost instead of ``levels`` x f_ref; ``formats``: of the figures (none: no
    figures); ``style``: of the figure files, ``paper`` (3.5 in or 7.16 in wide, 8-9 pt) or
    ``screen`` (the page's figures are always screen-sized); ``command``: what the page says made
    it; ``budgets``: fixed budgets (default: from the runs); ``tolerance``: final costs closer than
    this x f_ref are one result (default: the targets' resolution); ``latex``: the headline tables
    as booktabs .tex files too. Also writes ``index.html``, the report as one page, and
    ``conclusions.json``. Bad input is a ReportError (a ValueError, one line), raised before
    anything is written."""
    if not paths:
        raise ReportError("no directory given")
    out = Path(out) if out is not None else Path(paths[0]) / "report"
    ioh = Path(ioh) if ioh is not None else out / IOH
    with _staging(paths, out, ioh) as stage:
        import pandas as pd
        from matplotlib.backend_bases import FigureCanvasBase

        from zrp_ga.report import drawing, figures, ioh_export, page
        from zrp_ga.report.runs import find_runs, parse_overrides
        from zrp_ga.report.tables import build_tables
        from zrp_ga.report.targets import TargetRule

        unknown = sorted(set(formats) - set(FigureCanvasBase.get_supported_filetypes()))
        if unknown:
            raise ReportError(f"--formats: {unknown[0]} is not a figure format "
                              f"({', '.join(sorted(FigureCanvasBase.get_supported_filetypes()))})")  # fmt: skip
        if style not in figures.STYLES:
            raise ReportError(f"--style: {style} is not a style ({', '.join(figures.STYLES)})")
        if tolerance is not None and not (tolerance >= 0 and tolerance < 1):
            raise ReportError(f"--tolerance: {tolerance:g} is not a fraction of f_ref in [0, 1)")
        rule = TargetRule(tuple(dict.fromkeys(levels)), target, round_off, tolerance)
        runs, left = find_runs(paths)
        wanted = parse_overrides(list(only))
        runs = [r for r in runs if _matches(r, wanted)]
        if not runs:
            reasons = "; ".join(f"{p}: {why}" for p, why in left) or "no convergence.csv found"
            raise ReportError(f"no finished run under {', '.join(map(str, paths))}" + (f" with {' '.join(only)}" if only else "")
                             + f" ({reasons})")  # fmt: skip
        where = out.resolve()
        t = build_tables(runs, rule, tuple(budgets) if budgets else None, where)
        t["left_out"], t["notes"] = pd.DataFrame([(os.path.relpath(p, where), why) for p, why in left], columns=["run", "reason"]), []
        t["left_as_found"] = left
        figs: list[dict[str, Any]] = []
        shown: list[str] = []
        if formats:  # the tables written while other processes draw the figures
            figs, shown = drawing.draw(runs, t, stage, tuple(formats), rule, style, meanwhile=lambda: _write_tables(t, stage))
        else:
            _write_tables(t, stage)
        if latex:
            from zrp_ga.report import latex as tex

            tex.write(t, stage)
        if "ecdf_targets" in t:
            write_csv(t["ecdf_targets"], stage / "ecdf_targets.csv")
        order = list(t["summary"]["configuration"])
        single = drawing.median_runs(runs, t["labels"], order[:1])[0][1]
        unread = _paper_tables(single, stage)
        (stage / IOH).mkdir()
        notes = [f"not in the IOH export: {p} ({why})" for p, why in ioh_export.export(runs, t["labels"], t["shown"], stage / IOH)]
        notes += [f"no Table 2 or 3: {p} cannot be read" for p in unread]
        t["notes"] = notes
        write_csv(t["left_out"], stage / "left_out.csv")
        made = command or "zrp-ga-report " + " ".join(map(str, paths)) + f" --out {out}"
        from zrp_ga.report import conclusions

        t["sentences"] = conclusions.sentences(t)  # once, for the page and the console
        page.write(stage / "index.html", t, figs, runs, made, [str(p) for p in paths], where)
        _publish(stage, out, ioh)
    t.update(shown_in_figures=shown, single_run=str(single.path), out=str(out))
    return t


def console(t: dict, max_rows: int = 12) -> str:
    """What the command prints: counts, the runs left out, the targets (of ``max_rows`` instances
    at most), the configurations, the ranks."""
    rule: TargetRule = t["rule"]
    runs, floors = t["runs"], t["floors"]
    lines = [f"{len(runs)} runs of {runs['configuration'].nunique()} configurations on {len(floors)} instance(s); report in {t['out']}"]
    lines += [f"left out {run}: {why}" for run, why in t.get("left_as_found", t["left_out"].itertuples(index=False))]
    lines += [f"note: {note}" for note in t["notes"]]
    if rule.absolute is not None:
        lines.append(f"\nTarget: best cost <= {rule.absolute:g} on every instance (--target).")
    else:
        lines.append(f"\nTargets: c x f_ref for c in {', '.join(rule.names())}; f_ref = the floor f*, or {rule.round_off:g} x "
                     f"the nominal cost where f* is below that (round-off):")  # fmt: skip
    cols = ["instance", "runs", "nominal_cost", "floor", "floor_source", "round_off", "reference"]
    names = {"floor": "floor f*", "floor_source": "f* from", "reference": "f_ref"}
    lines.append(markdown(floors[cols].head(max_rows).rename(columns=names)))
    if len(floors) > max_rows:
        lines.append(f"... and {len(floors) - max_rows} more instances in targets.csv\n")
    s = t["summary"]
    table = s[["configuration", "runs", "instances", "final_over_ref_median", "val_rms_mm_median"]].copy()
    table["hit " + "/".join(rule.names())] = ["/".join(f"{s.loc[i, f'success_{n}']:.2f}" for n in rule.names()) for i in s.index]
    for n in rule.names():
        table[f"ERT {n}"] = s[f"ert_{n}"]
    lines.append(markdown(table.rename(columns={"final_over_ref_median": "final/f_ref, median", "val_rms_mm_median": "val RMS mm, median"})))
    from zrp_ga.report import conclusions

    lines.append(_friedman_line(t))
    if t["friedman"] is not None:
        lines.append("mean ranks: " + ", ".join(f"{k} {v:.2f}" for k, v in t["friedman"]["mean_ranks"].items()))
    for heading, said in (t["sentences"] if "sentences" in t else conclusions.sentences(t)).items():
        if said:
            lines.append(f"\n{heading}:")
            lines += [f"- {x}" for x in said]
    lines.append(f"\nThe report as one page: {Path(t['out']) / 'index.html'}")
    return "\n".join(lines)
