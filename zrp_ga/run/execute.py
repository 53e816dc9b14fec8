"""A prepared run executed and recorded: seeded, optimised with the callbacks, summarised, its
files written into its directory with ``status.json`` saying where it is. A job of a sweep
(:func:`sweep_job`) also continues whatever a killed run of the same sweep left in its
directory, and records its state in the sweep's manifest.

Nothing here knows Hydra: the command line (``zrp_ga.cli.main``), :func:`zrp_ga.calibrate`, the
experiments and the launcher's workers all run through :func:`run` or :func:`sweep_job`.
"""

from __future__ import annotations

import contextlib
import logging
import math
import random
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from zrp_ga.config import ConfigError
from zrp_ga.core.errors import warn
from zrp_ga.run import directory
from zrp_ga.run.build import Prepared, build, check_inputs, inputs, instance_key, prepare, task_config
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import CACHE, Cache

log = logging.getLogger("zrp_ga")


def run(cfg: DictConfig, out: str | Path, progress: bool | None = None, overrides: Sequence[str] = (),
        choices: dict | None = None) -> float:  # fmt: skip
    """Check and run one calibration as configured, write its files into ``out`` (or, resuming,
    the run's own directory) and return the objective (``objective``: the final cost, or the
    final cost over the instance's floor). ``progress``: show the progress line (default:
    ``cfg.progress``); ``overrides``, ``choices``: see :func:`zrp_ga.run.build.prepare`."""
    p = prepare(cfg, Path(out), overrides, choices)
    return objective(run_prepared(p, p.cfg.progress if progress is None else progress))


def objective(ran: tuple[Any, dict]) -> float:
    """The objective of what :func:`run_prepared` returned."""
    return float(ran[1]["objective"])


def run_prepared(p: Prepared, progress: bool, sweep: Sweep | None = None, cache: Cache = CACHE) -> tuple[Any, dict]:
    """Run ``p`` in ``p.out`` with ``status.json`` telling where it is: running, then done,
    failed or interrupted; the result and the summary (:func:`execute`)."""
    p.out.mkdir(parents=True, exist_ok=True)
    with directory.locked(p.out):  # one run per directory at a time
        directory.remove_temporary(p.out)  # what a killed run left
        directory.write_status(p.out, "running")
        try:
            ran = execute(p, p.out, progress, sweep, cache)
        except BaseException as exc:  # Ctrl-C or a crash (a full disk): say so where the report will look
            directory.remove_temporary(p.out)
            try:
                named = isinstance(exc, OSError) and exc.filename  # repr leaves the file out
                directory.write_status(p.out, "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed",
                                       f"{type(exc).__name__}: {exc}" if named else repr(exc))  # fmt: skip
            except OSError:  # the disk is full: the error itself tells
                pass
            raise
        directory.write_status(p.out, "done")
    return ran


