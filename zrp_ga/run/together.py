"""Prepared GA runs on one problem instance evolved together (lockstep): one evaluation of all
their offspring per generation (:meth:`zrp_ga.algorithms.Algorithm.run_together`), each run
with its own random streams, so that every run writes exactly what it writes alone. Each run
gets what a run alone gets (:mod:`zrp_ga.run.assembly`): its lock and status, callbacks,
checkpoints, summary, files and warnings, and its manifest line for a sweep's job.
:func:`zrp_ga.calibrate` over many seeds (:func:`run_together`) and zrp_ga's launcher (through
:func:`zrp_ga.run.sweep.sweep_batch`) run so.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import Any

from zrp_ga.algorithms import Result
from zrp_ga.run import assembly
from zrp_ga.run.assembly import Ran, Start
from zrp_ga.run.build import Prepared
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import CACHE, Cache

log = logging.getLogger("zrp_ga")

Member = tuple[int, Prepared, Sweep | None]  # a run of a group: its number (for ``within``), the run, its sweep job
Within = Callable[[int], AbstractContextManager[Any]]  # a context around what is done for run k alone


def run_together(prepared: Sequence[Prepared], cache: Cache = CACHE) -> list[Ran | Exception]:
    """Run prepared GA runs on one problem instance (the same ``task``) evolved together, each
    writing into its ``out`` (None: nothing written) what it writes alone; per run what
    :func:`zrp_ga.run.execute.execute` returns (the result and the summary), or the exception
    it failed with."""
    if len({id(p.task) for p in prepared}) > 1:
        raise ValueError("runs evolved together share one problem instance")
    return run_group([(k, p, None) for k, p in enumerate(prepared)], cache)


def run_group(group: Sequence[Member], cache: Cache = CACHE,
              within: Within | None = None) -> list[Ran | Exception]:  # fmt: skip
    """Evolve the runs of ``group`` together, each in its own directory if it has one; per run
    its result and summary, or the exception it failed with. ``within(k)``: a context entered
    around what is done for run ``k`` alone (the launcher's view of the job). KeyboardInterrupt
    after every unfinished run saved its checkpoint and recorded it."""
    within = within or (lambda k: contextlib.nullcontext())
    out: list[Ran | Exception | None] = [None] * len(group)
    with contextlib.ExitStack() as held:
        live, starts = _begin(group, out, held, within)
        if live:
            _evolve(group, live, starts, out, cache, within)
    for i, value in enumerate(out):
        if isinstance(value, Exception) and not isinstance(value, _NotHeld):
            k, p, sweep = group[i]
            with within(k):
                log.error("%s: %s: %s", p.out or f"run {k}", type(value).__name__, value)
                assembly.stopped(p, sweep, value)
    ended = [v.error if isinstance(v, _NotHeld) else v for v in out if v is not None]
    assert len(ended) == len(group)  # every run ended with its result and summary, or its error
    return ended


class _NotHeld(Exception):
    """A run that failed before it held its directory (another run's lock): recorded already."""

    def __init__(self, error: Exception):
        super().__init__(str(error))
        self.error = error


def _begin(group: Sequence[Member], out: list[Ran | Exception | None], held: contextlib.ExitStack[bool | None],
           within: Within) -> tuple[list[int], list[Start]]:  # fmt: skip
    """Each run's directory held (in ``held``) and its start (:func:`zrp_ga.run.assembly.start`);
    the runs that could start, and their starts."""
    live: list[int] = []
    starts: list[Start] = []
    hashed: dict[str, dict[str, str]] = {}  # instance key -> the hashes of its robot and data files
    for i, (k, p, sweep) in enumerate(group):
        with within(k):
            try:
                assembly.begin(p, held)
            except Exception as exc:
                log.error("%s: %s: %s", p.out or f"run {k}", type(exc).__name__, exc)
                assembly.stopped(None, sweep, exc)  # its directory is not this run's to write
                out[i] = _NotHeld(exc)
                continue
            try:
                starts.append(assembly.start(p, False, True, hashed, assembly.study(p, sweep)))
                live.append(i)
            except Exception as exc:
                out[i] = exc
    return live, starts


def _evolve(group: Sequence[Member], live: list[int], starts: list[Start], out: list[Ran | Exception | None], cache: Cache,
            within: Within) -> None:  # fmt: skip
    """Run the ``live`` runs of ``group`` together (their ``starts``), each ended as it
    finishes (:func:`zrp_ga.run.assembly.finish`); the results and failures into ``out``."""
    from threadpoolctl import threadpool_limits

    figures: list[dict[str, Any]] = []

    def finished(j: int, result: Result) -> None:  # run live[j] ended: its summary, files and status
        i = live[j]
        k, p, sweep = group[i]
        with within(k):
            out[i] = assembly.finish(p, result, figures[j], cache, sweep)
            assembly.done(p, sweep)

    runs = [group[i] for i in live]
    try:
        with threadpool_limits(limits=1, user_api="blas"):  # see zrp_ga.run.execute.execute
            figures.extend(assembly.diagnostics(p, cache, sweep) for _, p, sweep in runs)
            algorithms = [p.algorithm for _, p, _ in runs]
            for a, s in zip(algorithms, starts):
                a.random_state = s.random_state
            ended = type(algorithms[0]).run_together(algorithms, runs[0][1].task.problem, [s.rng for s in starts],
                                                     [s.callbacks for s in starts], [p.state for _, p, _ in runs], finished)  # fmt: skip
        for i, end in zip(live, ended):
            if isinstance(end, Exception):
                out[i] = end
    except BaseException as exc:  # Ctrl-C, or a failure shared by the runs: every unfinished run says so
        for i in live:
            if out[i] is None:
                if isinstance(exc, Exception):
                    out[i] = exc
                else:
                    k, p, sweep = group[i]
                    with within(k):
                        assembly.stopped(p, sweep, exc)
        if not isinstance(exc, Exception):
            raise
