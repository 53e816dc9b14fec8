"""zrp_ga's launcher beyond this machine: a sweep's jobs in batches, each batch one cluster job.

``hydra.launcher.executor=slurm`` submits the batches as one SLURM job array through submitit's
public API (``AutoExecutor``, ``map_array``), ``executor=ray`` as Ray tasks (``ray.remote``).
The driver composes every job's config (with ``_compose``'s cache), puts the jobs of one
``zrp_ga.run.sweep.batch_key`` side by side (those with none, such as LM and CMA-ES, too: they
run one after another), and cuts them into ``ceil(jobs / runs_per_job)`` batches of nearly equal
size. A cluster job sets itself up as a spawned worker of ``_workers`` does (Hydra's singletons,
the task function), runs its batch with ``_batch.run_batch`` (Hydra's ``run_job`` for each job:
its directory, ``.hydra`` record, log file and manifest line, as with the local launcher) and
sends the returns back, without their configs, as ``_workers`` does.

A cluster job that fails (killed, out of time or memory, its node lost) fails the runs of its
batch that had not finished, each with a ``failed`` line in the manifest; those it finished
keep their ``done`` line and return their objective. A sweep run again into the same ``hydra.sweep.dir`` continues: the run
layer keeps the finished runs and resumes the checkpointed ones. At Ctrl-C the cluster jobs not
ended are cancelled (SLURM sends them SIGTERM, Ray a KeyboardInterrupt: the runs save their
checkpoints); a SLURM job near its time limit (submitit's SIGUSR2) or cancelled stops the same way.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
import pickle
import signal
import zlib
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, Protocol

from hydra.core.hydra_config import HydraConfig
from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, configure_log, filter_overrides, setup_globals
from hydra.types import HydraContext
from omegaconf import DictConfig, open_dict

from . import _workers

log = logging.getLogger(__name__)


def batches(keys: Sequence[Any], runs_per_job: int) -> list[list[int]]:
    """The positions of jobs with these batch keys in ``ceil(len(keys) / runs_per_job)`` batches
    of nearly equal size, the jobs of one key side by side (keys in the order they first come)."""
    first: dict[Any, int] = {}
    for key in keys:
        first.setdefault(key, len(first))
    ranked = sorted(range(len(keys)), key=lambda i: first[keys[i]])  # stable: job order within a key
    n = math.ceil(len(keys) / runs_per_job)
    size, extra = divmod(len(keys), n) if n else (0, 0)
    out, at = [], 0
    for b in range(n):
        end = at + size + (b < extra)
        out.append(ranked[at:end])
        at = end
    return out


# --- in a cluster job ---------------------------------------------------------------------------------
@dataclasses.dataclass
class _Start:
    """What a cluster job needs besides its batch (pickled)."""

    hydra_context: HydraContext  # without its config loader (the jobs come composed)
    task_function: Any  # the function, or (module, qualified name) when it cannot be pickled
    singleton_state: Any  # Hydra's singletons, as _workers passes them to spawned workers
    stop_at_sigterm: bool = False  # SIGTERM, SIGUSR2 (scancel, the time limit near) as Ctrl-C: the run saves its checkpoint


def run_remote(start: _Start, jobs: list[tuple[int, bytes]]) -> list[bytes]:
    """A cluster job: run ``jobs`` ((job number, pickled config compressed with zlib) pairs); their pickled returns."""
    from . import _batch

    if start.stop_at_sigterm:  # in place of submitit's handlers, which would let the batch's next runs start
        for sig in (signal.SIGTERM, signal.SIGUSR2):
            signal.signal(sig, _interrupt)
    state = Singleton.get_state()
    state["instances"] = start.singleton_state
    Singleton.set_state(state)
    setup_globals()
    task_function = _workers._task_function(start.task_function)
    returns = _batch.run_batch([(idx, zlib.decompress(data)) for idx, data in jobs], start.hydra_context, task_function)
    return [_workers._dump_return(idx, ret) for (idx, _), ret in zip(jobs, returns)]


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


# --- the executors --------------------------------------------------------------------------------------
class _Slurm:
    """The batches as one SLURM job array (submitit; ``cluster=local`` or ``debug`` on this machine)."""

    def __init__(self, settings: Any):
        import submitit

        self.helpers = submitit.helpers
        self.executor = submitit.AutoExecutor(folder=settings.submitit_folder, cluster=settings.cluster)
        params = dict(name="zrp_ga", timeout_min=settings.timeout_min, cpus_per_task=settings.cpus_per_task,
                      mem_gb=settings.mem_gb, slurm_array_parallelism=settings.array_parallelism)  # fmt: skip
        if settings.partition:
            params["slurm_partition"] = settings.partition
        if settings.account:
            params["slurm_account"] = settings.account
        self.executor.update_parameters(**params)
        self.jobs: list[Any] = []

    def submit(self, start: _Start, payload: list[list[tuple[int, bytes]]]) -> None:
        start = dataclasses.replace(start, stop_at_sigterm=self.executor.cluster != "debug")  # debug: in this process
        self.jobs = self.executor.map_array(run_remote, [start] * len(payload), payload)
        log.info(f"submitted {len(self.jobs)} cluster jobs ({self.executor.cluster}): {', '.join(j.job_id for j in self.jobs[:3])}"
                 f"{', ...' if len(self.jobs) > 3 else ''}")  # fmt: skip

    def results(self) -> Iterator[tuple[int, Any]]:
        where = {id(job): k for k, job in enumerate(self.jobs)}
        for job in self.helpers.as_completed(self.jobs, poll_frequency=1.0):
            k = where[id(job)]
            try:
                yield k, job.result()
            except Exception as exc:
                yield k, ChildProcessError(f"cluster job {job.job_id} failed ({job.paths.stderr}): {_last_line(exc)}")  # one line on the console

    def cancel(self) -> None:
        for job in self.jobs:
            if not job.done():
                try:
                    job.cancel(check=False)
                except Exception as exc:  # the scheduler cannot be reached: say so, go on
                    log.warning(f"cluster job {job.job_id} could not be cancelled: {exc}")

    def close(self) -> None:
        pass


class _Ray:
    """The batches as Ray tasks, on a running cluster (``ray_address``) or a Ray started here."""

    def __init__(self, settings: Any):
        import ray

        self.ray = ray
        self.started = not ray.is_initialized()
        if self.started:
            local = settings.ray_address is None
            ray.init(address=settings.ray_address, num_cpus=settings.ray_num_cpus if local else None)
        self.remote = ray.remote(num_cpus=settings.cpus_per_task, max_retries=0)(run_remote)
        self.refs: list[Any] = []

    def submit(self, start: _Start, payload: list[list[tuple[int, bytes]]]) -> None:
        start_ref = self.ray.put(start)
        self.refs = [self.remote.remote(start_ref, jobs) for jobs in payload]
        log.info(f"submitted {len(self.refs)} Ray tasks")

    def results(self) -> Iterator[tuple[int, Any]]:
        where = {ref: k for k, ref in enumerate(self.refs)}
        pending = list(self.refs)
        while pending:
            ended, pending = self.ray.wait(pending, num_returns=1)
            for ref in ended:
                try:
                    yield where[ref], self.ray.get(ref)
                except Exception as exc:
                    yield where[ref], ChildProcessError(f"Ray task {where[ref]} failed: {_last_line(exc)}")

    def cancel(self) -> None:
        for ref in self.refs:
            try:
                self.ray.cancel(ref)
            except Exception:  # it ended in between
                pass

    def close(self) -> None:
        if self.started:
            self.ray.shutdown()


class _Executor(Protocol):
    """What :func:`launch` asks of an executor (:class:`_Slurm`, :class:`_Ray`)."""

    def submit(self, start: _Start, payload: list[list[tuple[int, bytes]]]) -> None: ...
    def results(self) -> Iterator[tuple[int, Any]]: ...  # (batch number, its pickled returns or the error)
    def cancel(self) -> None: ...
    def close(self) -> None: ...


EXECUTORS: dict[str, Callable[[Any], _Executor]] = {"slurm": _Slurm, "ray": _Ray}


def _last_line(exc: BaseException) -> str:
    """The last line of an error that carries the cluster job's traceback: its exception."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip() and set(line.strip()) != {"-"}]
    return lines[-1] if lines else type(exc).__name__


