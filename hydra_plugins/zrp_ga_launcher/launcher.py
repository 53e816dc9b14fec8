"""zrp_ga's Hydra launcher: ``zrp-ga -m ... hydra/launcher=zrp_ga`` (``hydra/launcher=local``: the
same on every core).

Long-lived worker processes, started once per sweep, import the app and load its compiled code
once (forked from the sweep's process after it warmed up, where processes can be forked), then
take jobs a batch at a time. GA jobs on one problem instance with one population shape run
together, their runs evolved in lockstep by the run layer (``_batch.py``; off with
``hydra.launcher.lockstep=false``), other jobs one at a time with Hydra's ``run_job``; every
job has its own output directory, ``.hydra`` config record, log file, callbacks (the manifest
line) and return value, as with Hydra's basic or joblib launcher. Job configs are composed from a few of Hydra's compositions
(``_compose.py``, equal to Hydra's own). While the jobs run, one line on stderr says how many are
done, failed and running and the time left (``_progress.py``; on a terminal only, else a plain
line a minute; none with ``progress=false``).

This module is imported by Hydra's plugin discovery at every start of every Hydra app, so it
imports nothing heavy; the work is in ``_workers`` and ``_compose`` (not scanned: names with
a leading underscore). It uses Hydra's public interfaces only (``Launcher``, ``run_job``, the
``ConfigLoader`` interface, ``Singleton.get_state``/``set_state``, ``HydraConfig``,
``configure_log``, ``JobReturn``), as hydra-core 1.3 and 1.4 keep them.
"""

from collections.abc import Sequence
from typing import Any, Optional

from hydra.core.utils import JobReturn
from hydra.plugins.launcher import Launcher
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig

from hydra_plugins.zrp_ga_launcher.config import ZrpGaLauncherConf  # its settings, stored in Hydra's ConfigStore there


class ZrpGaLauncher(Launcher):
    """See the module docstring; settings in :class:`hydra_plugins.zrp_ga_launcher.config.ZrpGaLauncherConf`."""

    def __init__(self, **settings: Any) -> None:
        self.settings = ZrpGaLauncherConf(**{k: v for k, v in settings.items() if k != "_target_"})
        self.config: Optional[DictConfig] = None
        self.task_function: Optional[TaskFunction] = None
        self.hydra_context: Optional[HydraContext] = None
        self.pool: Any = None

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig) -> None:
        from . import _batch, _compose, _workers

        self.settings.check()  # here, not in __init__: Hydra's instantiate would wrap its one line in its own
        # The sweeper checks every job with this same loader before launching: one cache for both.
        hydra_context.config_loader = _compose.ComposingLoader.wrap(
            hydra_context.config_loader, self.settings.cached_composition
        )
        if self.local and self.settings.lockstep and _batch.is_zrp_ga(task_function):
            # each job's batch key, noted as the sweeper checks it: the jobs of a key sent together
            hydra_context.config_loader.note = _workers._Dispatcher.key
        self.config, self.task_function, self.hydra_context = config, task_function, hydra_context
        if self.local:
            self.pool = _workers.Pool(self.settings, hydra_context, task_function, config)

    @property
    def local(self) -> bool:
        """On this machine's workers; else in batches, a cluster job each (``executor``: slurm, ray; ``_remote.py``)."""
        return str(getattr(self.settings.executor, "value", self.settings.executor)) == "local"

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
        if self.local:
            from . import _workers

            return _workers.launch(self, job_overrides, initial_job_idx)
        from . import _remote

        return _remote.launch(self, job_overrides, initial_job_idx)
