"""The settings of zrp_ga's launcher (``hydra.launcher.*`` with ``hydra/launcher=zrp_ga``, and the
presets of ``conf/hydra/launcher`` that extend it), stored in Hydra's ConfigStore when this
module is imported, as Hydra's own launcher plugins keep theirs: Hydra's plugin discovery imports
it (every module of the ``hydra_plugins`` packages whose name has no leading underscore, or
through ``launcher.py`` with hydra-core 1.4's entry points), and so does ``zrp-ga``, which
registers the launcher itself where discovery misses it (an editable install under 1.3)."""

from dataclasses import dataclass
from enum import Enum
from typing import Any, Optional

from hydra.core.config_store import ConfigStore

from zrp_ga.core.schema import ConfigError


class Executor(Enum):
    local = "local"  # this machine's cores: long-lived worker processes
    slurm = "slurm"  # a SLURM cluster through submitit, a batch of runs per cluster job
    ray = "ray"  # a Ray cluster, a batch of runs per task


@dataclass
class ZrpGaLauncherConf:
    """The settings of zrp_ga's launcher (``hydra.launcher.*``)."""

    _target_: str = "hydra_plugins.zrp_ga_launcher.launcher.ZrpGaLauncher"
    n_jobs: int = -1  # worker processes; -1: one per core this process may use
    batch_size: int = 1  # jobs handed to a worker at a time (it holds two batches, so it never waits)
    start_method: Optional[str] = None  # multiprocessing's: null is fork on Linux, spawn elsewhere
    cached_composition: bool = True  # job configs from a few of Hydra's compositions (equal to Hydra's)
    warm_up: Optional[str] = "zrp_ga.cli.main.warm_up"  # called with the sweep's config before the first job
    table_every_s: float = 1.0  # manifest.csv rewritten at most this often (and at the end)
    lockstep: bool = True  # GA jobs on one problem instance with one population shape evolved together (zrp_ga.run.sweep.sweep_batch)
    # Beyond this machine (hydra_plugins/zrp_ga_launcher/_remote.py): the jobs in batches, a batch per cluster job.
    executor: Executor = Executor.local
    runs_per_job: int = 300  # jobs of the sweep run one after another in one cluster job (those of one batch_key together)
    cpus_per_task: int = 1  # cores of a cluster job (SLURM's cpus_per_task; Ray's num_cpus of a task)
    # SLURM, through submitit:
    cluster: Optional[str] = "slurm"  # submitit's AutoExecutor cluster: slurm; local or debug try it on this machine; null: SLURM where found
    partition: Optional[str] = None
    account: Optional[str] = None
    timeout_min: int = 60  # of a cluster job: runs_per_job runs
    mem_gb: float = 2.0
    array_parallelism: int = 64  # cluster jobs of the sweep running at a time
    submitit_folder: str = "${hydra.sweep.dir}/.submitit/%j"  # submitit's job files and logs
    # Ray:
    ray_address: Optional[str] = None  # a running cluster (auto: the one this node belongs to); null: a Ray started on this machine
    ray_num_cpus: Optional[int] = None  # cores of the Ray started on this machine (null: all)

    def check(self, key: str = "hydra.launcher") -> None:
        for name in ("runs_per_job", "cpus_per_task"):
            value = getattr(self, name)
            if value < 1:
                raise ConfigError(f"{key}.{name}: must be at least 1, got {value}")


def _store() -> None:
    """``hydra/launcher=zrp_ga`` in Hydra's ConfigStore. hydra-core 1.3's plugin scan runs this
    module a second time where it was imported before (from the source tree, or by ``zrp-ga``):
    its class is then a new one, which the stored node must hold (a composed config is pickled
    with it), so it is stored again; 1.4 imports it once, and would warn about a name stored
    twice without ``replace``."""
    import inspect

    cs = ConfigStore.instance()
    replace: dict[str, Any] = {"replace": True} if "replace" in inspect.signature(cs.store).parameters else {}  # hydra-core 1.4
    cs.store(group="hydra/launcher", name="zrp_ga", node=ZrpGaLauncherConf, provider="zrp_ga", **replace)


_store()
