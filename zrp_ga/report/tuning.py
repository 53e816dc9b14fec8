"""Tuning studies in a report: for each Optuna storage a sweep folder holds (``optuna.db``, which
``hparams_search=ga_optuna`` keeps its study in), each study's trials, its best trial's value and
settings, and the parameters' importance (Optuna's fANOVA evaluator, ``optuna.importance``); for a
sweep folder without a storage, Hydra's ``optimization_results.yaml`` (the best settings). Written
as ``tuning.md`` beside the report's page."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

STORAGE = "optuna.db"
RESULTS = "optimization_results.yaml"


def find(dirs: list[str | Path]) -> tuple[list[Path], list[Path]]:
    """The Optuna storages and the ``optimization_results.yaml`` without a storage beside them,
    in ``dirs`` and the folders below them."""
    storages: list[Path] = []
    results: list[Path] = []
    for d in map(Path, dirs):
        if d.is_file():
            continue
        storages += sorted(d.rglob(STORAGE)) if not (d / STORAGE).exists() else [d / STORAGE]
        results += [r for r in sorted(d.rglob(RESULTS)) if not (r.parent / STORAGE).exists()]
    return list(dict.fromkeys(storages)), list(dict.fromkeys(results))


def _number(x: Any) -> str:
    return f"{x:.6g}" if isinstance(x, float) else str(x)


def study_lines(storage: Path) -> list[str]:
    """The Markdown lines of every study in the SQLite storage ``storage``."""
    import optuna

    url = f"sqlite:///{storage.absolute().as_posix()}"
    lines: list[str] = []
    for name in [s.study_name for s in optuna.study.get_all_study_summaries(url)]:  # Optuna 2.10 - 5
        study = optuna.load_study(study_name=name, storage=url)
        trials = study.get_trials(deepcopy=False)
        done = [t for t in trials if t.state == optuna.trial.TrialState.COMPLETE]
        lines += [f"## Study {name} ({storage})", "",
                  f"{len(trials)} trials, {len(done)} complete "
                  f"({len({tuple(sorted(t.params.items())) for t in trials})} distinct settings)."]  # fmt: skip
        if not done:
            lines += [""]
            continue
        best = study.best_trial
        lines += [f"Best trial: number {best.number}, value {_number(best.value)}.", "", "| setting | best value | importance |",
                  "| --- | --- | --- |"]  # fmt: skip
        found = _importance(study)
        importance = found if isinstance(found, dict) else {}
        for key in sorted(best.params, key=lambda k: -importance.get(k, -1.0)):
            share = importance.get(key)
            lines.append(f"| {key} | {_number(best.params[key])} | {'' if share is None else f'{share:.2f}'} |")
        if isinstance(found, str):
            lines += ["", f"Importance: {found.rstrip('.')}."]
        else:
            lines += ["", "Importance: Optuna's fANOVA evaluator (shares of the objective's variance, summing to 1)."]
        lines.append("")
    return lines


def _importance(study: Any) -> dict[str, float] | str:
    """The parameters' importance (fANOVA), or why there is none."""
    import optuna

    try:
        found = optuna.importance.get_param_importances(study, evaluator=optuna.importance.FanovaImportanceEvaluator(seed=0))
    except Exception as exc:  # too few trials; Optuna 2.10's fANOVA fails with numpy 2
        return f"not computed: Optuna {optuna.__version__}'s fANOVA evaluator says {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    return {k: float(v) for k, v in found.items() if math.isfinite(v)}


def results_lines(path: Path) -> list[str]:
    """The Markdown lines of Hydra's ``optimization_results.yaml`` (a study without a storage)."""
    import yaml

    found = yaml.safe_load(path.read_text()) or {}
    lines = [f"## {path}", "", f"Best value {_number(found.get('best_value'))}.", "", "| setting | best value |", "| --- | --- |"]
    lines += [f"| {k} | {_number(v)} |" for k, v in (found.get("best_params") or {}).items()]
    return [*lines, ""]


def write(dirs: list[str | Path], out: Path) -> Path | None:
    """``out/tuning.md`` for the tuning studies found in ``dirs`` (None: none found)."""
    storages, results = find(dirs)
    if not storages and not results:
        return None
    lines = ["# Tuning studies", ""]
    for storage in storages:
        lines += study_lines(storage)
    for path in results:
        lines += results_lines(path)
    out.mkdir(parents=True, exist_ok=True)
    (out / "tuning.md").write_text("\n".join(lines))
    return out / "tuning.md"
