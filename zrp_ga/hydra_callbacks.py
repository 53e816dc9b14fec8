"""Hydra callbacks: checks before a run, and the sweep manifest.

:class:`Prepare` checks a single run's config and builds its objects (robot, problem, optimiser)
before Hydra creates the run's directory, so that bad input stops with one line and leaves
nothing behind (the app reuses what it built).

Every job of a multirun appends its state to ``manifest.jsonl`` in the sweep directory when it
starts (``running``) and when it ends (``done``; ``failed`` with the error; ``interrupted`` at
Ctrl-C), one JSON line each, so that a sweep still running, or killed, can be read at any time;
the last line of a job is its state. A job whose directory already holds a finished run (a
sweep started again, see ``zrp_ga.app.sweep_job``) is recorded ``done`` without passing through
``running``. ``manifest.csv`` holds one row per job, rewritten whole (a temporary file, then a
rename) as jobs end.

Nothing a kill can do loses a recorded state: lines are short and appended with one ``write``
each (jobs of a parallel launcher do not interleave them, and a killed process writes a line
whole or not at all), and a sweep started again first ends a line that a crash of the machine
left unfinished, so that its own lines stay whole; :func:`read_manifest` skips such a fragment.
"""

from __future__ import annotations

import csv
import datetime
import json
import os
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import JobReturn, JobStatus
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig

MANIFEST = "manifest.jsonl"
TABLE = "manifest.csv"
COLUMNS = ["job", "overrides", "dir", "status", "error", "time"]

sweep_dir: Path | None = None  # the sweep this process started (for the interrupt message)
table_each_job = True  # False in the workers of zrp_ga's launcher, which writes the table itself


def _append(path: Path, record: dict) -> None:
    line = json.dumps(record) + "\n"
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, line.encode())
    finally:
        os.close(fd)


def _records(sweep: Path) -> list[dict]:
    """The manifest's records, skipping a line a crash left unfinished."""
    path = Path(sweep) / MANIFEST
    out = []
    for line in path.read_text().splitlines():
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if isinstance(record, dict) and "job" in record:
            out.append(record)
    return out


def job_states(sweep: str | Path) -> list[dict]:
    """Each job's last record, by job number."""
    last = {int(r["job"]): r for r in _records(Path(sweep))}
    return [{k: last[job].get(k) for k in COLUMNS} for job in sorted(last)]


def read_manifest(sweep: str | Path):
    """One row per job with its last state (a pandas DataFrame): job, overrides, dir, status, error, time."""
    import pandas as pd

    return pd.DataFrame(job_states(sweep), columns=COLUMNS)


def write_table(sweep: str | Path) -> None:
    """``manifest.csv`` from ``manifest.jsonl``, replaced whole."""
    sweep = Path(sweep)
    tmp = sweep / f".manifest.{os.getpid()}.csv"
    with open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(job_states(sweep))
    os.replace(tmp, sweep / TABLE)


def repair(sweep: str | Path) -> None:
    """Before a sweep (started again) writes: end a line left unfinished by a crash, so that the
    next one stays whole, and remove temporary tables of killed processes."""
    sweep = Path(sweep)
    path = sweep / MANIFEST
    if path.exists() and path.stat().st_size:
        with open(path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            unfinished = f.read(1) != b"\n"
        if unfinished:
            fd = os.open(path, os.O_WRONLY | os.O_APPEND)
            try:
                os.write(fd, b"\n")
            finally:
                os.close(fd)
    for tmp in sweep.glob(".manifest.*.csv"):
        tmp.unlink(missing_ok=True)


def record(status: str, error: str | None = None) -> None:
    """Append this job's state to its sweep's manifest (nothing outside a multirun job)."""
    if not HydraConfig.initialized():
        return
    hc = HydraConfig.get()
    if hc.mode != RunMode.MULTIRUN:
        return
    sweep = Path(hc.sweep.dir)
    sweep.mkdir(parents=True, exist_ok=True)
    _append(sweep / MANIFEST, {
        "job": int(hc.job.num),
        "overrides": " ".join(hc.overrides.task),
        "dir": str(hc.sweep.subdir),
        "status": status,
        "error": error,
        "time": datetime.datetime.now().isoformat(timespec="seconds"),
    })  # fmt: skip


class Refused(BaseException):
    """A run refused before it started; ``error`` says why. A BaseException because Hydra turns
    a callback's ordinary exceptions into warnings and goes on; this one passes through to the
    console script (``zrp_ga.app.cli``), like ``KeyboardInterrupt``."""

    def __init__(self, error: Exception):
        super().__init__(str(error))
        self.error = error


class Prepare(Callback):
    """Checks and builds a single run before Hydra creates its directory (see the module docstring)."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        from zrp_ga import app

        try:
            app.prepare(config, Path(config.hydra.run.dir))
        except (ValueError, OSError) as exc:
            raise Refused(exc) from None
        except MemoryError as exc:  # not a warning, and not the work again (zrp_ga.budget's estimate missed)
            raise Refused(MemoryError(f"out of memory before the run started ({exc}); see zrp_ga.budget")) from None


class Manifest(Callback):
    """Writes the sweep manifest (see the module docstring)."""

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        global sweep_dir
        sweep_dir = Path(config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        repair(sweep_dir)

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        from zrp_ga import app

        if HydraConfig.get().mode == RunMode.MULTIRUN and app.run_status(Path(HydraConfig.get().runtime.output_dir)) != "done":
            record("running")

    def on_job_end(self, config: DictConfig, job_return: JobReturn, **kwargs: Any) -> None:
        if HydraConfig.get().mode != RunMode.MULTIRUN:
            return
        if job_return.status == JobStatus.COMPLETED:
            record("done")
        else:
            exc = job_return._return_value
            record("failed", f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
        if table_each_job:  # (Hydra skips on_multirun_end when a job failed)
            write_table(HydraConfig.get().sweep.dir)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        write_table(config.hydra.sweep.dir)
