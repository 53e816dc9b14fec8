"""What a run is made of besides its config's objects, written once for a run alone
(:mod:`zrp_ga.run.execute`) and for runs evolved together (:mod:`zrp_ga.run.together`): its
start (the random streams, seeded from ``seed``, and the callbacks), its directory's lock and
status (``running``, then ``done``, ``failed`` or ``interrupted``) and the sweep manifest's line,
and its end (the summary, the objective, the files and the warnings).

What a run writes (``outputs``, :func:`study`): ``full`` (a single run's default) writes every
file; ``study`` (a sweep's default, ``outputs=auto``) writes what a study reads, convergence.csv,
summary.json, best_params.csv, initial_population.csv and status.json (Hydra writes the job's
``.hydra`` record, the sweep its manifest), and neither the calibrated arm's files, the problem
kind's own, nor a finished run's checkpoint: checkpoints are written during the run, for a
killed sweep to continue from, and the last one is removed when the run is done.

Runs evolved together differ in two settings only: their convergence rows are kept in memory
between checkpoints, and their checkpoints are written no sooner than :data:`BATCH_CHECKPOINT_S`
after the last (a batch of short runs then writes each run's checkpoint once).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import random
from pathlib import Path
from typing import TYPE_CHECKING, Any

from zrp_ga.algorithms import Callback, Result
from zrp_ga.core.errors import warn
from zrp_ga.core.schema import Outputs
from zrp_ga.run import directory
from zrp_ga.run.build import Prepared, inputs
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import Cache

if TYPE_CHECKING:
    import numpy as np

    from zrp_ga.run.summary import Summary

log = logging.getLogger("zrp_ga")

# Runs evolved together save their checkpoints every checkpoint_every generations, but no sooner
# than this many seconds after the last (and at the end, and at Ctrl-C): a batch of short runs
# then writes each run's checkpoint once, and a kill loses at most this much of a batch's work.
BATCH_CHECKPOINT_S = 10.0
INTERRUPTED = "KeyboardInterrupt: continue by running the sweep again"  # a sweep job's manifest line at Ctrl-C


@dataclasses.dataclass
class Start:
    """What a prepared run starts from: the optimiser's generator (``[seed, 0]``; problems draw
    from ``[seed, 1]`` and up), the state of Python's ``random`` after ``random.seed(seed)``
    (DEAP's own operators draw from it) and the callbacks, in their order."""

    rng: np.random.Generator
    random_state: tuple[Any, ...]
    callbacks: list[Callback]


Ran = tuple[Result, "Summary"]  # a run's end: its result and its summary (summary.json)


def study(p: Prepared, sweep: Sweep | None) -> bool:
    """Whether ``p`` writes a study's files only (module docstring): ``outputs=study``, or
    ``outputs=auto`` (the default) for a ``sweep``'s job."""
    outputs = p.cfg.outputs
    return outputs is Outputs.study or (outputs is Outputs.auto and sweep is not None)


def start(p: Prepared, progress: bool, together: bool = False, hashed: dict[str, dict[str, str]] | None = None,
          study: bool = False) -> Start:  # fmt: skip
    """The start of ``p`` (``together``: evolved with other runs); ``hashed``: the hashes of the
    robot and data files of the instances seen so far (:func:`zrp_ga.run.build.inputs`, computed
    once per instance); ``study``: no checkpoint after the last generation (:func:`study`)."""
    import numpy as np

    from zrp_ga.run import callbacks

    seed = int(p.cfg.seed)
    before = random.getstate()
    random.seed(seed)
    seeded = random.getstate()
    random.setstate(before)
    cbs: list[Callback] = [callbacks.Timing(), callbacks.Validation(p.task.judge)]
    if p.out is not None:
        rows = callbacks.ConvergenceLog(p.out / directory.CONVERGENCE, None if p.state is None else int(p.state["gen"]),
                                        buffered=together)  # fmt: skip
        cbs.append(rows)
        every = int(p.cfg.checkpoint_every) if p.algorithm.checkpointable else 0
        if every:
            hashed = {} if hashed is None else hashed
            if p.instance not in hashed:  # the runs of a batch share their instance: hashed once
                hashed[p.instance] = inputs(p.cfg, p.task)
            cbs.append(callbacks.Checkpoint(p.out / directory.CHECKPOINT, every, p.resolved, p.choices, hashed[p.instance],
                                            BATCH_CHECKPOINT_S if together else 0.0, rows.flush if together else None,
                                            final=not study))  # fmt: skip
    if progress:
        cbs.append(callbacks.Progress())
    return Start(np.random.default_rng([seed, 0]), seeded, cbs)


def diagnostics(p: Prepared, cache: Cache, sweep: Sweep | None) -> dict[str, Any]:
    """The warnings of the run's problem (found while it was built) and the identifiability of
    its data (:func:`zrp_ga.run.summary.diagnostics`); in a sweep, each once per problem instance."""
    from zrp_ga.run import summary

    for w in getattr(p.task, "warnings", ()):  # what the problem found while it was built: before the work
        if first_in_sweep(sweep, p.instance, w):
            warn(w, log)
    return summary.diagnostics(p.task, p.state is None, p.instance, cache, _where(sweep))


def finish(p: Prepared, result: Result, figures: dict[str, Any], cache: Cache, sweep: Sweep | None) -> Ran:
    """The run's end (``figures``: its :func:`diagnostics`): its summary and objective, its files
    (with a directory) and its warnings; the result and the summary."""
    from zrp_ga.run import summary

    written, x = summary.build(p.task, result, p.cfg, p.resolved, figures, p.algorithm.elapsed(), p.choices)
    written["objective"] = summary.objective(p.cfg, p.task, written, p.instance, cache, _where(sweep))
    if p.out is not None:
        summary.write(p.out, p.task, result, written, x, full=not study(p, sweep))
    said = set(getattr(p.task, "warnings", ()))  # the problem's own were said at the start (diagnostics)
    for w in written["warnings"]:
        if w not in said and first_in_sweep(sweep, p.instance, w):
            warn(w + (" (said once in this sweep: every job's summary.json has its own)" if sweep else ""), log)
    return result, written


def first_in_sweep(sweep: Sweep | None, instance: str, warning: str) -> bool:
    """Whether to say ``warning`` on the console: always outside a sweep; in a sweep, when no
    job said the same text before, nor a warning of its :func:`kind` on the same problem
    ``instance`` (a marker in the sweep's folder, :func:`zrp_ga.run.directory.first_to_ask`:
    every job process sees it)."""
    if sweep is None:
        return True
    text = directory.first_to_ask(sweep.dir, f"warning {warning}")
    of_kind = directory.first_to_ask(sweep.dir, f"warning {instance} {kind(warning)}")
    return text and of_kind


def kind(warning: str) -> str:
    """A warning without its numbers: one sweep job's "3 gene(s) ... on their range bounds" is of
    the kind of another's "5 gene(s) ..." (a sweep says each kind once per problem instance)."""
    import re

    return re.sub(r"[-+]?\d[\d.,]*(e[-+]?\d+)?", "#", warning)


def _where(sweep: Sweep | None) -> Path | None:
    return None if sweep is None else sweep.dir


# --- the directory's status and the manifest ----------------------------------------------------------
def begin(p: Prepared, stack: contextlib.ExitStack) -> None:
    """Hold ``p``'s run directory (created if need be) while ``stack`` is open: its lock (one run
    per directory at a time), what a killed run left removed, status ``running``."""
    if p.out is None:
        return
    p.out.mkdir(parents=True, exist_ok=True)
    stack.enter_context(directory.locked(p.out))
    directory.remove_temporary(p.out)
    directory.write_status(p.out, "running")


def done(p: Prepared, sweep: Sweep | None) -> None:
    """The run finished: status ``done`` (a study's run then removes its checkpoint: :func:`study`),
    and the manifest's line for a sweep's job."""
    if p.out is not None:
        directory.write_status(p.out, "done")
        if study(p, sweep):
            (p.out / directory.CHECKPOINT).unlink(missing_ok=True)
    if sweep is not None:
        directory.record(sweep, "done")


def stopped(p: Prepared | None, sweep: Sweep | None, exc: BaseException) -> None:
    """The run (``p``: None before it was prepared) stopped by ``exc``: Ctrl-C (``interrupted``)
    or a failure (``failed``), said in its directory (whose lock it holds) where the report will
    look, and in the manifest for a sweep's job."""
    interrupted = isinstance(exc, KeyboardInterrupt)
    if p is not None and p.out is not None:
        directory.remove_temporary(p.out)
        named = isinstance(exc, OSError) and exc.filename  # repr leaves the file out
        with contextlib.suppress(OSError):  # a full disk: the error itself tells
            directory.write_status(p.out, "interrupted" if interrupted else "failed",
                                   f"{type(exc).__name__}: {exc}" if named else repr(exc))  # fmt: skip
    if sweep is not None:
        record_stop(sweep, exc)


def record_stop(sweep: Sweep, exc: BaseException) -> None:
    """A sweep job's manifest line for ``exc``: interrupted at Ctrl-C, else failed with its
    first line. A manifest that cannot be written (the disk ``exc`` says is full) is left: the
    error ``exc`` raised goes on, and the run's status file says it."""
    with contextlib.suppress(OSError):
        if isinstance(exc, KeyboardInterrupt):
            directory.record(sweep, "interrupted", INTERRUPTED)
        else:
            directory.record(sweep, "failed", f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
        # manifest.csv too: at Ctrl-C no end-of-job or end-of-sweep callback rewrites it, and it
        # said "running" for jobs the manifest recorded interrupted
        directory.write_table(sweep.dir)
