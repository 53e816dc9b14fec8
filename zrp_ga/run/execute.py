"""A prepared run executed alone and recorded: seeded, optimised with its callbacks, summarised,
its files written into its directory with ``status.json`` saying where it is
(:mod:`zrp_ga.run.assembly`, shared with runs evolved together).

Nothing here knows Hydra: the command line (``zrp_ga.cli.main``), :func:`zrp_ga.calibrate`, the
experiments and the launcher's workers all run through :func:`run`, :func:`run_prepared` or the
sweep's jobs (:mod:`zrp_ga.run.sweep`), on the typed config.
"""

from __future__ import annotations

import contextlib
import logging
import random
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from zrp_ga.core.schema import Config
from zrp_ga.run import assembly
from zrp_ga.run.assembly import Ran
from zrp_ga.run.build import Prepared, build, prepare
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import CACHE, Cache

log = logging.getLogger("zrp_ga")


def run(cfg: Config, out: str | Path, progress: bool | None = None, overrides: Sequence[str] = (),
        choices: dict[str, Any] | None = None) -> float:  # fmt: skip
    """Check and run one calibration as configured, write its files into ``out`` (or, resuming,
    the run's own directory) and return the objective (``objective``: the final cost, or the
    final cost over the instance's floor). ``progress``: show the progress line (default:
    ``cfg.progress``); ``overrides``, ``choices``: see :func:`zrp_ga.run.build.prepare`."""
    p = prepare(cfg, Path(out), overrides, choices)
    return objective(run_prepared(p, p.cfg.progress if progress is None else progress))


def objective(ran: Ran) -> float:
    """The objective of what :func:`run_prepared` returned."""
    return float(ran[1]["objective"])


def run_prepared(p: Prepared, progress: bool, sweep: Sweep | None = None, cache: Cache = CACHE) -> Ran:
    """Run ``p`` in ``p.out`` (None: no files) with ``status.json`` telling where it is: running,
    then done, failed or interrupted (and the manifest's line for a ``sweep``'s job); the result
    and the summary (:func:`execute`)."""
    with contextlib.ExitStack() as held:
        try:
            assembly.begin(p, held)
        except BaseException as exc:  # its directory is another run's (or cannot be written): the manifest only
            assembly.stopped(None, sweep, exc)
            raise
        try:
            ran = execute(p, progress, sweep, cache)
        except BaseException as exc:  # Ctrl-C or a crash (a full disk): say so where the report will look
            assembly.stopped(p, sweep, exc)
            raise
        assembly.done(p, sweep)
    return ran


def execute(p: Prepared, progress: bool, sweep: Sweep | None = None, cache: Cache = CACHE) -> Ran:
    """Seed, optimise with the callbacks, summarise; with ``p.out``, write the run's files there
    (a convergence log and checkpoints as it goes, the rest at the end). Returns the result and
    the summary."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    s = assembly.start(p, progress, study=assembly.study(p, sweep))
    random.setstate(s.random_state)  # DEAP's own operators draw from `random`
    np.random.seed(int(p.cfg.seed) % 2**32)
    with threadpool_limits(limits=1, user_api="blas"):  # one BLAS thread: 50x faster on a busy 2-core machine
        figures = assembly.diagnostics(p, cache, sweep)
        result = p.algorithm.run(p.task.problem, s.rng, s.callbacks, p.state)
        return assembly.finish(p, result, figures, cache, sweep)


def warm_up(cfg: Config, cache: Cache = CACHE) -> None:
    """Load what the runs of a sweep need (modules, compiled code, the base config's problem
    instance) by building the sweep's base config and running one generation of it, writing
    nothing. zrp_ga's launcher calls it (through ``zrp_ga.cli.main.warm_up``) in each worker
    while Hydra still checks the sweep's jobs; whatever fails here fails again, with its message,
    in the job itself."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from zrp_ga.core import compiled
    from zrp_ga.io import records  # noqa: F401 (imported for the runs)
    from zrp_ga.run import callbacks, checkpoint, summary, together  # noqa: F401 (imported for the runs)

    compiled.prefer_compiled()  # a sweep's runs pay for compiling: load the kernels here, once, not in each worker
    try:
        p = build(cfg, None, None, {}, cache)
        with threadpool_limits(limits=1, user_api="blas"):
            p.algorithm.setup(p.task.problem, np.random.default_rng(0))
            p.algorithm.initialize()
            if p.algorithm.has_next():
                p.algorithm.step()
            x = p.algorithm.current()[0]
            if x is not None:
                p.task.judge(x)
    except Exception as exc:
        log.debug("warm-up: %s", exc)
