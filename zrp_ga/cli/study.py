"""The Optuna study of a tuning sweep (``hparams_search=ga_optuna``: ``hydra.sweeper.storage``
and ``study_name``) settled when the sweep is interrupted, and again when it is continued.

Hydra's Optuna sweeper asks the study for a batch of trials, has the launcher run them and tells
the study their values when the whole batch returned; a sweep stopped in between (Ctrl-C,
SIGTERM, a killed process) leaves the batch's trials RUNNING in the storage for good, the value
of a trial whose run had finished never told. :func:`settle` ends them through Optuna's public
API (``Study.tell``), each trial whose folder in the sweep folder (named by its number in the
study, as the tuning configs name it) holds a job run with the trial's settings (its
``.hydra/overrides.yaml``): a finished run (``status.json`` done, ``summary.json`` whole) gives
the trial the objective it returned (the summary's ``objective``, what
:func:`zrp_ga.run.execute.objective` returns to the sweeper), any other run FAILs it. A trial
without a folder (its job had not started) FAILs when the storage is the sweep folder's own
``optuna.db``, else it is left as it is (it may be another sweep's on a shared storage: Optuna's
distributed optimisation), as is a trial whose folder holds a job of other settings. An interrupted run
is not continued: the study's next trials get new numbers, folders and seeds (the sweeper asks
for new settings), so its checkpoint stays where it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import DictConfig


@dataclass(frozen=True)
class Study:
    """Where a tuning sweep keeps its study."""

    storage: str
    name: str
    sweep: Path

    @property
    def own(self) -> bool:
        """Whether the storage is an SQLite file in the sweep folder (as the tuning configs keep
        it): then every trial in it is this sweep folder's."""
        prefix = "sqlite:///"
        if not self.storage.startswith(prefix):
            return False
        return Path(self.storage[len(prefix) :]).absolute().parent == self.sweep.absolute()


_CURRENT: list[Study] = []  # the study of the sweep this process runs (set by the Manifest callback)


def of(config: DictConfig) -> Study | None:
    """The study of the sweep ``config`` (the sweep's, with ``hydra``), None without a storage."""
    sweeper = config.hydra.sweeper
    storage = sweeper.get("storage") if "storage" in sweeper else None
    name = sweeper.get("study_name") if "study_name" in sweeper else None
    if not storage or not name:
        return None
    return Study(str(storage), str(name), Path(str(config.hydra.sweep.dir)))


def started(config: DictConfig) -> None:
    """At the start of a sweep: settle what an earlier, interrupted run of its study left
    running, and remember the study for :func:`interrupted`."""
    _CURRENT.clear()
    study = of(config)
    if study is None:
        return
    _CURRENT.append(study)
    settle(study)


def interrupted() -> tuple[Study, bool] | None:
    """At Ctrl-C in the sweep's process: the study of its sweep settled, and whether it could be
    (False: its storage could not be written now; the next run of the sweep settles it). None:
    not a tuning sweep, or stopped before it started."""
    if not _CURRENT:
        return None
    study = _CURRENT[0]
    try:
        settle(study)
    except Exception:
        return study, False
    return study, True


def settle(study: Study) -> list[tuple[int, str]]:
    """End the study's RUNNING trials (see the module docstring); returns each one's number and
    the state it was given."""
    import optuna

    if not any(s.study_name == study.name for s in optuna.study.get_all_study_summaries(study.storage)):  # Optuna 2.10 - 5
        return []
    loaded = optuna.load_study(study_name=study.name, storage=study.storage)
    settled: list[tuple[int, str]] = []
    for trial in loaded.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        out = study.sweep / str(trial.number)
        if (out / ".hydra").exists() and not _made_with(out, trial.params):  # that folder is another trial's
            continue
        if not (out / ".hydra").exists() and not study.own:  # another sweep's on a shared storage, or not started
            continue
        value = finished_objective(out) if (out / ".hydra").exists() else None
        if value is None:
            loaded.tell(trial.number, state=optuna.trial.TrialState.FAIL)
            settled.append((trial.number, "FAIL"))
        else:
            loaded.tell(trial.number, value)
            settled.append((trial.number, "COMPLETE"))
    return settled


def finished_objective(out: Path) -> float | None:
    """The objective the run in ``out`` returned, if it finished whole; None otherwise."""
    from zrp_ga.run import directory

    if directory.status(out) != "done" or not (out / directory.SUMMARY).exists() or directory.damage(out):
        return None
    try:
        written = directory.read_summary(out)
    except (OSError, ValueError):
        return None
    value = written.get("objective", written.get("final_cost"))  # as zrp_ga.run.sweep keeps a finished job's
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def _made_with(out: Path, params: dict[str, Any]) -> bool:
    """Whether the job in ``out`` was run with the trial's ``params`` (each ``name=value`` among
    its overrides, numbers compared as numbers)."""
    import yaml

    try:
        overrides = yaml.safe_load((out / ".hydra" / "overrides.yaml").read_text())
    except (OSError, yaml.YAMLError):
        return False
    if not isinstance(overrides, list):
        return False
    given = dict(o.split("=", 1) for o in overrides if isinstance(o, str) and "=" in o)
    for name, value in params.items():
        if name not in given:
            return False
        try:
            same = float(given[name]) == float(value)
        except (TypeError, ValueError):
            same = given[name] == str(value)
        if not same:
            return False
    return True
