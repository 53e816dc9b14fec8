"""Jobs of a sweep run together: each keeps what Hydra's ``run_job`` gives it, and their runs
go through one call of :func:`zrp_ga.run.sweep.sweep_batch`, which evolves them together.

For each job, as ``run_job`` does it: its output directory, the three ``.hydra`` records
(``config.yaml``, ``hydra.yaml``, ``overrides.yaml``: the same text Hydra writes), Hydra's view
of the job (``HydraConfig``, its ``env_set``, its working directory with ``hydra.job.chdir``)
and its log file (``hydra.job_logging``) while anything is done for it alone, the callbacks'
``on_job_start`` and ``on_job_end`` (zrp_ga's manifest, any of the user's), and a ``JobReturn``
with its status and return value. The task's own part is that of ``zrp_ga.cli.main.main`` for a job
of a sweep: the run, then the one line saying how it ended.

Logging is configured once for the batch, as Hydra configures it for its first job; the
handlers whose settings differ from job to job (the log file, named after the job's
directory) are one per job, attached while that job's work runs (``around`` of
``sweep_batch``) and open only while it writes.

What a job costs besides its run is kept small: its config is read once as a container
(``OmegaConf.to_container``), the plain interpolations of its directory and log file's name
are resolved from that container (not through OmegaConf's parser), the records' texts from kept
texts, and the garbage collector is kept off the objects from before the batch (``python
tests/launcher_overhead.py``).

Callable in any process that got the pickled configs and ``hydra_context`` (a worker of this
launcher, or a cluster's job): :func:`run_batch`. A task function other than ``zrp_ga.cli.main.main``
runs its jobs one at a time through Hydra's ``run_job``. Hydra's and OmegaConf's public
interfaces only (tests/test_packaging.py).
"""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import re
from collections.abc import Iterator
from enum import Enum
from pathlib import Path
from typing import Any

import yaml
from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import JobReturn, JobRuntime, JobStatus, configure_log, env_override, run_job, setup_globals
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, ListConfig, OmegaConf, open_dict, read_write

log = logging.getLogger(__name__)


def run_batch(jobs: list[tuple[int, DictConfig | bytes]], hydra_context: HydraContext, task_function: TaskFunction) -> list[JobReturn]:
    """Run the sweep's jobs ``(job number, composed config or its pickle)``, their runs together; a
    ``JobReturn`` per job, in order, as Hydra's ``run_job`` makes it. Raises KeyboardInterrupt
    (at Ctrl-C) once every job recorded its state."""
    setup_globals()  # Hydra's resolvers (a fresh process)
    if not is_zrp_ga(task_function):
        return [run_alone(idx, pickle.loads(cfg) if isinstance(cfg, bytes) else cfg, hydra_context, task_function) for idx, cfg in jobs]
    from zrp_ga.run.shared import few_collections

    # the objects from before the batch frozen: each full collection went over all of them, about
    # half the batch's own CPU besides its runs
    with few_collections(freeze_older=True):
        return _Batch(jobs, hydra_context, task_function).run()


