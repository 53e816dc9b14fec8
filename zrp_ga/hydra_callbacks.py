"""Hydra callbacks: checks before a run, and the sweep manifest.

:class:`Prepare` checks a single run's config and builds its objects (robot, problem, optimiser)
before Hydra creates the run's directory, so that bad input stops with one line and leaves
nothing behind (the app reuses what it built).

Every job of a multirun appends its state to ``manifest.jsonl`` in the sweep directory when it
starts (``running``) and when it ends (``done``, or ``failed`` with the error), one JSON line
each, so that a sweep still running, or killed, can be read at any time; the last line of a job
is its state; ``manifest.csv`` holds one row per job, rewritten as each job ends. Lines are short
and appended with one ``write`` each, so jobs of a parallel launcher do not interleave them.
"""

from __future__ import annotations

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


def _append(path: Path, record: dict) -> None:
    line = json.dumps(record) + "\n"
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, line.encode())
    finally:
        os.close(fd)


def read_manifest(sweep_dir: str | Path):
    """One row per job with its last state (a pandas DataFrame): job, overrides, dir, status, error, time."""
    import pandas as pd

    path = Path(sweep_dir) / MANIFEST
    records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    if not records:
        return pd.DataFrame(columns=["job", "overrides", "dir", "status", "error", "time"])
    df = pd.DataFrame(records).drop_duplicates("job", keep="last").sort_values("job")
    return df.reset_index(drop=True)


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


class Manifest(Callback):
    """Writes the sweep manifest (see the module docstring)."""

    def _record(self, status: str, error: str | None = None) -> None:
        hc = HydraConfig.get()
        if hc.mode != RunMode.MULTIRUN:
            return
        sweep = Path(hc.sweep.dir)
        sweep.mkdir(parents=True, exist_ok=True)
        _append(
            sweep / MANIFEST,
            {
                "job": int(hc.job.num),
                "overrides": " ".join(hc.overrides.task),
                "dir": str(hc.sweep.subdir),
                "status": status,
                "error": error,
                "time": datetime.datetime.now().isoformat(timespec="seconds"),
            },
        )

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._record("running")

    def on_job_end(self, config: DictConfig, job_return: JobReturn, **kwargs: Any) -> None:
        if job_return.status == JobStatus.COMPLETED:
            self._record("done")
        else:
            exc = job_return._return_value
            self._record("failed", f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            # A table of the jobs so far, replaced whole (Hydra skips on_multirun_end when a job failed).
            sweep = Path(HydraConfig.get().sweep.dir)
            tmp = sweep / f".manifest.{os.getpid()}.csv"
            read_manifest(sweep).to_csv(tmp, index=False)
            os.replace(tmp, sweep / "manifest.csv")
