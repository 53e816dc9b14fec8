"""The worker processes of zrp_ga's launcher and the loop that hands them jobs.

Each worker is started once per sweep and warmed up once: where processes are forked (Linux),
the sweep's process calls the warm-up function with the sweep's config (the app's modules, its
compiled code, the first problem instance) and the workers are forked from it, sharing all
that; elsewhere each spawned worker warms itself up while the sweeper checks the jobs. A
worker runs the batches it is sent, one after another. Jobs that can be evolved together (the
same ``zrp_ga.run.sweep.batch_key``: GA runs on one problem instance with one population
shape) come as one batch, run by :func:`._batch.run_batch` with their runs in one call of the
run layer; other jobs (and all with ``hydra.launcher.lockstep=false``) one at a time through
Hydra's ``run_job``, as Hydra's own launchers run them. Each job's ``JobReturn`` goes back as
soon as it is known.

The driver (:func:`launch`) groups the jobs by batch key: a batch is ``batch_size`` jobs of one
key (enough for every worker to get a few; fewer when the key has no more, at the end, or when
too many wait composed), a job without a key goes alone. The keys are noted, and the configs
kept pickled, by the config loader as Hydra's sweeper checks the jobs (``_compose``), so that
the jobs of a key far apart in the sweep (a seed sweep of simulated instances: ``seed`` varies
fastest and each seed is an instance) are sent together, whole; without them (zrp_ga's sweeper,
which composes a few jobs, or another config loader) the driver groups the jobs by the values of
the swept keys that change the batch key (``_Dispatcher._by_overrides``: one composition per
swept key) and composes them in that order ahead while the workers run. A
worker holds one batch of jobs run together (two of other jobs: one running, one waiting).
The driver collects the returns in job order and rewrites the manifest table now and then. A
worker that dies (killed, out of memory) fails its unfinished jobs, which are recorded in the
manifest (but for runs of its batch that had ended), and another takes its place. At Ctrl-C
every process of the sweep gets the signal: each worker's jobs save their checkpoints and
record ``interrupted``, the driver waits for them (and signals any worker that did not get it)
before it raises ``KeyboardInterrupt`` to the console script. Workers die with the driver
(Linux: the kernel kills them; elsewhere they stop at their next batch), so that a sweep killed
and started again never has two processes writing one job's files.
"""

from __future__ import annotations

import atexit
import collections
import contextlib
import dataclasses
import io
import logging
import multiprocessing
import os
import pickle
import signal
import sys
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig
from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, configure_log, filter_overrides, setup_globals
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, open_dict

from . import _batch

log = logging.getLogger(__name__)
AHEAD = 2  # batches a worker holds: one running, one waiting
MIN_BATCH, MAX_BATCH, ROUNDS = 8, 256, 3  # jobs run together (batch_size)
PATIENCE_S = (2.0, 15.0)  # at Ctrl-C: waiting for workers to stop on their own, then after signalling them