def run_alone(idx: int, config: DictConfig, hydra_context: HydraContext, task_function: TaskFunction) -> JobReturn:
    """One job with Hydra's ``run_job``, as Hydra's basic launcher runs it."""
    _number(config, idx)
    return run_job(hydra_context=hydra_context, task_function=task_function, config=config,
                   job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir")  # fmt: skip


def is_zrp_ga(task_function: Any) -> bool:
    """Whether ``task_function`` is ``zrp_ga.cli.main.main`` (or the function it wraps), whose jobs
    :func:`run_batch` runs together."""
    fn = getattr(task_function, "__wrapped__", task_function)
    return (getattr(fn, "__module__", None), getattr(fn, "__qualname__", None)) == ("zrp_ga.cli.main", "main")


def _number(config: DictConfig, idx: int) -> None:
    with open_dict(config):
        config.hydra.job.id = str(idx)  # a string field
        config.hydra.job.num = idx


def _numbered(config: DictConfig, idx: int) -> DictConfig:
    _number(config, idx)
    return config


# --- the .hydra records --------------------------------------------------------------------------------
def _omegaconfs_base_dumper() -> type:
    """The PyYAML dumper ``OmegaConf.to_yaml`` writes with: libyaml's (``yaml.CDumper``) from
    OmegaConf 2.4 on where PyYAML has it, the Python one before. The two break a long
    double-quoted string at different places (one escapes the break, the other does not); the
    one whose text of such a string is OmegaConf's is taken."""
    probe = {"text": "a long text " * 20 + "\n with lines\n"}  # double-quoted, folded at spaces
    text = OmegaConf.to_yaml(probe)
    for base in (getattr(yaml, "CDumper", None), yaml.Dumper):
        if base is not None and yaml.dump(probe, Dumper=base, default_flow_style=False, allow_unicode=True, sort_keys=False) == text:
            return base
    return yaml.Dumper


class _Dumper(_omegaconfs_base_dumper()):  # type: ignore[misc]  # a base found at run time
    """OmegaConf's YAML dumper (``OmegaConf.to_yaml``): strings that would read back as
    another type quoted."""


YAML_BOOLS = frozenset(["y", "Y", "yes", "Yes", "YES", "n", "N", "no", "No", "NO", "true", "True", "TRUE", "false", "False", "FALSE", "on", "On", "ON", "off", "Off", "OFF"])


def _str_representer(dumper: Any, data: str) -> Any:
    """A string as OmegaConf's dumper writes it: quoted when it would read back as a bool
    (YAML 1.1's), an int or a float."""
    quoted = data in YAML_BOOLS or _reads_as(int, data) or _reads_as(float, data)
    return dumper.represent_scalar(yaml.resolver.BaseResolver.DEFAULT_SCALAR_TAG, data, style=("'" if quoted else None))


def _reads_as(kind: type, data: str) -> bool:
    try:
        kind(data)
        return True
    except ValueError:
        return False


_Dumper.add_representer(str, _str_representer)
_TEXTS: dict[tuple, str] = {}  # (parent keys, key, repr of the value) -> its YAML lines
_TEXTS_MAX = 4096


def to_yaml(container: Any) -> str:
    """``OmegaConf.to_yaml(cfg)`` of the container ``OmegaConf.to_container(cfg, enum_to_str=True)``,
    the same text, made faster. In block style a mapping's text is its entries' texts one after
    another, a sequence's its items' texts, and the text of an entry depends only on the keys
    above it and its value (of an item, on the keys above its sequence and the item): each
    entry's text is kept and reused by the next jobs (the jobs of a sweep differ in a few
    values), and the entries of a mapping not seen before are written one by one, the same way.
    A number or a name (a path, a run's ``override_dirname``) is written as PyYAML writes it."""
    if isinstance(container, list) and container:
        return "".join(_item((), None, v) for v in container)
    if not isinstance(container, dict) or not container:
        return _dump(container)
    return "".join(_entry((), k, v) for k, v in container.items())


def _nested(parents: tuple, key: Any, value: Any) -> Any:
    nested: Any = value if key is None else {key: value}
    for p in reversed(parents):
        nested = {p: nested}
    return nested


def _item(parents: tuple, key: Any, value: Any) -> str:
    """The YAML lines of the item ``value`` of the sequence ``key`` inside the mappings
    ``parents`` (``key`` None: the sequence is the document)."""
    cache_key = (parents, key, "- ", repr(value))
    text = _TEXTS.get(cache_key)
    if text is None:
        text = _dump(_nested(parents, key, [value])).split("\n", len(parents) + (key is not None))[-1]
        _keep(cache_key, text)
    return text


def _entry(parents: tuple, key: Any, value: Any) -> str:
    """The YAML lines of ``key: value`` inside the mappings ``parents`` (whose own lines are cut)."""
    cache_key = (parents, key, repr(value))
    text = _TEXTS.get(cache_key)
    if text is None:
        head = ""
        if ((isinstance(value, (dict, list)) and value) or type(value) is int or _plain(value)) and isinstance(key, str):
            head = _entry(parents, key, {})  # "<indent>key: {}", on one line unless the key is long
            assert head.endswith(" {}\n"), head
            head = head[: -len(" {}\n")]
        if head and "\n" not in head:
            if isinstance(value, dict):
                text = head + "\n" + "".join(_entry((*parents, key), k, v) for k, v in value.items())
            elif isinstance(value, list):
                text = head + "\n" + "".join(_item(parents, key, v) for v in value)
            else:
                text = f"{head} {value}\n"
        else:
            text = _dump(_nested(parents, key, value)).split("\n", len(parents))[-1]
        _keep(cache_key, text)
    return text


_PLAIN = re.compile(r"[A-Za-z_/][A-Za-z0-9_./=,+-]*")


def _plain(value: Any) -> bool:
    """Whether PyYAML writes the string ``value`` as it is (plain, on one line whatever its
    length): letters, digits and a few signs that start nothing in YAML, read back as a string."""
    return (type(value) is str and _PLAIN.fullmatch(value) is not None and value not in YAML_BOOLS
            and value not in ("null", "Null", "NULL") and not _reads_as(float, value))  # fmt: skip


def _keep(cache_key: tuple, text: str) -> None:
    if len(_TEXTS) >= _TEXTS_MAX:
        _TEXTS.clear()
    _TEXTS[cache_key] = text


def _dump(container: Any) -> str:
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
                with contextlib.suppress(OSError):  # a full disk: the lines lost, the run's own error says where
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


def _interpolations(raw: Any, path: tuple = ()) -> Iterator[tuple]:
    """The paths of the interpolations in the container ``raw`` (unresolved)."""
    if isinstance(raw, dict):
        for k, v in raw.items():
            yield from _interpolations(v, (*path, k))
    elif isinstance(raw, list):
        for i, v in enumerate(raw):
            yield from _interpolations(v, (*path, i))
    elif isinstance(raw, str) and "${" in raw:
        yield path


def _resolve(node: DictConfig, like: dict, paths: list[tuple], raw: dict, whole: dict) -> dict:
    """``OmegaConf.to_container(node, resolve=True)`` of a ``node`` of a config whose text
    (unresolved) is ``raw`` (the config's own: ``whole``), that of the resolved ``like``'s node,
    whose interpolations are at ``paths`` and whose values are untyped (``hydra.job_logging``):
    ``like`` with those resolved in ``node``."""
    out = _copy(like)
    for path in paths:
        text = raw
        for k in path:
            text = text[k]
        value = _interpolated(text, whole)
        if value is _UNKNOWN:
            value = node
            for k in path:
                value = value[k]
            if isinstance(value, (DictConfig, ListConfig)):
                value = OmegaConf.to_container(value, resolve=True)
        target = out
        for k in path[:-1]:
            target = target[k]
        target[path[-1]] = value
    return out


_UNKNOWN = object()
_NODE_INTERPOLATION = re.compile(r"\$\{([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\}")


def _interpolated(text: Any, whole: dict) -> Any:
    """The value of the string ``text`` as OmegaConf resolves it in an untyped node (``Any``) of
    a config whose unresolved container (``OmegaConf.to_container(cfg, resolve=False)``) is
    ``whole``, when all its interpolations name values of the config by their keys
    (``${hydra.job.num}``, ``${hydra.runtime.output_dir}/${hydra.job.name}.log``) that are
    numbers or strings without interpolations: from those values (OmegaConf parses each such
    string, ~0.3 ms); else ``_UNKNOWN``. In a string node (``str``) the value is ``str()`` of it."""
    if not isinstance(text, str):
        return _UNKNOWN
    parts = _NODE_INTERPOLATION.split(text)
    if len(parts) == 1 or any(c in t for t in parts[0::2] for c in "${}\\'\""):
        return _UNKNOWN  # no interpolation, or one of another kind
    values = []
    for key in parts[1::2]:
        value: Any = whole
        for k in key.split("."):
            if not isinstance(value, dict) or k not in value:
                return _UNKNOWN  # no such key (or inside an interpolation): OmegaConf says what it is
            value = value[k]
        if type(value) not in (str, int, float, bool) or (isinstance(value, str) and ("${" in value or value == "???")):
            return _UNKNOWN
        values.append(value)
    if parts[0::2] == ["", ""]:  # the value itself
        return values[0]
    out = [parts[0]]
    for value, after in zip(values, parts[2::2]):
        out += [str(value), after]
    return "".join(out)


def _copy(container: Any) -> Any:
    """A copy of a container (``copy.deepcopy`` of its dicts and lists; their leaves are immutable)."""
    if isinstance(container, dict):
        return {k: _copy(v) for k, v in container.items()}
    if isinstance(container, list):
        return [_copy(v) for v in container]
    return container


def _sweep_job_args(job: _Job) -> tuple[Path, Any, dict]:
    """A job of a sweep as the run layer takes it (``zrp_ga.run.sweep.SweepJob``: its directory, its
    place in the sweep, the groups' options), from Hydra's config of the job, as
    ``zrp_ga.cli.main.main`` makes them (not imported from there: the command line imports this
    launcher): from the values its ``prepare`` read, resolved where they have interpolations."""
    from zrp_ga.run.directory import Sweep

    hydra = job.hydra
    task = _resolved(job.config, hydra["overrides"]["task"], "hydra.overrides.task")
    choices = _resolved(job.config, hydra["runtime"]["choices"], "hydra.runtime.choices")
    sweep = Sweep(Path(job.sweep_dir), job.idx, tuple(task), job.subdir)
    return Path(hydra["runtime"]["output_dir"]), sweep, dict(choices)


def _names(container: Any) -> Any:
    """``container`` (``OmegaConf.to_container(cfg)``) with its enums, keys and values, as their
    names: ``OmegaConf.to_container(cfg, enum_to_str=True)`` without reading the config again."""
    if isinstance(container, dict):
        return {(k.name if isinstance(k, Enum) else k): _names(v) for k, v in container.items()}
    if isinstance(container, list):
        return [_names(v) for v in container]
    return container.name if isinstance(container, Enum) else container


def _resolved(config: DictConfig, raw: Any, path: str) -> Any:
    """The value at ``path`` in ``config`` as Hydra's view of the job resolves it, whose
    unresolved container is ``raw``: ``raw`` itself when it has no interpolation."""
    if next(_interpolations(raw), None) is None and not (isinstance(raw, str) and raw == "???"):
        return raw
    instance = HydraConfig.instance()
    before, instance.cfg = instance.cfg, config  # type: ignore[assignment]  # Hydra's view of a job is a DictConfig: HydraConfig.set_config stores one too (its cfg is annotated HydraConf)
    try:
        value = OmegaConf.select(config, path)
        return OmegaConf.to_container(value, resolve=True) if isinstance(value, (DictConfig, ListConfig)) else value
    finally:
        instance.cfg = before


def _container(node: DictConfig) -> dict[Any, Any]:
    """``OmegaConf.to_container(node, resolve=True)`` of a dict node (``hydra.job_logging``)."""
    value = OmegaConf.to_container(node, resolve=True)
    assert isinstance(value, dict)  # a DictConfig's container is a dict
    return value


def _without_hydra(config: DictConfig, data: bytes | None = None) -> DictConfig:
    """A copy of ``config`` without its ``hydra`` node, as Hydra's ``run_job`` makes the task's
    config (a deep copy, ``hydra`` deleted): a copy (pickled and unpickled, faster than
    ``copy.deepcopy``; or unpickled from ``data``, ``config`` as it was sent, when only its
    ``hydra`` node changed since), ``hydra`` deleted."""
    task_cfg: DictConfig = pickle.loads(pickle.dumps(config) if data is None else data)
    with read_write(task_cfg), open_dict(task_cfg):
        del task_cfg["hydra"]
    return task_cfg


OWN_CALLBACKS = frozenset(["zrp_ga.cli.callbacks.Prepare", "zrp_ga.cli.callbacks.Manifest"])  # they read no job's return's cfg


def _task_config_read(hydra: dict, task: dict) -> bool:
    """Whether a job's task config (``JobReturn.cfg``) must be made: the job's callbacks
    (``hydra``: its hydra node as a container) are not all zrp_ga's own, or an interpolation of
    the task's part (``task``, a container) names ``hydra`` (the task's config, without that
    node, would not resolve it as the whole config does)."""
    callbacks = hydra.get("callbacks") or {}
    if not all(isinstance(c, dict) and c.get("_target_") in OWN_CALLBACKS for c in callbacks.values()):
        return True
    for path in _interpolations(task):
        value: Any = task
        for k in path:
            value = value[k]
        if "hydra" in value:
            return True
    return False


# --- the batch -----------------------------------------------------------------------------------------
class _Job:
    """One job of the batch: its configs, its directory, its log files and its return."""

    def __init__(self, idx: int, config: DictConfig | bytes):
        # its config pickled, as sent (as given: prepare() changes the config's hydra node)
        self.data = config if isinstance(config, bytes) else pickle.dumps(config)
        self.idx, self.config = idx, pickle.loads(config) if isinstance(config, bytes) else config
        self.typed: Any = None  # the task's config, typed (zrp_ga.config.typed)
        self.ret = JobReturn()
        self.out = Path()
        self.logs: list[_JobLog] = []
        self.error: Exception | None = None
        self.chdir = False
        self.env: dict[str, str] = {}  # hydra.job.env_set, resolved
        self.raw: dict = {}  # its config as a container (unresolved, enums as they are)
        self.hydra: dict = {}  # its hydra node, as a container (unresolved, enums as names)
        self.sweep_dir, self.subdir = "", ""  # hydra.sweep's, resolved

    def prepare(self) -> None:
        """As ``run_job`` before the task: the config numbered, its output directory, the
        task's config, the directory made and the ``.hydra`` records written. Hydra's view of
        the job (``HydraConfig``) is its config itself, whose ``hydra`` node is then read-only
        (as ``HydraConfig.set_config`` leaves it)."""
        config = self.config
        _number(config, self.idx)
        self.raw = OmegaConf.to_container(config, resolve=False)  # type: ignore[assignment]  # enums as they are
        whole = _names(self.raw)  # as the records have them
        self.hydra = hydra = whole.pop("hydra")  # its hydra node, unresolved; the rest is the task's
        self.sweep_dir, self.subdir = (self._text(hydra["sweep"][key], f"hydra.sweep.{key}") for key in ("dir", "subdir"))
        output_dir = os.path.join(self.sweep_dir, self.subdir)
        with read_write(config.hydra.runtime), open_dict(config.hydra.runtime):
            config.hydra.runtime.output_dir = hydra["runtime"]["output_dir"] = self.raw["hydra"]["runtime"]["output_dir"] = (
                os.path.abspath(output_dir))
        OmegaConf.set_readonly(config.hydra, True)
        self.out = Path(output_dir)
        # the task's config, a copy without the hydra node, as run_job makes it, when something
        # could read it other than zrp_ga.config.typed (which leaves the hydra node out itself): a
        # callback other than zrp_ga's own (the job's return holds it), an interpolation naming hydra
        task_cfg = _without_hydra(config, self.data) if _task_config_read(hydra, whole) else None
        # Hydra's view of the job (HydraConfig's config): the config itself, rather than a copy of its hydra node
        self.ret.cfg, self.ret.hydra_cfg = task_cfg, config
        self.ret.overrides = list(hydra["overrides"]["task"])
        self.out.mkdir(parents=True, exist_ok=True)
        self.chdir = bool(hydra["job"]["chdir"])
        self.ret.working_dir = output_dir if self.chdir else os.getcwd()
        self.env = dict(_resolved(config, hydra["job"]["env_set"], "hydra.job.env_set"))
        if hydra["output_subdir"] is not None:
            records = Path(hydra["runtime"]["output_dir"]) / self._text(hydra["output_subdir"], "hydra.output_subdir")
            records.mkdir(parents=True, exist_ok=True)
            _save(to_yaml(whole), records / "config.yaml")
            _save(to_yaml({"hydra": hydra}), records / "hydra.yaml")
            _save(to_yaml(hydra["overrides"]["task"]), records / "overrides.yaml")

    def _text(self, raw: Any, path: str) -> str:
        """The string of the value at ``path`` (unresolved: ``raw``), resolved."""
        value = _interpolated(raw, self.raw)
        return str(value if value is not _UNKNOWN else _resolved(self.config, raw, path))

    @contextlib.contextmanager
    def around(self) -> Iterator[None]:
        """Hydra's view of this job and its log file, while something is done for it alone."""
        instance = HydraConfig.instance()
        before, instance.cfg = instance.cfg, self.config  # type: ignore[assignment]  # Hydra's view of a job is a DictConfig: HydraConfig.set_config stores one too (its cfg is annotated HydraConf)
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
    def __init__(self, jobs: list[tuple[int, DictConfig | bytes]], hydra_context: HydraContext, task_function: TaskFunction):
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
            ready = self.keyed([j for j in self.jobs if j.error is None])
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

    def keyed(self, ready: list[_Job]) -> list[_Job]:
        """The jobs whose runs can be evolved together (a ``batch_key``), their configs typed; the
        others (a config that is not valid, a run that goes alone: zrp_ga's launcher sends a
        group of jobs whose keys it did not compute) run here one by one with Hydra's
        ``run_job``, as the launcher sends a job without a key, their configs as sent."""
        from zrp_ga.config import typed
        from zrp_ga.run.sweep import batch_key

        out = []
        for job in ready:
            key = None
            with contextlib.suppress(Exception), job.around():
                job.typed = typed(job.config if job.ret.cfg is None else job.ret.cfg)  # the hydra node left out
                key = batch_key(job.typed)
            if key is not None:
                out.append(job)
            else:
                job.ret = run_alone(job.idx, pickle.loads(job.data), self.hydra_context, self.task_function)
        return out

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
        confs: list[dict[Any, Any]] = []
        with first.around():
            confs.append(_container(first.config.hydra.job_logging))
        raw = first.hydra["job_logging"]
        paths = list(_interpolations(raw))
        for job in ready[1:]:
            with job.around():
                confs.append(_resolve(job.config.hydra.job_logging, confs[0], paths, raw, job.raw) if job.hydra["job_logging"] == raw
                             else _container(job.config.hydra.job_logging))  # fmt: skip
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
        """The runs, together (``zrp_ga.cli.main.main``'s part, but the console line)."""
        from zrp_ga.run.sweep import SweepJob, sweep_batch

        tasks = []
        for job in ready:
            with job.around():
                tasks.append(SweepJob(job.typed, *_sweep_job_args(job)))
        return sweep_batch(tasks, around=lambda k: ready[k].around()) if tasks else []

    def end(self, job: _Job, value: Any) -> None:
        """As ``run_job`` after the task: the console line, the status, the callbacks."""
        from zrp_ga.run import summary

        ret = job.ret
        if isinstance(value, Exception):
            ret.return_value, ret.status = value, JobStatus.FAILED
        else:
            try:
                assert ret.overrides is not None  # set by prepare(), as the job ran
                summary.console(job.out, (job.idx, " ".join(ret.overrides)))  # hydra.job.num
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
