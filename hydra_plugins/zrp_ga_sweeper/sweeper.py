"""zrp_ga's sweeper (``hydra/sweeper=zrp_ga``), through Hydra's public ``Sweeper`` interface.

Hydra's basic sweeper composes every job's config before it launches a batch (to report a bad
override before any job runs): 64 s of a 10,080-run sweep's 412 s, before any worker had a job.
This sweeper expands the same grid (every combination of the sweep overrides, in Hydra's order;
``hydra.sweeper.params`` first, then the command line's; ``max_batch_size`` as Hydra's) and
composes only the jobs that bring something not yet checked: a new combination of config-group
choices (``crossover=sbx mutation=swap``: another schema, other keys) or a new value of a key
(``seed=7``, ``crossover.prob=0.9``). A bad value or option still fails the sweep before any job
runs; a value valid with one option and not with another fails in its own job, with the same
message. Every job is launched as Hydra launches it (the configured launcher composes it and
writes its ``.hydra`` record); ``multirun.yaml`` is written as Hydra writes it.
"""

import copy
import itertools
import logging
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.core.utils import JobReturn
from hydra.errors import HydraException
from hydra.plugins.launcher import Launcher
from hydra.plugins.sweeper import Sweeper
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, OmegaConf, flag_override

log = logging.getLogger(__name__)


@dataclass  # no `from __future__ import annotations`: Hydra's plugin scan runs this module outside sys.modules
class ZrpGaSweeperConf:
    """The settings of zrp_ga's sweeper (``hydra.sweeper.*``), Hydra's basic sweeper's."""

    _target_: str = "hydra_plugins.zrp_ga_sweeper.sweeper.ZrpGaSweeper"
    max_batch_size: Optional[int] = None  # jobs per launch; null: the whole grid at once
    params: Optional[dict[str, str]] = None  # sweep overrides of the config (KEY: 'a,b', KEY: 'range(3)')


ConfigStore.instance().store(group="hydra/sweeper", name="zrp_ga", node=ZrpGaSweeperConf, provider="zrp_ga")


def grid(overrides: Sequence[Override]) -> list[list[str]]:
    """The jobs' overrides: every combination of the sweeps' values, the last key varying fastest,
    a key given twice taking its last place and values (as Hydra's basic sweeper expands them)."""
    values: dict[str, list[str]] = {}
    for o in overrides:
        key = o.get_key_element()
        if o.is_sweep_override():
            if not o.is_discrete_sweep():
                raise HydraException(f"ZrpGaSweeper does not support sweep type : {o.value_type.name if o.value_type else o}")
            values[key] = [f"{key}={v}" for v in o.sweep_string_iterator()]
        else:
            values[key] = [f"{key}={o.get_value_element_as_str()}"]
    return [list(job) for job in itertools.product(*values.values())]


class Checker:
    """Checks the jobs' configs as Hydra's basic sweeper does (every job composed by the config
    loader: ``load_sweep_config``), with fewer compositions: a job is composed if it chooses a
    config-group option (``crossover=sbx``) no composed job chose, or sets a value in a way that
    is not a plain assignment (``+key=``, ``~key``, ``key@package=``, ``hydra.*``); a new plain
    value (``seed=7``, ``crossover.prob=0.9``) is assigned to the config composed for the same
    group choices (OmegaConf checks its key and type), the job composed where there is none or
    where the assignment fails (Hydra's own error, if it is one). Each job's config is still
    composed by the launcher, which fails a job whose config does not compose."""

    def __init__(self, loader: Any, master: DictConfig, groups: set[str]) -> None:
        self.loader, self.master, self.groups = loader, master, groups
        self.parser = OverridesParser.create(config_loader=loader)
        self.seen: set[str] = set()
        self.composed: dict[tuple[str, ...], DictConfig] = {}
        self.compositions = 0

    def check(self, jobs: Sequence[Sequence[str]]) -> None:
        for job in jobs:
            choices = tuple(o for o in job if _key(o) in self.groups)
            new = [o for o in job if o not in self.seen]
            if not new:
                continue
            plain = all(_key(o) not in self.groups and _plain(o) for o in new)
            if not (plain and choices in self.composed and self._assign(self.composed[choices], new)):
                cfg = self.loader.load_sweep_config(master_config=self.master, sweep_overrides=list(job))
                self.composed[choices] = copy.deepcopy(cfg)  # assigned to: not the loader's (a launcher may keep it for the job)
                self.compositions += 1
            self.seen.update(new)

    def _assign(self, cfg: DictConfig, overrides: list[str]) -> bool:
        try:
            with flag_override(cfg, "readonly", False):
                for o in self.parser.parse_overrides(overrides):
                    OmegaConf.update(cfg, o.key_or_group, o.value(), merge=True)
        except Exception:  # the job composed instead: Hydra's own answer and message
            return False
        return True


