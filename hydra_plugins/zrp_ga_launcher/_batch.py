"""Jobs of a sweep run together: each keeps what Hydra's ``run_job`` gives it, and their runs
go through one call of :func:`zrp_ga.run.execute.sweep_batch`, which evolves them together.

For each job, as ``run_job`` does it: its output directory, the three ``.hydra`` records
(``config.yaml``, ``hydra.yaml``, ``overrides.yaml``: the same text Hydra writes), Hydra's view
of the job (``HydraConfig``, its ``env_set``, its working directory with ``hydra.job.chdir``)
and its log file (``hydra.job_logging``) while anything is done for it alone, the callbacks'
``on_job_start`` and ``on_job_end`` (zrp_ga's manifest, any of the user's), and a ``JobReturn``
with its status and return value. The task's own part is that of ``zrp_ga.cli.main`` for a job
of a sweep: the run, then the one line saying how it ended.

Logging is configured once for the batch, as Hydra configures it for its first job; the
handlers whose settings differ from job to job (the log file, named after the job's
directory) are one per job, attached while that job's work runs (``around`` of
``sweep_batch``) and open only while it writes.

Callable in any process that got the pickled configs and ``hydra_context`` (a worker of this
launcher, or a cluster's job): :func:`run_batch`. A task function other than ``zrp_ga.cli.main``
runs its jobs one at a time through Hydra's ``run_job``. Hydra's public interfaces only.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml
from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import JobReturn, JobRuntime, JobStatus, configure_log, env_override, run_job, setup_globals
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

log = logging.getLogger(__name__)


def run_batch(jobs: list[tuple[int, DictConfig]], hydra_context: HydraContext, task_function: TaskFunction) -> list[JobReturn]:
    """Run the sweep's jobs ``(job number, composed config)``, their runs together; a
    ``JobReturn`` per job, in order, as Hydra's ``run_job`` makes it. Raises KeyboardInterrupt
    (at Ctrl-C) once every job recorded its state."""
    setup_globals()  # Hydra's resolvers (a fresh process)
    if not is_zrp_ga(task_function):
        return [run_alone(idx, cfg, hydra_context, task_function) for idx, cfg in jobs]
    return _Batch(jobs, hydra_context, task_function).run()


def run_alone(idx: int, config: DictConfig, hydra_context: HydraContext, task_function: TaskFunction) -> JobReturn:
    """One job with Hydra's ``run_job``, as Hydra's basic launcher runs it."""
    _number(config, idx)
    return run_job(hydra_context=hydra_context, task_function=task_function, config=config,
                   job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir")  # fmt: skip


def is_zrp_ga(task_function: Any) -> bool:
    """Whether ``task_function`` is ``zrp_ga.cli.main`` (or the function it wraps), whose jobs
    :func:`run_batch` runs together."""
    fn = getattr(task_function, "__wrapped__", task_function)
    return (getattr(fn, "__module__", None), getattr(fn, "__qualname__", None)) == ("zrp_ga.cli", "main")


def _number(config: DictConfig, idx: int) -> None:
    with open_dict(config):
        config.hydra.job.id = str(idx)  # a string field
        config.hydra.job.num = idx


# --- the .hydra records --------------------------------------------------------------------------------
class _Dumper(getattr(yaml, "CDumper", yaml.Dumper)):  # type: ignore[misc]
    """OmegaConf's YAML dumper (``OmegaConf.to_yaml``: strings that read as another type
    quoted), on libyaml's emitter when PyYAML has it."""


def _str_representer(dumper: Any, data: str) -> Any:
    from omegaconf._utils import is_float, is_int, yaml_is_bool  # the rules OmegaConf's dumper applies

    quoted = yaml_is_bool(data) or is_int(data) or is_float(data)
    return dumper.represent_scalar(yaml.resolver.BaseResolver.DEFAULT_SCALAR_TAG, data, style=("'" if quoted else None))


_Dumper.add_representer(str, _str_representer)


def to_yaml(cfg: Any) -> str:
    """``OmegaConf.to_yaml(cfg)``, faster."""
    container = OmegaConf.to_container(cfg, resolve=False, enum_to_str=True)
    return yaml.dump(container, Dumper=_Dumper, default_flow_style=False, allow_unicode=True, sort_keys=False)


def _save(text: str, path: Path) -> None:
    with open(path, "w", encoding="utf-8") as f:  # as Hydra's _save_config
        f.write(text)


