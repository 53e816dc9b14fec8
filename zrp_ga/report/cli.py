"""``zrp-ga-report``: the command line and :func:`write_report`, which writes every table, figure
and the IOHprofiler export into a temporary folder and moves them into place at the end.

The paths are checked before pandas, scipy and matplotlib are imported, so that a mistyped
path is reported at once."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

    from zrp_ga.report.runs import Run
    from zrp_ga.report.targets import TargetRule

class ReportError(ValueError):
    """What is wrong with the command's input, in one line (the command prints it and exits with 2)."""


LEVELS = (1.5, 1.1, 1.05, 1.01)  # target levels c (targets c x f_ref)
BUDGETS = (100, 1_000, 10_000)  # fixed budgets, evaluations
ROUND_OFF = 1e-9  # a floor below ROUND_OFF x nominal cost is round-off

# Every name the report writes (with .csv/.md/.png/.pdf): one left from an earlier report into the
# same folder that this one does not write is removed, so that the folder never mixes two reports.
STEMS = ("targets", "summary", "per_instance", "ert", "ecdf", "fixed_budget", "ranks", "statistics", "factors", "runs",
         "tidy", "left_out", "fig2_convergence", "convergence_by_configuration", "ecdf_evals_to_target",
         "validation_error_boxplot", "critical_difference", "table2_initial_population", "table3_best_params",
         "ranks_nemenyi")  # fmt: skip
IOH = "ioh"