def _plain(override: str) -> bool:
    """Whether ``override`` is a plain ``KEY=VALUE`` of the job's own config."""
    key = override.split("=", 1)[0]
    return key == key.lstrip("+~") and "@" not in key and not key.startswith("hydra.") and key != "hydra"


def _key(override: str) -> str:
    """The config key or group of one override ``[+~]KEY[@PACKAGE]=VALUE``."""
    return override.split("=", 1)[0].lstrip("+~").split("@", 1)[0]


class ZrpGaSweeper(Sweeper):
    def __init__(self, max_batch_size: Optional[int] = None, params: Optional[dict[str, str]] = None) -> None:
        self.max_batch_size = max_batch_size
        self.params = params
        self.config: DictConfig | None = None
        self.hydra_context: HydraContext | None = None
        self.launcher: Launcher | None = None
        self.compositions = 0  # job configs composed before their launch (tests and logs)

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig) -> None:
        from hydra.core.plugins import Plugins

        self.hydra_context = hydra_context
        self.config = config
        self.launcher = Plugins.instance().instantiate_launcher(hydra_context=hydra_context, task_function=task_function, config=config)

    def batches(self, arguments: list[str]) -> Iterator[list[list[str]]]:
        """The sweep's jobs (their overrides), in batches of ``max_batch_size``."""
        assert self.hydra_context is not None
        params = [f"{k}={v}" for k, v in (self.params or {}).items()] + list(arguments)
        jobs = grid(OverridesParser.create(config_loader=self.hydra_context.config_loader).parse_overrides(params))
        n = len(jobs) if self.max_batch_size in (None, -1) else self.max_batch_size
        if n is None or n <= 0:
            raise HydraException(f"hydra.sweeper.max_batch_size must be positive or -1, not {self.max_batch_size}")
        for i in range(0, len(jobs), n):
            yield jobs[i : i + n]

    def sweep(self, arguments: list[str]) -> Any:
        assert self.config is not None and self.launcher is not None and self.hydra_context is not None
        batches = list(self.batches(arguments))
        groups = _groups(self.hydra_context.config_loader, batches[0] if batches else [])
        sweep_dir = Path(self.config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        returns: list[Sequence[JobReturn]] = []
        checker = Checker(self.hydra_context.config_loader, self.config, groups)
        first = 0
        for batch in batches:
            tic = time.perf_counter()
            checker.check(batch)
            self.compositions = checker.compositions
            log.debug(f"Validated {len(batch)} job configs ({checker.compositions} composed) in {time.perf_counter() - tic:0.2f} s")
            results = self.launcher.launch(batch, initial_job_idx=first)
            for r in results:
                _ = r.return_value  # a failed job's exception raised
            first += len(batch)
            returns.append(results)
        return returns


def _groups(loader: Any, jobs: Sequence[Sequence[str]]) -> set[str]:
    """The keys of ``jobs``' overrides that are config groups (``crossover``, ``hydra/launcher``),
    asked of the config loader's sources (Hydra's ``ConfigSource.is_group``)."""
    keys = {_key(o) for job in jobs[:1] for o in job}
    return {k for k in keys if any(s.is_group(k) for s in loader.get_sources())}