# --- a job's log file ----------------------------------------------------------------------------------
class _JobLog(logging.FileHandler):
    """A job's log file (a handler of ``hydra.job_logging`` whose file is the job's own), open
    only while its job runs: :meth:`pause` closes it until the job's next line, which then
    appends."""

    def pause(self) -> None:
        self.acquire()
        try:
            if self.stream is not None:
                self.stream.close()
                self.stream = None
                self.mode = "a"
        finally:
            self.release()


def _job_logs(handlers: dict[str, logging.Handler], confs: list[dict]) -> tuple[list[str], list[list[_JobLog]]] | None:
    """The names of the root's handlers whose settings differ between the jobs (``confs``: each
    job's ``hydra.job_logging``, resolved; the first one's is configured, its handlers are
    ``handlers`` by name), and per job its own copies of them; None when the jobs' settings
    differ in more than the name of a ``logging.FileHandler``'s file."""
    first = confs[0]

    def without(c: dict, name: str | None = None) -> dict:
        if name is None:
            return {**c, "handlers": sorted(c.get("handlers") or {})}
        return {**c["handlers"][name], "filename": None}

    if any(without(c) != without(first) for c in confs):
        return None
    varying = [name for name in first.get("handlers") or {} if any(c["handlers"][name] != first["handlers"][name] for c in confs)]
    out: list[list[_JobLog]] = [[] for _ in confs]
    for name in varying:
        h = handlers.get(name)
        if type(h) is not logging.FileHandler or any(without(c, name) != without(first, name) for c in confs):
            return None
        for k, c in enumerate(confs):
            mine = _JobLog(c["handlers"][name]["filename"], mode=h.mode, encoding=h.encoding, delay=True, errors=h.errors)
            mine.setLevel(h.level)
            mine.setFormatter(h.formatter)
            for f in h.filters:
                mine.addFilter(f)
            out[k].append(mine)
    return varying, out


# --- the batch -----------------------------------------------------------------------------------------
class _Job:
    """One job of the batch: its configs, Hydra's view of it, its directory and return."""

    def __init__(self, idx: int, config: DictConfig):
        self.idx, self.config = idx, config
        self.ret = JobReturn()
        self.hydra: Any = None  # HydraConfig's config of this job
        self.out: Path | None = None
        self.logs: list[_JobLog] = []
        self.error: Exception | None = None

    def prepare(self) -> None:
        """As ``run_job`` before the task: the config numbered, its output directory, Hydra's
        view of it, the task's config, the directory made and the ``.hydra`` records written."""
        config = self.config
        _number(config, self.idx)
        HydraConfig.instance().set_config(config)
        output_dir = os.path.join(str(OmegaConf.select(config, "hydra.sweep.dir")), str(OmegaConf.select(config, "hydra.sweep.subdir")))
        with read_write(config.hydra.runtime), open_dict(config.hydra.runtime):
            config.hydra.runtime.output_dir = os.path.abspath(output_dir)
        HydraConfig.instance().set_config(config)
        self.hydra = HydraConfig.instance().cfg
        self.out = Path(output_dir)
        task_cfg = copy.deepcopy(config)
        with read_write(task_cfg), open_dict(task_cfg):
            del task_cfg["hydra"]
        self.ret.cfg, self.ret.hydra_cfg = task_cfg, self.hydra
        self.ret.overrides = OmegaConf.to_container(config.hydra.overrides.task)
        self.out.mkdir(parents=True, exist_ok=True)
        self.chdir = bool(config.hydra.job.chdir)
        self.ret.working_dir = output_dir if self.chdir else os.getcwd()
        self.env = dict(config.hydra.job.env_set)
        if config.hydra.output_subdir is not None:
            records = Path(config.hydra.runtime.output_dir) / str(config.hydra.output_subdir)
            records.mkdir(parents=True, exist_ok=True)
            _save(to_yaml(task_cfg), records / "config.yaml")
            _save(to_yaml(self.hydra), records / "hydra.yaml")
            _save(to_yaml(config.hydra.overrides.task), records / "overrides.yaml")

    @contextlib.contextmanager
    def around(self) -> Iterator[None]:
        """Hydra's view of this job and its log file, while something is done for it alone."""
        instance = HydraConfig.instance()
        before, instance.cfg = instance.cfg, self.hydra
        root = logging.getLogger()
        for h in self.logs:
            root.addHandler(h)
        cwd = os.getcwd() if self.chdir else None
        if cwd is not None:
            os.chdir(self.out)
        try:
            with env_override(self.env) if self.env else contextlib.nullcontext():
                yield
        finally:
            if cwd is not None:
                os.chdir(cwd)
            for h in self.logs:
                root.removeHandler(h)
                h.pause()
            instance.cfg = before