def execute(p: Prepared, out: Path | None, progress: bool, sweep: Sweep | None = None,
            cache: Cache = CACHE) -> tuple[Any, dict]:  # fmt: skip
    """Seed, optimise with the callbacks, summarise; with ``out``, write the run's files there
    (a convergence log and checkpoints as it goes, the rest at the end). Returns the result and
    the summary."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from zrp_ga.run import callbacks, summary

    cfg, task = p.cfg, p.task
    seed = int(cfg.seed)
    random.seed(seed)  # DEAP's own operators draw from `random`
    np.random.seed(seed % 2**32)
    rng = np.random.default_rng([seed, 0])  # the optimiser's stream; problems draw from [seed, 1] and up
    resolved = p.resolved or OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    cbs = [callbacks.Timing(), callbacks.Validation(task.judge)]
    if out is not None:
        cbs.append(callbacks.ConvergenceLog(out / directory.CONVERGENCE, None if p.state is None else int(p.state["gen"])))
        if p.algorithm.checkpointable and cfg.checkpoint_every:
            cbs.append(callbacks.Checkpoint(out / directory.CHECKPOINT, int(cfg.checkpoint_every), resolved, p.choices,
                                            inputs(cfg, task)))  # fmt: skip
    if progress:
        cbs.append(callbacks.Progress())
    where = None if sweep is None else sweep.dir
    with threadpool_limits(limits=1, user_api="blas"):  # one BLAS thread: 50x faster on a busy 2-core machine
        diagnostics = summary.diagnostics(task, p.state is None, p.instance, cache, where)
        result = p.algorithm.run(task.problem, rng, cbs, p.state)
    written, x = summary.build(task, result, cfg, resolved, diagnostics, p.algorithm.elapsed(), p.choices)
    with threadpool_limits(limits=1, user_api="blas"):
        written["objective"] = summary.objective(cfg, task, written, p.instance, cache, where)
    if out is not None:
        summary.write(out, task, result, written, x)
    for w in written["warnings"]:
        warn(w, log)
    return result, written


def sweep_job(cfg: DictConfig, out: Path, sweep: Sweep, choices: dict, cache: Cache = CACHE) -> float:
    """Run a job of a sweep in its directory ``out`` and return its objective, recording its
    state in the sweep's manifest, and continuing whatever a killed run of the same sweep left
    there: a finished run is kept as it is, a run with a checkpoint continues from it (to the
    same files an uninterrupted run writes), a partial run without one starts again. A run of
    another config in ``out`` is refused."""
    try:
        value = _sweep_job(task_config(cfg), out, sweep, choices, cache)
    except KeyboardInterrupt:
        directory.record(sweep, "interrupted", INTERRUPTED)
        raise
    except Exception as exc:
        directory.record(sweep, "failed", f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
        raise
    directory.record(sweep, "done")
    return value


Job = tuple  # (cfg, out, sweep, choices): a sweep job's config, run directory, place in the sweep, groups' options


def batch_key(cfg: DictConfig) -> str | None:
    """Jobs of a sweep with the same key can be evolved together (:func:`sweep_batch`): GA runs
    on the same problem instance with the same population shapes. None: the job runs alone."""
    if str(cfg.algorithm.get("_target_", "")) != "zrp_ga.algorithms.ga.GA" or cfg.get("resume"):  # (the hydra node left in)
        return None
    pop = cfg.algorithm.population
    return f"{instance_key(cfg)}|mu={int(pop.mu)}|lambda={int(pop.lambda_)}"


def sweep_batch(jobs: Sequence[Job], cache: Cache = CACHE,
                around: Callable[[int], contextlib.AbstractContextManager] | None = None) -> list[float | Exception]:  # fmt: skip
    """Run jobs of a sweep (each ``(cfg, out, sweep, choices)`` as :func:`sweep_job` takes
    them) and return per job its objective or the exception it failed with, each job recorded
    in the manifest as :func:`sweep_job` records it. GA jobs with the same :func:`batch_key`
    are evolved together (:meth:`zrp_ga.algorithms.Algorithm.run_together`): one evaluation of
    all their offspring per generation, each run with its own random streams, so that every
    run's files are those it writes alone; the others run one after another. ``around(k)``: a
    context entered around everything done for job ``k`` alone (its log file, Hydra's view of
    the job), by the launcher. KeyboardInterrupt is raised after every job recorded its state."""
    out: list[Any] = [None] * len(jobs)
    ready: dict[Any, list[tuple[int, Prepared, Sweep]]] = {}

    def job(k: int) -> contextlib.AbstractContextManager:
        return around(k) if around else contextlib.nullcontext()

    for k, (cfg, where, sweep, choices) in enumerate(jobs):
        with job(k):
            got = _attempt(sweep, _job, cfg, where, sweep, choices, cache)
            if isinstance(got, (float, Exception)):
                if isinstance(got, float):
                    directory.record(sweep, "done")
                out[k] = got
            else:
                key = None if got.algorithm.draws_from_random() else batch_key(got.cfg)
                ready.setdefault((key, id(got.task)) if key else ("alone", k), []).append((k, got, sweep))
    for group in ready.values():
        if len(group) == 1:
            k, p, sweep = group[0]
            with job(k):
                out[k] = _attempt(sweep, _run_job, p, sweep, cache)
                if not isinstance(out[k], Exception):
                    directory.record(sweep, "done")
        else:
            for (k, _, _), value in zip(group, _together(group, cache, job)):
                out[k] = value if isinstance(value, Exception) else objective(value)
    return out


INTERRUPTED = "KeyboardInterrupt: continue by running the sweep again"
# Runs evolved together save their checkpoints every checkpoint_every generations, but no sooner
# than this many seconds after the last (and at the end, and at Ctrl-C): a batch of short runs
# then writes each run's checkpoint once, and a kill loses at most this much of a batch's work.
BATCH_CHECKPOINT_S = 10.0


def _attempt(sweep: Sweep, work: Callable[..., Any], *args: Any) -> Any:
    """``work(*args)``, or the exception it raised, recorded in the sweep's manifest as failed;
    Ctrl-C recorded as interrupted, and raised."""
    try:
        return work(*args)
    except KeyboardInterrupt:
        directory.record(sweep, "interrupted", INTERRUPTED)
        raise
    except Exception as exc:
        _failed(sweep, exc)
        return exc


def _failed(sweep: Sweep, exc: BaseException) -> None:
    directory.record(sweep, "failed", f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")


def run_together(prepared: Sequence[Prepared], cache: Cache = CACHE) -> list[tuple[Any, dict] | Exception]:
    """Run prepared GA runs on one problem instance (the same ``task``) evolved together, each
    writing into its ``out`` (None: nothing written) what it writes alone; per run what
    :func:`execute` returns (the result and the summary), or the exception it failed with.
    :func:`zrp_ga.calibrate` over many seeds runs so."""
    if len({id(p.task) for p in prepared}) > 1:
        raise ValueError("runs evolved together share one problem instance")
    return _together([(k, p, None) for k, p in enumerate(prepared)], cache, lambda k: contextlib.nullcontext())


def _together(group: list[tuple[int, Prepared, Sweep | None]], cache: Cache, job: Callable) -> list[Any]:
    """Evolve the prepared runs of ``group`` (GA runs on one problem instance) together, each
    in its own directory (if it has one) with everything :func:`run_prepared` and
    :func:`execute` give a run alone: its lock, status, convergence log (written at every
    checkpoint: the rows in memory between them), checkpoints, summary and files, manifest
    line (for a sweep's job). Per run its result and summary, or the exception it failed with;
    KeyboardInterrupt after every unfinished run saved its checkpoint and recorded it."""
    from threadpoolctl import threadpool_limits

    from zrp_ga.run import callbacks, summary

    out: list[Any] = [None] * len(group)
    live: list[int] = []
    setups: list[tuple] = []
    hashed: dict[str, dict] = {}  # instance key -> the hashes of its robot and data files
    with contextlib.ExitStack() as stack:
        for i, (k, p, _) in enumerate(group):
            with job(k):
                try:
                    if p.out is not None:
                        p.out.mkdir(parents=True, exist_ok=True)
                        stack.enter_context(directory.locked(p.out))  # one run per directory at a time
                        directory.remove_temporary(p.out)
                        directory.write_status(p.out, "running")
                    setups.append(_callbacks(p, callbacks, hashed))
                    live.append(i)
                except Exception as exc:
                    out[i] = exc

        def finished(j: int, result: Any) -> None:  # run live[j] ended: its summary and files, as execute writes them
            i = live[j]
            k, p, sweep = group[i]
            where = None if sweep is None else sweep.dir
            with job(k):
                written, x = summary.build(p.task, result, p.cfg, setups[j][2], diagnostics[j], p.algorithm.elapsed(), p.choices)
                written["objective"] = summary.objective(p.cfg, p.task, written, p.instance, cache, where)
                if p.out is not None:
                    summary.write(p.out, p.task, result, written, x)
                for w in written["warnings"]:
                    warn(w, log)
                if p.out is not None:
                    directory.write_status(p.out, "done")
                if sweep is not None:
                    directory.record(sweep, "done")
                out[i] = (result, written)

        try:
            with threadpool_limits(limits=1, user_api="blas"):  # see execute
                diagnostics = [summary.diagnostics(group[i][1].task, group[i][1].state is None, group[i][1].instance, cache,
                                                   None if group[i][2] is None else group[i][2].dir) for i in live]  # fmt: skip
                algorithms = [group[i][1].algorithm for i in live]
                for a, setup in zip(algorithms, setups):
                    a.random_state = setup[3]
                ended = type(algorithms[0]).run_together(
                    algorithms, group[live[0]][1].task.problem, [s[0] for s in setups], [s[1] for s in setups],
                    [group[i][1].state for i in live], finished,
                ) if live else []  # fmt: skip
            for j, i in enumerate(live):
                if isinstance(ended[j], Exception):
                    out[i] = ended[j]
        except BaseException as exc:  # Ctrl-C, or a failure shared by the runs: every unfinished run says so
            interrupted = isinstance(exc, KeyboardInterrupt)
            for i in live:
                if out[i] is None:
                    k, p, sweep = group[i]
                    if interrupted:
                        if p.out is not None:
                            directory.remove_temporary(p.out)
                            directory.write_status(p.out, "interrupted", repr(exc))
                        if sweep is not None:
                            directory.record(sweep, "interrupted", INTERRUPTED)
                    else:
                        out[i] = exc if isinstance(exc, Exception) else RuntimeError(repr(exc))
            if interrupted or not isinstance(exc, Exception):
                raise
        for i, value in enumerate(out):
            if isinstance(value, Exception):
                k, p, sweep = group[i]
                with job(k):
                    log.error("%s: %s: %s", p.out or f"run {k}", type(value).__name__, value)
                    if p.out is not None:
                        directory.remove_temporary(p.out)
                        with contextlib.suppress(OSError):  # a full disk: the error itself tells
                            directory.write_status(p.out, "failed", repr(value))
                    if sweep is not None:
                        _failed(sweep, value)
    return out


def _callbacks(p: Prepared, callbacks: Any, hashed: dict[str, dict]) -> tuple:
    """A run's generator, callbacks (those :func:`execute` gives it, the convergence log written
    at each checkpoint), resolved config and seeded state of ``random``."""
    import numpy as np

    cfg, task = p.cfg, p.task
    seed = int(cfg.seed)
    before = random.getstate()
    random.seed(seed)  # the state a run alone starts from (zrp_ga's own operators never draw from it)
    seeded = random.getstate()
    random.setstate(before)
    resolved = p.resolved or OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    cbs = [callbacks.Timing(), callbacks.Validation(task.judge)]
    if p.out is not None:
        every = int(cfg.checkpoint_every) if p.algorithm.checkpointable else 0
        rows = callbacks.ConvergenceLog(p.out / directory.CONVERGENCE, None if p.state is None else int(p.state["gen"]), buffered=True)
        cbs.append(rows)
        if every:
            if p.instance not in hashed:  # the runs of a batch share their instance: hashed once
                hashed[p.instance] = inputs(cfg, task)
            cbs.append(callbacks.Checkpoint(p.out / directory.CHECKPOINT, every, resolved, p.choices, hashed[p.instance],
                                            BATCH_CHECKPOINT_S, rows.flush))  # fmt: skip
    return np.random.default_rng([seed, 0]), cbs, resolved, seeded


def _run_job(p: Prepared, sweep: Sweep, cache: Cache) -> float:
    return objective(run_prepared(p, False, sweep, cache))


def _job(cfg: DictConfig, out: Path, sweep: Sweep, choices: dict, cache: Cache) -> float | Prepared:
    """A sweep job's run prepared, or its objective when its directory holds it finished (see
    :func:`sweep_job`); ``cfg`` with or without its hydra node."""
    from zrp_ga.run import checkpoint

    cfg = task_config(cfg)
    damaged = directory.damage(out) if directory.status(out) == "done" else None
    if damaged:  # never kept as finished: the run is deterministic, so running it again gives its files back
        log.warning("%s: %s; the job runs again", out, damaged)
        directory.clear(out)
    elif directory.status(out) == "done" and (out / directory.SUMMARY).exists():
        written = directory.read_summary(out)
        _same_run(cfg, written.get("config"), out)
        log.info("%s: finished before; kept", out)
        value = written.get("objective", written["final_cost"])
        return float("nan") if value is None else float(value)
    directory.record(sweep, "running")
    if cfg.get("resume"):
        raise ConfigError("resume: a sweep continues when it is run again into the same hydra.sweep.dir")
    state = None
    if (out / directory.CHECKPOINT).exists():
        try:
            state = checkpoint.load(out / directory.CHECKPOINT)
        except ValueError as exc:  # a checkpoint is written atomically: this is a damaged disk or a foreign file
            log.warning("%s; the run starts again", exc)
        else:
            state.pop("choices", None)
            _same_run(cfg, state.pop("config"), out)
            recorded = state.pop("inputs", None)
            log.info("%s: continues from its checkpoint after generation %d", out, int(state["gen"]))
    p = build(cfg, out, state, choices, cache)
    if state is not None:
        check_inputs(p, recorded, str(out))
    return p


def _sweep_job(cfg: DictConfig, out: Path, sweep: Sweep, choices: dict, cache: Cache) -> float:
    got = _job(cfg, out, sweep, choices, cache)
    return got if isinstance(got, float) else _run_job(got, sweep, cache)


def _same_run(cfg: DictConfig, stored: dict | None, out: Path) -> None:
    """Refuse to continue the run in ``out`` when its config (``stored``, from its summary or
    checkpoint) is not ``cfg`` (the progress line and resume setting aside)."""

    def plain(o: Any) -> Any:  # as JSON holds it: non-finite floats as null; a null setting as an absent one
        if isinstance(o, dict):  # (a run recorded before a setting existed holds no key for it)
            return {str(k): p for k, v in o.items() if (p := plain(v)) is not None}
        if isinstance(o, (list, tuple)):
            return [plain(v) for v in o]
        return None if isinstance(o, float) and not math.isfinite(o) else o

    mine, theirs = (plain({k: v for k, v in c.items() if k not in ("progress", "resume")})
                    for c in (OmegaConf.to_container(cfg, resolve=True, enum_to_str=True), stored or {}))  # fmt: skip
    if mine != theirs:
        raise ConfigError(f"{out} holds a run of another config ({_difference(mine, theirs)} differs); "
                          "run this sweep into another hydra.sweep.dir")  # fmt: skip


def _difference(a: Any, b: Any) -> str:
    """A dotted key at which the nested dicts ``a`` and ``b`` differ, the shortest (the same
    setting can appear deeper through an interpolation: ``algorithm.population``)."""

    def leaves(a: Any, b: Any, key: str) -> list[str]:
        if isinstance(a, dict) and isinstance(b, dict):
            return [k for name in [*a, *(n for n in b if n not in a)] if a.get(name) != b.get(name)
                    for k in leaves(a.get(name), b.get(name), f"{key}.{name}" if key else name)]  # fmt: skip
        return [key or "the config"]

    return min(leaves(a, b, ""), key=lambda k: k.count("."), default="the config")


def warm_up(cfg: DictConfig, cache: Cache = CACHE) -> None:
    """Load what the runs of a sweep need (modules, compiled code, the base config's problem
    instance) by building the sweep's base config and running one generation of it, writing
    nothing. zrp_ga's launcher calls it in each worker while Hydra still checks the sweep's jobs;
    whatever fails here fails again, with its message, in the job itself."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from zrp_ga.core import compiled
    from zrp_ga.io import records  # noqa: F401 (imported for the runs)
    from zrp_ga.run import callbacks, checkpoint, summary  # noqa: F401 (imported for the runs)

    compiled.prefer_compiled()  # a sweep's runs pay for compiling: load the kernels here, once, not in each worker
    try:
        p = build(task_config(cfg), None, None, {}, cache)
        with threadpool_limits(limits=1, user_api="blas"):
            p.algorithm.setup(p.task.problem, np.random.default_rng(0))
            p.algorithm.initialize()
            if p.algorithm.has_next():
                p.algorithm.step()
            p.task.judge(p.algorithm.current()[0])
    except Exception as exc:
        log.debug("warm-up: %s", exc)
