"""The jobs of a sweep: each a :class:`SweepJob` (its typed config, its directory, its place in
the sweep, the config groups' options), run alone (:func:`sweep_job`) or, for GA jobs on one
problem instance with one population shape (:func:`batch_key`), evolved together
(:func:`sweep_batch`, :mod:`zrp_ga.run.together`). Every job records its state in the sweep's
manifest and continues whatever a killed run of the same sweep left in its directory: a
finished run is kept as it is, a run with a checkpoint continues from it (to the same files an
uninterrupted run writes), a partial run without one starts again. A run of another config in
the directory is refused.

The command line's ``zrp-ga -m`` (one job per call, :func:`sweep_job`) and zrp_ga's launcher
(batches, :func:`sweep_batch`) run their jobs through here.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
from collections.abc import Callable, Hashable, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any, TypeVar

from zrp_ga.algorithms import State
from zrp_ga.core import schema
from zrp_ga.core.schema import Config, ConfigError
from zrp_ga.run import assembly, directory, execute, together
from zrp_ga.run.build import Prepared, build, check_inputs, instance_key
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import CACHE, Cache
from zrp_ga.run.together import Within

log = logging.getLogger("zrp_ga")
T = TypeVar("T")


@dataclasses.dataclass(frozen=True)
class SweepJob:
    """A job of a sweep as the run layer takes it: its config, its run directory ``out``, its
    place in the sweep (the manifest's line) and the config groups' options (``summary.json``)."""

    cfg: Config
    out: Path
    sweep: Sweep
    choices: dict[str, Any] = dataclasses.field(default_factory=dict)


def sweep_job(job: SweepJob, cache: Cache = CACHE) -> float:
    """Run ``job`` in its directory and return its objective (see the module docstring)."""
    try:
        got = _job(job, cache)
    except BaseException as exc:
        assembly.record_stop(job.sweep, exc)
        raise
    if isinstance(got, float):
        directory.record(job.sweep, "done")
        return got
    return execute.objective(execute.run_prepared(got, False, job.sweep, cache))


def batch_key(cfg: Config) -> str | None:
    """Jobs of a sweep with the same key can be evolved together (:func:`sweep_batch`): GA runs
    on the same problem instance with the same population shapes. None: the job runs alone."""
    if schema.setting(cfg.algorithm, "_target_") != "zrp_ga.algorithms.ga.GA" or cfg.resume:
        return None
    pop = cfg.population
    return f"{instance_key(cfg)}|mu={int(pop.mu)}|lambda={int(pop.lambda_)}"


def sweep_batch(jobs: Sequence[SweepJob], cache: Cache = CACHE,
                around: Within | None = None) -> list[float | Exception]:  # fmt: skip
    """Run jobs of a sweep and return per job its objective or the exception it failed with,
    each job recorded in the manifest as :func:`sweep_job` records it. GA jobs with the same
    :func:`batch_key` are evolved together (:func:`zrp_ga.run.together.run_group`), the others
    run one after another. ``around(k)``: a context entered around everything done for job
    ``k`` alone (its log file, Hydra's view of the job), by the launcher. KeyboardInterrupt is
    raised after every job recorded its state."""
    out: list[float | Exception | None] = [None] * len(jobs)

    def within(k: int) -> AbstractContextManager[Any]:
        return around(k) if around else contextlib.nullcontext()

    for group in _groups(jobs, out, within, cache).values():
        if len(group) == 1:
            k, p, sweep = group[0]
            with within(k):
                ran = _caught(execute.run_prepared, p, False, sweep, cache)
                out[k] = ran if isinstance(ran, Exception) else execute.objective(ran)
        else:
            for (k, _, _), value in zip(group, together.run_group(group, cache, within)):
                out[k] = value if isinstance(value, Exception) else execute.objective(value)
    ended = [v for v in out if v is not None]
    assert len(ended) == len(jobs)  # every job ended with its objective or its error
    return ended


def _groups(jobs: Sequence[SweepJob], out: list[float | Exception | None], within: Within,
            cache: Cache) -> dict[Hashable, list[tuple[int, Prepared, Sweep]]]:  # fmt: skip
    """The jobs prepared, by what can be evolved together (a job that finished before, or failed
    before its run, put into ``out`` and recorded)."""
    ready: dict[Hashable, list[tuple[int, Prepared, Sweep]]] = {}
    for k, job in enumerate(jobs):
        with within(k):
            got = _attempt(job.sweep, _job, job, cache)
            if isinstance(got, (float, Exception)):
                if isinstance(got, float):
                    directory.record(job.sweep, "done")
                out[k] = got
            else:
                key = None if got.algorithm.draws_from_random() else batch_key(got.cfg)
                ready.setdefault((key, id(got.task)) if key else ("alone", k), []).append((k, got, job.sweep))
    return ready


def _attempt(sweep: Sweep, work: Callable[..., T], *args: Any) -> T | Exception:
    """``work(*args)``, or the exception it raised, recorded in the sweep's manifest; Ctrl-C
    recorded, and raised."""
    try:
        return work(*args)
    except BaseException as exc:
        assembly.record_stop(sweep, exc)
        if not isinstance(exc, Exception):
            raise
        return exc


def _caught(work: Callable[..., T], *args: Any) -> T | Exception:
    """``work(*args)``, or the exception it raised (which ``work`` recorded); Ctrl-C raised."""
    try:
        return work(*args)
    except Exception as exc:
        return exc


def _job(job: SweepJob, cache: Cache) -> float | Prepared:
    """A sweep job's run prepared, or its objective when its directory holds it finished (see
    the module docstring)."""
    cfg, out = job.cfg, job.out
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
    directory.record(job.sweep, "running")
    if cfg.resume:
        raise ConfigError("resume: a sweep continues when it is run again into the same hydra.sweep.dir")
    state, recorded = _checkpoint(cfg, out)
    p = build(cfg, out, state, job.choices, cache)
    if state is not None:
        check_inputs(p, recorded, str(out))
    return p


def _checkpoint(cfg: Config, out: Path) -> tuple[State | None, dict[str, str] | None]:
    """The state of the checkpoint a killed run of this job left in ``out`` (None: none, or
    unreadable: the run starts again) and the inputs it recorded."""
    from zrp_ga.run import checkpoint

    if not (out / directory.CHECKPOINT).exists():
        return None, None
    try:
        state = checkpoint.load(out / directory.CHECKPOINT)
    except ValueError as exc:  # a checkpoint is written atomically: this is a damaged disk or a foreign file
        log.warning("%s; the run starts again", exc)
        return None, None
    state.pop("choices", None)
    _same_run(cfg, state.pop("config"), out)
    log.info("%s: continues from its checkpoint after generation %d", out, int(state["gen"]))
    return state, state.pop("inputs", None)


def _same_run(cfg: Config, stored: dict[str, Any] | None, out: Path) -> None:
    """Refuse to continue the run in ``out`` when its config (``stored``, from its summary or
    checkpoint) is not ``cfg`` (the progress line, resume and outputs settings aside: they change no result)."""

    def plain(o: Any) -> Any:  # as JSON holds it: non-finite floats as null; a null setting as an absent one
        if isinstance(o, dict):  # (a run recorded before a setting existed holds no key for it)
            return {str(k): p for k, v in o.items() if (p := plain(v)) is not None}
        if isinstance(o, (list, tuple)):
            return [plain(v) for v in o]
        return None if isinstance(o, float) and not math.isfinite(o) else o

    mine, theirs = (plain({k: v for k, v in c.items() if k not in ("progress", "resume", "outputs")})
                    for c in (schema.to_dict(cfg), stored or {}))  # fmt: skip
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