# --- the driver ---------------------------------------------------------------------------------------
def _batch_key(cfg: Any) -> Any:
    """The job's batch key (None: it runs alone; so does a job whose config fails here: it fails in its run)."""
    from zrp_ga.config import typed
    from zrp_ga.run.sweep import batch_key

    try:
        return batch_key(typed(cfg))
    except Exception:
        return None


def launch(launcher: Any, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> list[JobReturn]:
    """Run the jobs in batches, a cluster job each (see the module docstring); their returns in job order."""
    setup_globals()
    configure_log(launcher.config.hydra.hydra_logging, launcher.config.hydra.verbose)
    HydraConfig.instance().set_config(copy.deepcopy(launcher.config))  # the sweep's: at Ctrl-C the console script names it
    settings = launcher.settings
    sweep = Path(str(launcher.config.hydra.sweep.dir))
    sweep.mkdir(parents=True, exist_ok=True)
    jobs = [(initial_job_idx + k, list(o)) for k, o in enumerate(job_overrides)]
    keys, data, places = [], [], []
    for idx, overrides in jobs:
        log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
        cfg = launcher.hydra_context.config_loader.load_sweep_config(launcher.config, overrides)
        keys.append(_batch_key(cfg))
        places.append(_place(idx, cfg))
        data.append(zlib.compress(pickle.dumps(cfg)))  # about 5 kB a job rather than 22 kB: 10,000 jobs in 50 MB
    groups = batches(keys, settings.runs_per_job)
    payload = [[(jobs[i][0], data[i]) for i in group] for group in groups]
    del data
    context = HydraContext(config_loader=None, callbacks=launcher.hydra_context.callbacks)  # type: ignore[arg-type]  # no config loader to send: the jobs come composed
    start = _Start(context, _workers._portable(launcher.task_function), Singleton.get_state()["instances"])
    executor = EXECUTORS[_name(settings.executor)](settings)
    log.info(f"Launching {len(jobs)} jobs in {len(groups)} cluster jobs, sweep output dir : {sweep}")
    returns: dict[int, JobReturn] = {}
    try:
        executor.submit(start, payload)
        for k, result in executor.results():
            if isinstance(result, BaseException):
                _fail(sweep, [(*jobs[i], places[i]) for i in groups[k]], result, returns)
            else:
                for data in result:
                    idx, returns[idx] = pickle.loads(data)
            failed = sum(r.status == JobStatus.FAILED for r in returns.values())
            log.info(f"cluster job {k + 1} of {len(groups)} ended: {len(returns)} of {len(jobs)} jobs ended, {failed} failed")
            _write_table(sweep)
    except KeyboardInterrupt:
        executor.cancel()
        _write_table(sweep)
        raise
    finally:
        executor.close()
    return [returns[idx] for idx, _ in jobs]


def _name(executor: Any) -> str:
    return str(getattr(executor, "value", executor))


def _place(idx: int, cfg: DictConfig) -> Any:
    """The job's place in the sweep (``zrp_ga.run.directory.Sweep``), its number set in ``cfg`` as ``run_job`` sets it."""
    from zrp_ga.run import directory

    with open_dict(cfg):
        cfg.hydra.job.id, cfg.hydra.job.num = str(idx), idx
    hc = cfg.hydra
    return directory.Sweep(Path(hc.sweep.dir), idx, tuple(hc.overrides.task), str(hc.sweep.subdir))


def _fail(sweep: Path, jobs: list[tuple[int, list[str], Any]], error: BaseException, returns: dict) -> None:
    """The runs of a failed cluster job (``(number, overrides, place)``): those it had finished
    completed with the objective in their summary, as the run layer returns a kept run's; the
    others failed, with a ``failed`` manifest line."""
    from zrp_ga.run import directory

    log.error(str(error))
    states = {int(r["job"]): r["status"] for r in directory.job_states(sweep)} if (sweep / directory.MANIFEST).exists() else {}
    for idx, overrides, place in jobs:
        ret = returns[idx] = JobReturn(overrides=overrides, status=JobStatus.FAILED)
        ret.return_value = error
        out = place.dir / place.subdir
        if states.get(idx) == "done" and directory.status(out) == "done":
            try:
                written = directory.read_summary(out)
                value = written.get("objective", written.get("final_cost"))
                ret.status, ret.return_value = JobStatus.COMPLETED, float("nan") if value is None else float(value)
                continue
            except (OSError, ValueError, TypeError):
                pass
        directory.fail_lost(out, f"{type(error).__name__}: {error}")  # its status file as the manifest says
        directory.record(place, "failed", f"{type(error).__name__}: {error}")


def _write_table(sweep: Path) -> None:
    from zrp_ga.run import directory

    directory.write_table(sweep)
