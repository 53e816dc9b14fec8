"""Hydra callbacks of ``zrp-ga``: the checks before a single run, and the sweep manifest's ends.

:class:`Prepare` checks a single run's config and builds its objects (robot, problem,
optimiser) before Hydra creates the run's directory, so that bad input stops with one line and
leaves nothing behind; the run it built is handed to :func:`zrp_ga.cli.main`
(:func:`take_prepared`), which runs it without building it again. :class:`Manifest` refuses a sweep
whose largest job does not fit the memory (:mod:`zrp_ga.cli.sweep_size`), prepares
the sweep directory and writes the manifest's table (each job records its own states,
:func:`zrp_ga.run.sweep.sweep_job`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from hydra.conf import HydraConf
from hydra.core.hydra_config import HydraConfig
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from zrp_ga.cli import study
from zrp_ga.run import directory


class Refused(BaseException):
    """A run refused before it started; ``error`` says why. A BaseException because Hydra turns
    a callback's ordinary exceptions into warnings and goes on; this one passes through to the
    console script (:func:`zrp_ga.cli.main.cli`), like ``KeyboardInterrupt``."""

    def __init__(self, error: Exception):
        super().__init__(str(error))
        self.error = error


class Prepare(Callback):
    """Checks and builds a single run before Hydra creates its directory (see the module docstring)."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        from zrp_ga.config import typed
        from zrp_ga.run import build

        _PREPARED.clear()
        try:
            p = build.prepare(typed(config), Path(config.hydra.run.dir), list(config.hydra.overrides.task),
                              dict(config.hydra.runtime.choices))  # fmt: skip
        except (ValueError, OSError) as exc:
            raise Refused(exc) from None
        except MemoryError as exc:  # not a warning, and not the work again (zrp_ga.run.budget's estimate missed)
            raise Refused(MemoryError(f"out of memory before the run started ({exc}); see zrp_ga.run.budget")) from None
        if config.get("resume") and not any(o.startswith("hydra.run.dir=") for o in config.hydra.overrides.hydra):
            # Hydra's own files (log, config) go into the resumed run's directory, not a new outputs/DATE/TIME
            with open_dict(config.hydra), read_write(config.hydra):
                config.hydra.run.dir = str(p.out)
                config.hydra.output_subdir = ".hydra/resume"
        _PREPARED[os.path.abspath(config.hydra.run.dir)] = p

    def on_run_end(self, config: DictConfig, **kwargs: Any) -> None:
        _PREPARED.clear()  # nothing kept past its run (main took it, or the job never started)


_PREPARED: dict[str, Any] = {}  # Prepare's run, by the directory Hydra runs it in, until main takes it


def take_prepared(out: Path) -> Any:
    """The run (a :class:`zrp_ga.run.build.Prepared`) that :class:`Prepare` checked and built
    for Hydra's run directory ``out``, handed over once; None when Prepare did not run."""
    p = _PREPARED.pop(os.path.abspath(out), None)
    if p is not None and p.state is None:
        p.out = Path(out)  # the directory as Hydra names it to the job (absolute)
    return p


def _ours(hydra: DictConfig | HydraConf) -> bool:
    """zrp_ga's launcher writes the manifest's table itself (a worker process runs many jobs)."""
    return str(hydra.launcher.get("_target_", "")).startswith("hydra_plugins.zrp_ga_launcher.")


class Manifest(Callback):
    """The sweep directory made and repaired before its jobs, the manifest's table after each
    job (Hydra skips ``on_multirun_end`` when a job failed) and at the end."""

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        from hydra.errors import HydraException

        from zrp_ga.cli import sweep_size

        try:
            sweep_size.check(config)  # the largest job against the memory limit, once, before any job or directory
        except (ValueError, OSError) as exc:
            raise Refused(exc) from None
        except HydraException:  # a job that cannot be composed: the sweeper says which, as it checks them
            pass
        sweep = Path(config.hydra.sweep.dir)
        grid = config.hydra.sweeper.get("params") if "params" in config.hydra.sweeper else None
        grid = OmegaConf.to_container(grid, resolve=False) if isinstance(grid, DictConfig) else grid
        try:  # one sweep per folder: another is refused here, before any job (the same one continues)
            directory.claim(sweep, list(config.hydra.overrides.task), grid)
        except (ValueError, OSError) as exc:
            raise Refused(exc) from None
        directory.repair(sweep)
        study.started(config)  # a tuning sweep continued: the trials its interrupted run left running settled

    def on_job_end(self, config: DictConfig, job_return: Any, **kwargs: Any) -> None:
        hc = HydraConfig.get()
        if hc.mode == RunMode.MULTIRUN and not _ours(hc):
            directory.write_table(hc.sweep.dir)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        directory.write_table(config.hydra.sweep.dir)
