"""The launcher's own cost per job, on the operator grid (144 jobs), in one process:

- the driver's: composing each job's config, its batch key, pickling it (``_Dispatcher.next_batch``);
- the worker's: everything ``_batch.run_batch`` does but the runs (``zrp_ga.run.sweep.sweep_batch``):
  Hydra's records, logging, callbacks, the job configs typed, the console line.

The runs are made short (``population.max_evals``) since only what surrounds them is measured.
CPU seconds of this process (``time.process_time``), so that a busy machine changes them less
than wall time.

    python tests/launcher_overhead.py [--evals 100] [--profile driver|worker] [--lockstep false]
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import itertools
import pickle
import pstats
import sys
import tempfile
import time
import types
from pathlib import Path


def grid() -> list[list[str]]:
    jobs = itertools.product(["one_point", "two_point", "blend", "sbx"], ["gaussian", "polynomial", "uniform_reset"],
                             ["none", "segment"], ["none", "segment"], range(3))  # fmt: skip
    return [[f"crossover={c}", f"mutation={m}", f"inversion={i}", f"rotation={r}", f"seed={s}"] for c, m, i, r, s in jobs]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--evals", type=int, default=100)
    parser.add_argument("--profile", choices=["driver", "worker"])
    parser.add_argument("--lockstep", default="true")
    args = parser.parse_args()

    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import HydraContext, RunMode

    from hydra_plugins.zrp_ga_launcher import _batch, _compose, _workers
    from hydra_plugins.zrp_ga_launcher.config import ZrpGaLauncherConf
    from zrp_ga import config
    from zrp_ga.cli import main as cli_main
    from zrp_ga.cli.main import warm_up
    from zrp_ga.run import sweep as run_sweep

    sweep = Path(tempfile.mkdtemp(prefix="launcher_overhead-"))
    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        loader = _compose.ComposingLoader.wrap(GlobalHydra.instance().hydra.config_loader)
        master = loader.load_configuration(
            "config", ["experiment=operator_grid", f"population.max_evals={args.evals}", "hydra/launcher=local",
                       f"hydra.launcher.lockstep={args.lockstep}", f"hydra.sweep.dir={sweep}", "hydra.mode=MULTIRUN"],
            RunMode.MULTIRUN)  # fmt: skip
        jobs = grid()
        settings = ZrpGaLauncherConf(lockstep=args.lockstep == "true")
        context = HydraContext(config_loader=loader, callbacks=_Callbacks(master))
        launcher = types.SimpleNamespace(config=master, hydra_context=context, settings=settings,
                                         task_function=cli_main.main.__wrapped__)  # fmt: skip
        pool = types.SimpleNamespace(workers=[None, None])
        todo = collections.deque(enumerate(jobs))
        dispatcher = _workers._Dispatcher(launcher, pool, todo, sweep)
        warm_up(master)

        hydras = [0.0]  # in Hydra's own composition (a few per sweep, not per job)
        for name in ("load_sweep_config", "compute_defaults_list"):
            setattr(loader.loader, name, _timed(getattr(loader.loader, name), hydras))
        profile = cProfile.Profile()
        t0 = time.process_time()
        with profile if args.profile == "driver" else _nothing():
            batches = []
            while True:
                together, batch = dispatcher.next_batch()
                if not batch:
                    break
                batches.append((together, batch))
        driver = time.process_time() - t0
        sizes = [len(b) for _, b in batches]

        inside = [0.0]
        real = run_sweep.sweep_batch

        def timed(*a, **kw):
            t = time.process_time()
            try:
                return real(*a, **kw)
            finally:
                inside[0] += time.process_time() - t

        if args.lockstep == "true":
            run_sweep.sweep_batch = timed
        else:  # the task function's run (zrp_ga.cli.main.main calls zrp_ga.run.sweep.sweep_job)
            real = run_sweep.sweep_job
            run_sweep.sweep_job = timed
        t0 = time.process_time()
        with profile if args.profile == "worker" else _nothing():
            for together, batch in batches:
                if together:
                    _batch.run_batch([(idx, data) for idx, _, data in batch], context, launcher.task_function)
                else:
                    for idx, _, data in batch:
                        _batch.run_alone(idx, pickle.loads(data), context, launcher.task_function)
        worker = time.process_time() - t0
    n = len(jobs)
    print(f"{n} jobs in {len(batches)} batches of {min(sizes)}-{max(sizes)}; sweep directory {sweep}", file=sys.stderr)
    print(f"driver: {1000 * (driver - hydras[0]) / n:.1f} ms a job besides Hydra's {loader.hydra_compositions} compositions "
          f"({hydras[0]:.2f} s)", file=sys.stderr)  # fmt: skip
    where = "sweep_batch" if args.lockstep == "true" else "sweep_job, through Hydra's run_job"
    print(f"worker: {1000 * (worker - inside[0]) / n:.1f} ms a job besides the runs ({1000 * inside[0] / n:.1f} ms a job in {where})",
          file=sys.stderr)  # fmt: skip
    if args.profile:
        profile.dump_stats(f"launcher_overhead-{args.profile}.prof")
        pstats.Stats(profile, stream=sys.stderr).sort_stats("cumulative").print_stats(40)


def _timed(fn, total: list):
    def timed(*a, **kw):
        t = time.process_time()
        try:
            return fn(*a, **kw)
        finally:
            total[0] += time.process_time() - t

    return timed


class _Callbacks:
    """The app's Hydra callbacks, called as Hydra calls them around a job."""

    def __init__(self, master):
        from hydra.utils import instantiate

        self.callbacks = [instantiate(c) for c in master.hydra.callbacks.values()]

    def on_job_start(self, **kw):
        for c in self.callbacks:
            c.on_job_start(**kw)

    def on_job_end(self, **kw):
        for c in reversed(self.callbacks):
            c.on_job_end(**kw)


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


if __name__ == "__main__":
    main()