def markdown(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    """A DataFrame as a Markdown table (floats with ``floatfmt``)."""
    cols = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        cells = [format(v, floatfmt) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _matches(run: Run, wanted: dict[str, str]) -> bool:
    """Whether ``run`` was given every ``KEY=VALUE`` of ``wanted`` (an override, a Hydra choice, a
    setting of its algorithm or any key of its resolved config)."""
    from zrp_ga.report.labels import flatten, settings

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
    for name in ("targets", "summary", "per_instance", "ert", "ecdf", "fixed_budget", "statistics", "factors", "runs", "tidy"):
        t["floors" if name == "targets" else name].to_csv(stage / f"{name}.csv", index=False)
    for name in ("targets", "summary", "per_instance", "statistics", "factors"):
        df = t["floors" if name == "targets" else name]
        if len(df):
            (stage / f"{name}.md").write_text(markdown(df))
    order = list(t["summary"]["configuration"])
    wide = t["fixed_budget_all"].pivot(index="configuration", columns="budget", values="median_cost_over_ref").reindex(order)
    wide.columns = [f"at {b:,} evaluations" for b in wide.columns]
    (stage / "fixed_budget.md").write_text(
        "Median over instances of the median over runs of (best cost within the budget) / f_ref\n\n"
        + markdown(wide.reset_index()))  # fmt: skip
    ert = t["ert"][t["ert"]["instance"] == "all"].pivot(index="configuration", columns="level", values="ert")
    ert = ert.reindex(index=[c for c in order if c in ert.index], columns=t["rule"].names())
    (stage / "ert.md").write_text("ERT (evaluations) per target level, pooled over instances\n\n" + markdown(ert.reset_index()))
    f = t["friedman"]
    if f is not None:
        ranks = f["mean_ranks"].rename("mean_rank").reset_index()
        ranks.to_csv(stage / "ranks.csv", index=False)
        f["pairs"].to_csv(stage / "ranks_nemenyi.csv", index=False)
        (stage / "ranks.md").write_text(f"{_friedman_line(t)}\n\n" + markdown(ranks) + "\nNemenyi's pairwise p-values:\n\n"
                                        + markdown(f["pairs"]))  # fmt: skip


def _friedman_line(t: dict) -> str:
    f = t["friedman"]
    if f is None:
        return f"Ranks across instances: not computed ({t['friedman_note'].strip()})"
    stat = f"chi2 = {f['statistic']:.3g}" if f["test"] == "Friedman" else f"{f['statistic']:.0f} wins of the first"
    return (f"{f['test']} test over {f['instances']} instances and {f['configurations']} configurations: {stat}, "
            f"p = {f['p']:.3g}; Nemenyi critical difference {f['cd']:.2f} ranks{t['friedman_note']}")  # fmt: skip


def _draw(runs: list[Run], t: dict, stage: Path, formats: tuple[str, ...], rule: TargetRule, max_lines: int = 10) -> list[str]:
    """The figures; returns the configurations drawn (the ``max_lines`` best)."""
    from zrp_ga.report import figures

    order = list(t["summary"]["configuration"])
    shown = order[:max_lines]
    note = f" ({len(shown)} best of {len(order)} configurations)" if len(order) > len(shown) else ""
    labels = t["labels"]
    one = t["floors"]["instance"].nunique() == 1
    reference = t["floors"].set_index("instance")["reference"]
    scale = {i: 1.0 if one else (float(v) if v > 0 else math.nan) for i, v in reference.items()}
    ylabel = figures.COST_LABEL if one else "best cost / f_ref of its instance"
    figures.convergence_by_configuration(runs, labels, shown, scale, ylabel, note, stage, formats)
    if len(t["ecdf"]):
        what = ", ".join(rule.names()) + (" x f_ref" if rule.absolute is None else "")
        ends = t["runs"].groupby("configuration")["nevals"].max().to_dict()
        figures.ecdf(t["ecdf"], [s for s in shown if s in set(t["ecdf"]["configuration"])], ends, what, note, stage, formats)
    figures.validation_boxplot(t["runs"], shown, note, stage, formats)
    if t["friedman"] is not None:
        figures.critical_difference(t["friedman"], stage, formats)
    return shown


def median_runs(runs: list[Run], labels: list[str], order: list[str]) -> list[tuple[str, Run]]:
    """For each configuration (in ``order``), its run with the median final cost."""
    out = []
    for label in order:
        members = sorted((r for r, lab in zip(runs, labels) if lab == label), key=lambda r: (math.isnan(r.final_cost), r.final_cost))
        out.append((label, members[(len(members) - 1) // 2]))
    return out


def _paper_tables(run: Run, stage: Path) -> list[str]:
    """Tables 2 and 3 of one run; the files that could not be read."""
    import pandas as pd

    missing = []
    for name, source in (("table2_initial_population", "initial_population.csv"), ("table3_best_params", "best_params.csv")):
        try:
            (stage / f"{name}.md").write_text(markdown(pd.read_csv(run.path / source)))
        except (OSError, ValueError, pd.errors.ParserError):
            missing.append(str(run.path / source))
    return missing


def write_report(paths: list[str | Path], out: str | Path | None = None, target: float | None = None, only: list[str] = (),
                 levels: tuple[float, ...] = LEVELS, budgets: tuple[int, ...] = BUDGETS,
                 round_off: float = ROUND_OFF, ioh: str | Path | None = None,
                 formats: tuple[str, ...] = ("png", "pdf")) -> dict:  # fmt: skip
    """Build every table and figure of the runs under ``paths`` into ``out``, the IOHprofiler
    export into ``ioh`` (default ``out/ioh``); returns the tables. ``only``: ``KEY=VALUE``
    settings a run must have been given to count (e.g. ``refine=none``); ``target``: one
    absolute target cost instead of ``levels`` x f_ref; ``formats``: of the figures (none: no
    figures). Bad input is a ReportError (a ValueError, one line), raised before anything is
    written."""
    if not paths:
        raise ReportError("no directory given")
    out = Path(out) if out is not None else Path(paths[0]) / "report"
    ioh = Path(ioh) if ioh is not None else out / IOH
    with _staging(paths, out, ioh) as stage:
        import pandas as pd
        from matplotlib.backend_bases import FigureCanvasBase

        from zrp_ga.report import figures, ioh_export
        from zrp_ga.report.runs import find_runs, parse_overrides
        from zrp_ga.report.tables import build_tables
        from zrp_ga.report.targets import TargetRule

        unknown = sorted(set(formats) - set(FigureCanvasBase.get_supported_filetypes()))
        if unknown:
            raise ReportError(f"--formats: {unknown[0]} is not a figure format "
                              f"({', '.join(sorted(FigureCanvasBase.get_supported_filetypes()))})")  # fmt: skip
        rule = TargetRule(tuple(dict.fromkeys(levels)), target, round_off)
        runs, left = find_runs(paths)
        wanted = parse_overrides(list(only))
        runs = [r for r in runs if _matches(r, wanted)]
        if not runs:
            reasons = "; ".join(f"{p}: {why}" for p, why in left) or "no convergence.csv found"
            raise ReportError(f"no finished run under {', '.join(map(str, paths))}" + (f" with {' '.join(only)}" if only else "")
                             + f" ({reasons})")  # fmt: skip
        t = build_tables(runs, rule, tuple(budgets))
        t["rule"] = rule
        _write_tables(t, stage)
        chosen = median_runs(runs, t["labels"], list(t["summary"]["configuration"])[:4])
        shown = _draw(runs, t, stage, tuple(formats), rule) if formats else []
        if formats:
            figures.convergence_runs(chosen, stage, tuple(formats))
        unread = _paper_tables(chosen[0][1], stage)
        (stage / IOH).mkdir()
        notes = [f"not in the IOH export: {p} ({why})" for p, why in ioh_export.export(runs, t["labels"], t["shown"], stage / IOH)]
        notes += [f"no Table 2 or 3: {p} cannot be read" for p in unread]
        t["left_out"], t["notes"] = pd.DataFrame(left, columns=["run", "reason"]), notes
        t["left_out"].to_csv(stage / "left_out.csv", index=False)
        _publish(stage, out, ioh)
    t.update(shown_in_figures=shown, single_run=str(chosen[0][1].path), out=str(out))
    return t


def console(t: dict, max_rows: int = 12) -> str:
    """What the command prints: counts, the runs left out, the targets (of ``max_rows`` instances
    at most), the configurations, the ranks."""
    rule: TargetRule = t["rule"]
    runs, floors = t["runs"], t["floors"]
    lines = [f"{len(runs)} runs of {runs['configuration'].nunique()} configurations on {len(floors)} instance(s); report in {t['out']}"]
    lines += [f"left out {run}: {why}" for run, why in t["left_out"].itertuples(index=False)]
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
    lines.append(_friedman_line(t))
    if t["friedman"] is not None:
        lines.append("mean ranks: " + ", ".join(f"{k} {v:.2f}" for k, v in t["friedman"]["mean_ranks"].items()))
    return "\n".join(lines)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, like every other error of the command
        self.exit(2, f"{self.prog}: error: {message}\n")


def _numbers(kind: type):
    def parse(text: str) -> tuple:
        try:
            values = tuple(kind(v) for v in text.split(",") if v.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}") from None
        if not values or any(v <= 0 for v in values):
            raise argparse.ArgumentTypeError(f"needs positive numbers: {text!r}")
        return values

    return parse


def main(argv: list[str] | None = None) -> None:
    p = _Parser(prog="zrp-ga-report", description="Tables, statistics, figures and an IOHprofiler export of finished zrp-ga runs.")
    p.add_argument("dirs", nargs="+", help="run directories, sweep directories, or folders holding them")
    p.add_argument("--out", default=None, help="report directory (default: DIR/report of the first DIR)")
    p.add_argument("--ioh", default=None, metavar="DIR", help="where the IOHprofiler export goes (default: OUT/ioh)")
    p.add_argument("--levels", type=_numbers(float), default=LEVELS, metavar="C,...",
                   help="target levels c: targets c x f_ref (default 1.5,1.1,1.05,1.01)")
    p.add_argument("--target", type=float, default=None, help="one absolute target cost for every instance instead of the levels")
    p.add_argument("--round-off", type=float, default=ROUND_OFF, metavar="EPS",
                   help="a floor below EPS x nominal cost is round-off: f_ref = EPS x nominal cost (default 1e-9)")
    p.add_argument("--budgets", type=_numbers(int), default=BUDGETS, metavar="N,...",
                   help="fixed budgets in evaluations (default 100,1000,10000)")
    p.add_argument("--only", action="append", default=[], metavar="KEY=VALUE",
                   help="keep only the runs given this setting (repeatable), e.g. --only refine=none")
    p.add_argument("--formats", default="png,pdf", help="figure formats, e.g. png,pdf,svg (default png,pdf; none: no figures)")
    args = p.parse_args(argv)
    try:
        t = write_report(args.dirs, args.out, args.target, args.only, args.levels, args.budgets, args.round_off, args.ioh,
                         tuple(f for f in args.formats.split(",") if f and f != "none"))  # fmt: skip
    except ReportError as exc:
        p.exit(2, f"zrp-ga-report: error: {exc}\n")
    print(console(t))


if __name__ == "__main__":
    main()