def batch_size(n_jobs: int, n_workers: int) -> int:
    """Jobs run together in one batch: enough for each worker to get ``ROUNDS`` batches of the
    sweep (so that the workers end together), at least ``MIN_BATCH``, at most ``MAX_BATCH``."""
    return max(MIN_BATCH, min(MAX_BATCH, -(-n_jobs // (n_workers * ROUNDS))))


def n_workers(n_jobs: int) -> int:
    """``n_jobs``, or with -1 the cores this process may run on."""
    if n_jobs > 0:
        return n_jobs
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, cores + 1 + n_jobs)  # joblib's convention: -1 all, -2 all but one


# --- in a worker ------------------------------------------------------------------------------------
@dataclasses.dataclass
class _Start:
    """What a worker needs (pickled for spawned workers)."""

    hydra_context: HydraContext
    task_function: Any  # the function, or (module, qualified name) when it cannot be pickled
    config: DictConfig
    warm_up: str | None
    parent: int
    singleton_state: Any = None  # Hydra's singletons, for spawned workers


def _serve(conn: Any, start: _Start) -> None:
    """A worker's life: set up, warm up, run the batches it is sent until told to stop."""
    _die_with(start.parent)
    if start.singleton_state is not None:
        # Hydra's singletons, as Hydra's joblib launcher passes them, but for OmegaConf's
        # resolvers (closures: not picklable without cloudpickle), which stay this process's own:
        # Hydra's are registered again by setup_globals, the app's when its module is imported
        # for the task function.
        state = Singleton.get_state()
        state["instances"] = start.singleton_state
        Singleton.set_state(state)
    setup_globals()
    task_function = _task_function(start.task_function)
    try:
        if start.warm_up:
            _warm_up(start.warm_up, start.config)
        while True:
            message = conn.recv()
            if message is None:
                return
            together, batch = message
            if together:  # their runs evolved together
                for (idx, _), ret in zip(batch, _batch.run_batch(batch, start.hydra_context, task_function)):
                    conn.send_bytes(_dump_return(idx, ret))
                continue
            for idx, data in batch:
                ret = _batch.run_alone(idx, pickle.loads(data), start.hydra_context, task_function)
                conn.send_bytes(_dump_return(idx, ret))
    except (EOFError, OSError):  # the driver is gone
        return
    except KeyboardInterrupt:  # the job saved its checkpoint and recorded it; no traceback
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        sys.exit(130)


def _warm_up(path: str, config: DictConfig) -> None:
    t0 = time.perf_counter()
    _locate(path)(config)
    log.debug(f"warm-up ({path}) in process {os.getpid()}: {time.perf_counter() - t0:.2f} s")


def _dump_return(idx: int, ret: JobReturn) -> bytes:
    """The job number and ``ret``, pickled, without the job's configs (``cfg``, ``hydra_cfg``:
    Hydra's sweepers read the status and the return value, and unpickling two configs per job
    cost the driver about half a core in an 864-job sweep); an exception that cannot be
    pickled goes as its text."""
    ret.cfg = ret.hydra_cfg = None
    try:
        return pickle.dumps((idx, ret))
    except Exception:
        error = _error(ret)
        ret.return_value = RuntimeError(f"{type(error).__name__}: {error}")
        return pickle.dumps((idx, ret))


def _error(ret: JobReturn) -> BaseException | None:
    """The exception of a failed job (``JobReturn.return_value`` raises it, and says so on
    stderr, which is silenced here: Hydra's sweeper says it again)."""
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            ret.return_value  # noqa: B018
    except BaseException as exc:
        return exc
    return None


def _die_with(parent: int) -> None:
    """Linux: have the kernel kill this process when the driver dies (``prctl`` has no Python
    binding; ``PR_SET_PDEATHSIG`` is 1). Elsewhere the worker stops at its next job, when its
    pipe to the driver closes."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:
        os._exit(1)


def _task_function(ref: Any) -> TaskFunction:
    if not isinstance(ref, tuple):
        return ref
    fn = _locate(".".join(ref))
    return getattr(fn, "__wrapped__", fn)  # @hydra.main's wrapper: the function it wraps


def _locate(path: str) -> Callable:
    from hydra.utils import get_method

    return get_method(path)


# --- the driver ---------------------------------------------------------------------------------------
@dataclasses.dataclass
class _Worker:
    process: Any
    conn: Any
    batches: collections.deque = dataclasses.field(default_factory=collections.deque)  # of [job idx]


class Pool:
    """The worker processes of one sweep (see the module docstring)."""

    def __init__(self, settings: Any, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig):
        method = settings.start_method or ("fork" if sys.platform.startswith("linux") else "spawn")
        self.context = multiprocessing.get_context(method)
        self.settings = settings
        spawned = method != "fork"
        if not spawned and settings.warm_up:  # once here, before the workers inherit it all
            _warm_up(settings.warm_up, config)
        context = HydraContext(config_loader=None, callbacks=hydra_context.callbacks) if spawned else hydra_context  # type: ignore[arg-type]  # no config loader to send: a spawned worker's jobs come composed
        self.start = _Start(
            context,
            _portable(task_function) if spawned else task_function,
            config, settings.warm_up if spawned else None, os.getpid(), Singleton.get_state()["instances"] if spawned else None,
        )  # fmt: skip
        self.workers = [self._spawn() for _ in range(n_workers(settings.n_jobs))]
        atexit.register(self.close)

    def _spawn(self) -> _Worker:
        here, there = self.context.Pipe()
        # every start method's context has Process; typeshed gives get_context(a str) their base class, which has not
        process = self.context.Process(target=_serve, args=(there, self.start), daemon=True, name="zrp_ga-worker")  # type: ignore[attr-defined]
        process.start()
        there.close()
        return _Worker(process, here)

    def replace(self, worker: _Worker) -> _Worker:
        worker.conn.close()
        new = self._spawn()
        self.workers[self.workers.index(worker)] = new
        return new

    def interrupt(self) -> None:
        """After Ctrl-C: let the workers finish saving; interrupt those that did not get the
        signal, and kill what still runs after that."""
        for patience, sig in zip(PATIENCE_S, (signal.SIGINT, getattr(signal, "SIGKILL", signal.SIGTERM))):  # Windows: no SIGKILL
            deadline = time.monotonic() + patience
            while any(w.process.is_alive() for w in self.workers) and time.monotonic() < deadline:
                time.sleep(0.02)
            for w in self.workers:
                if w.process.is_alive():
                    with contextlib.suppress(ProcessLookupError):  # it ended in between
                        os.kill(w.process.pid, sig)
        for w in self.workers:
            w.process.join(PATIENCE_S[0])

    def close(self) -> None:
        for w in self.workers:
            try:
                w.conn.send(None)
            except (OSError, ValueError):
                pass
        for w in self.workers:
            w.process.join(PATIENCE_S[1])
            if w.process.is_alive():
                w.process.kill()
        self.workers = []


def _portable(task_function: TaskFunction) -> Any:
    """The task function, or its module and name when it cannot be pickled (``@hydra.main``'s
    wrapper has taken its name)."""
    try:
        pickle.dumps(task_function)
        return task_function
    except Exception:
        return (task_function.__module__, task_function.__qualname__)


def launch(launcher: Any, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> list[JobReturn]:
    """Run the jobs on the launcher's workers; their returns in job order."""
    setup_globals()
    configure_log(launcher.config.hydra.hydra_logging, launcher.config.hydra.verbose)
    if not HydraConfig.initialized():  # Hydra's view of the sweep, in this process too (where Ctrl-C is reported)
        HydraConfig.instance().set_config(launcher.config)
    sweep = Path(str(launcher.config.hydra.sweep.dir))
    sweep.mkdir(parents=True, exist_ok=True)
    pool: Pool = launcher.pool
    log.info(f"Launching {len(job_overrides)} jobs on {len(pool.workers)} workers, sweep output dir : {sweep}")
    todo = collections.deque((initial_job_idx + k, list(o)) for k, o in enumerate(job_overrides))
    dispatcher = _Dispatcher(launcher, pool, todo, sweep)
    try:
        with dispatcher.progress.logging():
            returns = dispatcher.run()
    except KeyboardInterrupt:
        dispatcher.show_progress(close=True)
        pool.interrupt()
        dispatcher.write_table()
        raise
    dispatcher.show_progress(close=True)
    dispatcher.write_table()
    return [returns[initial_job_idx + k] for k in range(len(job_overrides))]


class _Dispatcher:
    """Hands out batches, collects returns, replaces dead workers (see the module docstring)."""

    def __init__(self, launcher: Any, pool: Pool, todo: collections.deque, sweep: Path):
        self.launcher, self.pool, self.todo, self.sweep = launcher, pool, todo, sweep
        self.overrides = dict(todo)
        self.returns: dict[int, JobReturn] = {}
        self.failed = 0  # of the returns
        self.table_at = time.monotonic()
        from ._progress import SweepProgress

        self.progress = SweepProgress(len(self.overrides), bool(launcher.config.get("progress", True)))
        self.together = bool(launcher.settings.lockstep) and _batch.is_zrp_ga(launcher.task_function)
        self.pending: dict[str, list] = {}  # batch key -> jobs composed, not sent yet
        self.alone: collections.deque = collections.deque()  # jobs without a key, composed, not sent yet
        self.waiting = 0  # jobs composed, not sent yet
        self.size = batch_size(len(todo), len(pool.workers))
        self.limit = self.size * len(pool.workers) * 2  # jobs composed ahead at most
        self.left: collections.Counter | None = None  # per batch key (or group), its jobs not composed yet (if known)
        self.noted: Callable[..., Any] | None = None  # the loader's notes of every job's key
        self.group: dict[int, Any] | None = None  # else per job, its group: the values of the overrides that change keys
        self.early: dict[tuple[str, ...], DictConfig] = {}  # configs composed to find the groups, by their overrides
        self.group_keys: dict[Any, bool] = {}  # per group, whether its first job composed has a batch key
        if self.together:
            noted = getattr(launcher.hydra_context.config_loader, "noted_for", None)
            if not (noted is not None and self._by_key(noted)):
                self._by_overrides()

    def _by_key(self, noted: Callable[..., Any]) -> bool:
        """Put the jobs of each batch key side by side (keys in the order they first come), from
        the keys the config loader noted when the sweeper checked the jobs (Hydra's sweeper
        composes every job): a sweep whose jobs of one key are far apart (seeds of simulated
        instances: ``seed`` varies fastest) then sends whole batches without composing the sweep
        ahead. False, nothing changed, when a job's key was not noted."""
        unknown = object()
        keys = [noted(self.launcher.config, overrides, unknown) for _, overrides in self.todo]
        if any(k is unknown for k in keys):
            return False
        groups: dict[Any, list] = {}
        for job, key in zip(self.todo, keys):
            groups.setdefault(("alone", job[0]) if key is None else key, []).append(job)
        self.todo = collections.deque(job for jobs in groups.values() for job in jobs)
        self.left = collections.Counter(keys)
        self.noted = noted
        return True

    def _by_overrides(self) -> None:
        """Put side by side the jobs that differ only in overrides that do not change the batch
        key, when the keys were not noted (zrp_ga's sweeper composes a few jobs, not all): a
        swept key changes the key if the first job with a key gets another key with that
        override's next value (composed here: one composition per swept key). Jobs are grouped
        by their values of such keys, and a group is sent together when its first job has a key;
        the worker computes each job's own key, evolves together only the runs that share it and
        runs a job without one alone (``_batch``), so that a wrong guess here (keys changed only
        in combination) costs time, never a result."""
        jobs = list(self.todo)
        lines = [dict(_split(o) for o in overrides) for _, overrides in jobs]
        swept = [k for k in dict.fromkeys(k for job in lines for k in job) if len({job.get(k) for job in lines}) > 1]
        if not swept:
            return
        base = next(((i, key) for i in range(min(3, len(jobs))) if (key := self._key_of(jobs[i][1])) is not None), None)
        if base is None:  # no key among the first jobs (LM, CMA-ES sweeps): in their order
            return
        first, key = base
        changing = []
        for k in swept:
            value = lines[first].get(k)
            other = next((job[k] for job in lines if k in job and job[k] != value), None)
            # the first job with the key's next value, overrides in their order (a job of the sweep, whose config is kept for it)
            variant = [f"{k}={other}" if _split(o)[0] == k else o for o in jobs[first][1]]
            if k not in lines[first] or other is None or self._key_of(variant) != key:
                changing.append(k)
        self.group = {idx: ("group", *(job.get(k) for k in changing)) for (idx, _), job in zip(jobs, lines)}
        groups: dict[Any, list] = {}
        for job in jobs:
            groups.setdefault(self.group[job[0]], []).append(job)
        self.todo = collections.deque(job for same in groups.values() for job in same)
        self.left = collections.Counter(self.group.values())

    def _key_of(self, overrides: list[str]) -> Any:
        """The batch key of a job with these overrides (None: runs alone or does not compose);
        its config kept for the job (the loader's own kept config is taken by this call)."""
        try:
            config = self.compose(overrides)
        except Exception:
            return None
        self.early[tuple(overrides)] = config
        return self.key(config)

    def show_progress(self, close: bool = False) -> None:
        """The progress line (``_progress``): jobs ended, failed, running (a worker's first batch)."""
        failed = self.failed
        running = sum(len(w.batches[0]) for w in self.pool.workers if w.batches)
        (self.progress.close if close else self.progress.show)(len(self.returns), failed, 0 if close else running)

    def run(self) -> dict[int, JobReturn]:
        for w in list(self.pool.workers):
            self.feed(w)
        while len(self.returns) < len(self.overrides):
            self.show_progress()
            handles = {}
            for w in self.pool.workers:
                handles[w.conn] = handles[w.process.sentinel] = w
            ahead = self.together and self.todo and self.waiting < self.limit  # compose while the workers work
            ready = wait(list(handles), timeout=0 if ahead else self.launcher.settings.table_every_s)
            for handle in ready:
                w = handles[handle]
                if w in self.pool.workers:
                    self.receive(w) if handle is w.conn else self.lost(w)
            if ahead and not ready:
                self.compose_next()
            if time.monotonic() - self.table_at > self.launcher.settings.table_every_s:
                self.write_table()
        return self.returns

    def feed(self, w: _Worker) -> None:
        """Send ``w`` batches until it holds ``AHEAD`` (batches of jobs run together: one, so
        that no batch waits behind another while a worker is idle)."""
        while len(w.batches) < (1 if self.together else AHEAD):
            together, batch = self.next_batch()
            if not batch:
                return
            for idx, overrides, _ in batch:
                log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
            w.conn.send((together, [(idx, data) for idx, _, data in batch]))
            w.batches.append([idx for idx, _, _ in batch])

    def next_batch(self) -> tuple[bool, list[tuple[int, list[str], bytes]]]:
        """Whether the jobs of the next batch run together, and its jobs (number, overrides,
        pickled config). Together: jobs of the same ``batch_key``, ``self.size`` of them, or
        fewer when ``self.limit`` jobs wait composed (then those of the key with the most) and
        at the end of the sweep; a job without a key alone; with ``lockstep=false``
        ``batch_size`` jobs one after another."""
        if not self.together:
            batch = [self.todo.popleft() for _ in range(min(self.launcher.settings.batch_size, len(self.todo)))]
            return False, [(idx, overrides, pickle.dumps(self.compose(overrides))) for idx, overrides in batch]
        while True:
            if self.alone:
                self.waiting -= 1
                return False, [self.alone.popleft()]
            full = next((key for key, jobs in self.pending.items()
                         if len(jobs) >= self.size or (self.left is not None and not self.left[key])), None)  # fmt: skip
            if full is not None:
                return True, self._pop(full)
            if not self.todo or self.waiting >= self.limit:
                break
            self.compose_next()
        if not self.pending:
            return False, []
        return True, self._pop(max(self.pending, key=lambda k: len(self.pending[k])))

    def compose_next(self) -> None:
        """Compose the next job and put it with those of its batch key (or alone)."""
        idx, overrides = self.todo.popleft()
        loader = self.launcher.hydra_context.config_loader
        if self.noted is not None and self.left is not None:  # the keys noted by the loader, which keeps the configs too (ComposingLoader)
            data = loader.pickled_config(self.launcher.config, overrides)
            key = self.noted(self.launcher.config, overrides)
            self.left[key] -= 1
        elif self.group is not None and self.left is not None and hasattr(loader, "pickled_config"):
            # sent with the jobs of its group, its key not computed here (the config made typed: a
            # few ms a job, again in the worker): the worker runs alone, as Hydra's run_job, a job
            # whose key is None (_batch.run_batch), so that only the first job of a group is
            # composed whole here, to send a group whose jobs have no key one at a time
            early = self.early.pop(tuple(overrides), None)  # composed to find the groups (and perhaps kept by the loader)
            data = loader.pickled_config(self.launcher.config, overrides, compose=early is None)
            data = pickle.dumps(early) if data is None else data
            group = self.group[idx]
            self.left[group] -= 1
            if group not in self.group_keys:
                self.group_keys[group] = self.key(early if early is not None else pickle.loads(data)) is not None
            key = group if self.group_keys[group] else None
        else:
            config = self.compose(overrides)
            kept = getattr(loader, "pickled_config", None)  # with notes: the config and key the loader kept as it composed it
            data = kept(self.launcher.config, overrides, compose=False) if kept else None
            key = self.key(config) if data is None else loader.noted_for(self.launcher.config, overrides)
            data = pickle.dumps(config) if data is None else data
            if self.group is not None and self.left is not None:  # sent with the jobs of its group (the worker splits it by key)
                self.left[self.group[idx]] -= 1
                key = None if key is None else self.group[idx]
        job = (idx, overrides, data)
        self.alone.append(job) if key is None else self.pending.setdefault(key, []).append(job)
        self.waiting += 1

    def _pop(self, key: str) -> list:
        jobs = self.pending[key]
        batch, self.pending[key] = jobs[: self.size], jobs[self.size :]
        if not self.pending[key]:
            del self.pending[key]
        self.waiting -= len(batch)
        return batch

    @staticmethod
    def key(config: DictConfig) -> str | None:
        """The job's ``batch_key`` (None: it runs alone; so does a job whose config fails here:
        it fails in its run, with its own message)."""
        try:
            from zrp_ga.config import typed
            from zrp_ga.run.sweep import batch_key

            return batch_key(typed(config))
        except Exception:
            return None

    def compose(self, overrides: list[str]) -> DictConfig:
        """The job's config, composed now (while the workers run the jobs before it), or when
        the jobs were grouped (``_key_of``)."""
        early = self.early.pop(tuple(overrides), None)
        return early if early is not None else self.launcher.hydra_context.config_loader.load_sweep_config(self.launcher.config, overrides)

    def returned(self, idx: int, ret: JobReturn) -> None:
        self.returns[idx] = ret
        self.failed += ret.status == JobStatus.FAILED

    def receive(self, w: _Worker) -> None:
        try:
            data = w.conn.recv_bytes()
        except (EOFError, OSError):
            return self.lost(w)
        idx, ret = pickle.loads(data)
        self.returned(idx, ret)
        w.batches[0].remove(idx)
        if not w.batches[0]:
            w.batches.popleft()
            self.feed(w)

    def lost(self, w: _Worker) -> None:
        """``w`` died: its unfinished jobs fail (and are recorded), but those whose run had
        finished (a batch's runs end before the batch); another worker takes its place."""
        w.process.join(1.0)
        code = w.process.exitcode
        how = f"killed by {signal.Signals(-code).name}" if code is not None and code < 0 and -code in signal.valid_signals() else f"exit code {code}"
        states = _states(self.sweep)
        lost = [i for batch in w.batches for i in batch]
        for idx in lost:
            others = [i for i in lost if i != idx]
            with_them = f", with job{'s' * (len(others) > 1)} {', '.join(map(str, others))}" if others else ""
            # one line on the console (an OSError's), naming the job; the same command runs it again
            error = ChildProcessError(f"job {idx} ({' '.join(filter_overrides(self.overrides[idx]))}): the worker process running this job "
                                      f"died ({how}){with_them}; its run is failed, run the same command again to continue it")  # fmt: skip
            self.returned(idx, _lost_job(self.launcher, idx, self.overrides[idx], error, states.get(idx)))
        self.feed(self.pool.replace(w))

    def write_table(self) -> None:
        """``manifest.csv``; one line when it cannot be written (a full disk: ``manifest.jsonl``
        keeps the states, and the jobs that failed for it say why)."""
        self.table_at = time.monotonic()
        try:
            from zrp_ga.run import directory
        except ImportError:
            return
        try:
            directory.write_table(self.sweep)
        except OSError as exc:
            if getattr(self, "table_failed", False):
                return
            self.table_failed = True  # said once
            log.warning(f"{exc.filename or self.sweep}: not written ({exc.strerror or exc}); manifest.jsonl holds the jobs' states")


def _split(override: str) -> tuple[str, str | None]:
    """An override line's key (with its ``+``, ``~`` and ``@package``) and value (None: none)."""
    key, eq, value = override.partition("=")
    return key, value if eq else None


def _lost_job(launcher: Any, idx: int, overrides: list[str], error: Exception, state: str | None) -> JobReturn:
    """The return of a job whose worker died before sending it: completed with the objective in
    its summary when its run had ended (``state``: its last in the manifest), else failed, with
    the manifest line the job could not write."""
    ret = JobReturn(overrides=overrides, status=JobStatus.FAILED)
    ret.return_value = error
    try:
        from zrp_ga.run import directory
    except ImportError:
        return ret
    config = launcher.hydra_context.config_loader.load_sweep_config(launcher.config, overrides)
    with open_dict(config):
        config.hydra.job.id, config.hydra.job.num = str(idx), idx
    hc = config.hydra
    sweep = directory.Sweep(Path(hc.sweep.dir), idx, tuple(hc.overrides.task), str(hc.sweep.subdir))
    out = sweep.dir / sweep.subdir
    if state == "done" and directory.status(out) == "done":
        try:
            value = directory.read_summary(out).get("objective")
            ret.status, ret.return_value = JobStatus.COMPLETED, float("nan") if value is None else float(value)
            return ret
        except (OSError, ValueError, TypeError):
            pass
    text = f"{type(error).__name__}: {error}"
    directory.fail_lost(out, text)  # its status as its run would have set it
    directory.record(sweep, "failed", text)
    return ret


def _states(sweep: Path) -> dict[int, str]:
    """Each job's last state in the sweep's manifest."""
    try:
        from zrp_ga.run import directory
    except ImportError:
        return {}
    return {int(s["job"]): s["status"] for s in directory.job_states(sweep)}