class _Batch:
    def __init__(self, jobs: list[tuple[int, DictConfig]], hydra_context: HydraContext, task_function: TaskFunction):
        self.jobs = [_Job(idx, cfg) for idx, cfg in jobs]
        self.hydra_context, self.task_function = hydra_context, task_function

    def run(self) -> list[JobReturn]:
        from zrp_ga.run import directory

        instance = HydraConfig.instance()
        before = instance.cfg
        try:
            for job in self.jobs:
                try:
                    job.prepare()
                except Exception as exc:  # a bad config value, a directory that cannot be made
                    job.error = exc
            ready = [j for j in self.jobs if j.error is None]
            if not self.logging(ready):
                for job in ready:
                    job.ret = run_alone(job.idx, job.config, self.hydra_context, self.task_function)
                ready = []
            for job in ready:
                with job.around():
                    self.hydra_context.callbacks.on_job_start(config=job.config, task_function=self.task_function)
            values = self.sweep(ready)
            for job, value in zip(ready, values):
                with job.around():
                    self.end(job, value)
            for job in self.jobs:
                if job.error is not None:
                    self.failed_before(job, directory)
        finally:
            instance.cfg = before
        return [job.ret for job in self.jobs]

    def logging(self, ready: list[_Job]) -> bool:
        """Hydra's job logging, configured for the first job, with each job's own log files;
        False when the jobs' logging settings differ in more than their files' names (then
        each job runs alone, with its own)."""
        if not ready:
            return True
        first = ready[0]
        with first.around():
            configure_log(first.config.hydra.job_logging, first.config.hydra.verbose)
        if first.config.hydra.job_logging is None:
            return True
        confs = []
        for job in ready:
            with job.around():
                confs.append(OmegaConf.to_container(job.config.hydra.job_logging, resolve=True))
        root = logging.getLogger()
        handlers = {h.name: h for h in root.handlers if h.name}
        found = _job_logs(handlers, confs)
        if found is None:
            return False
        varying, logs = found
        for name in varying:
            root.removeHandler(handlers[name])
            handlers[name].close()
        for job, mine in zip(ready, logs):
            job.logs = mine
            for h in mine:  # the file exists from the job's start, as with Hydra
                open(h.baseFilename, h.mode, encoding=h.encoding).close()
        return True

    def sweep(self, ready: list[_Job]) -> list[Any]:
        """The runs, together (``zrp_ga.cli.main``'s part, but the console line)."""
        from zrp_ga.cli import sweep_job_args
        from zrp_ga.run import execute

        tasks = []
        for job in ready:
            with job.around():
                tasks.append((job.ret.cfg, *sweep_job_args(HydraConfig.get())))
        return execute.sweep_batch(tasks, around=lambda k: ready[k].around()) if tasks else []

    def end(self, job: _Job, value: Any) -> None:
        """As ``run_job`` after the task: the console line, the status, the callbacks."""
        from zrp_ga import summary

        ret = job.ret
        if isinstance(value, Exception):
            ret.return_value, ret.status = value, JobStatus.FAILED
        else:
            try:
                hc = HydraConfig.get()
                summary.console(job.out, (hc.job.num, " ".join(ret.overrides)))
                ret.return_value, ret.status = value, JobStatus.COMPLETED
            except Exception as exc:
                ret.return_value, ret.status = exc, JobStatus.FAILED
        ret.task_name = JobRuntime.instance().get("name")
        for h in logging.getLogger().handlers:
            with contextlib.suppress(Exception):
                h.flush()
        self.hydra_context.callbacks.on_job_end(config=job.config, job_return=ret)

    def failed_before(self, job: _Job, directory: Any) -> None:
        """A job that failed before its run (its config, its directory): failed, and recorded."""
        ret = job.ret
        ret.return_value, ret.status = job.error, JobStatus.FAILED
        if ret.overrides is None:
            ret.overrides = list(OmegaConf.select(job.config, "hydra.overrides.task", default=[]) or [])
        with contextlib.suppress(Exception):
            hc = job.config.hydra
            sweep = directory.Sweep(Path(str(hc.sweep.dir)), job.idx, tuple(ret.overrides), str(hc.sweep.subdir))
            directory.record(sweep, "failed", f"{type(job.error).__name__}: {str(job.error).splitlines()[0] if str(job.error) else ''}")
