"""``zrp-ga``: the Hydra app. ``zrp-ga`` alone runs the paper's case study; any setting can be
overridden (``zrp-ga problem=multipose seed=3``), swept (``zrp-ga -m crossover=glob(*)``) or
inspected with Hydra's own flags (``--cfg job``, ``--info defaults``, ``--help``).

:func:`prepare` checks a config and builds its objects (robot, problem, optimiser) from their
``_target_``; :func:`run` optimises, writes the run's files and returns the objective, so that
Hydra's sweepers can optimise it; :func:`main` is the ``@hydra.main`` entry point and :func:`cli`
the console script, which turns every error in the user's input into one line and exit code 2.
Heavy modules are imported where they are used, so that ``--help`` starts fast.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import random
import signal
import sys
from pathlib import Path
from typing import Any

import hydra
from omegaconf import DictConfig, OmegaConf

from zrp_ga import budget, checks, config
from zrp_ga.config import ConfigError

log = logging.getLogger("zrp_ga")
config.register()
import hydra_plugins.zrp_ga_launcher.launcher  # noqa: E402,F401 (hydra/launcher=zrp_ga and =local; see _register_launcher)

RUN_FILES = ("convergence.csv", "summary.json")


@dataclasses.dataclass
class Prepared:
    """A checked config and what it builds."""

    cfg: DictConfig
    task: Any  # zrp_ga.problems.Task
    algorithm: Any  # zrp_ga.algorithms.Algorithm
    state: dict | None  # a checkpoint's state when resuming
    out: Path | None
    instance: str | None = None  # the problem instance's key, for cached diagnostics (sweep jobs)


_prepared: tuple[str, Prepared] | None = None  # what the Hydra callback built for the run about to start


def _task_config(cfg: DictConfig) -> DictConfig:
    return OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]) if "hydra" in cfg else cfg


def prepare(cfg: DictConfig, out: Path | None) -> Prepared:
    """Check ``cfg`` and build its objects, before any work and before ``out`` is created (None:
    no run directory); with ``resume``, the checkpoint's config instead. Every error names what
    is wrong in one line."""
    global _prepared
    cfg = _task_config(cfg)
    key = OmegaConf.to_yaml(cfg) + str(out)
    if _prepared is not None and _prepared[0] == key:
        return _prepared[1]
    state = None
    if cfg.get("resume"):
        out, state, cfg = _resume(cfg)
    elif out is not None:
        _check_writable(out)
        if any((out / f).exists() for f in RUN_FILES):
            raise ConfigError(f"output directory {out} already holds a run; choose another hydra.run.dir, "
                              f"or continue it with resume={out}")  # fmt: skip
    prepared = _build(cfg, out, state)
    _prepared = (key, prepared)
    return prepared


def _build(cfg: DictConfig, out: Path | None, state: dict | None, reuse: bool = False) -> Prepared:
    """The robot, problem and optimiser of the checked task config ``cfg``. ``reuse``: take the
    robot and problem instance from the instances this process built before (sweep jobs: the
    instances are pure functions of their config, and building one costs more than many runs)."""
    from threadpoolctl import threadpool_limits

    if cfg.checkpoint_every < 0:
        raise ConfigError(f"checkpoint_every: must be >= 0, got {cfg.checkpoint_every}")
    checks.run_settings(cfg)  # seeds, an optimiser's needs of the shared settings (zrp_ga.checks)
    with threadpool_limits(limits=1, user_api="blas"):  # the problem's SVDs: see execute
        key, task = _instance(cfg, reuse)
        algorithm = config.instantiate(cfg.algorithm, "algorithm")
    if state is not None and not algorithm.checkpointable:
        raise ConfigError(f"resume: {type(algorithm).__name__} runs keep no checkpoints")
    from zrp_ga import summary

    if summary.over_floor(cfg) and hasattr(task, "judged"):
        raise ConfigError("objective: over_floor divides by a calibration's floor; this problem kind has none (use final_cost)")
    return Prepared(cfg, task, algorithm, state, out, instance=key if reuse else None)


_instances: dict[str, Any] = {}  # instance key -> Task, the last few built by sweep jobs of this process
MAX_INSTANCES = 8


def _instance(cfg: DictConfig, reuse: bool) -> tuple[str, Any]:
    """The problem instance (a Task) of ``cfg`` and its key: the resolved robot and problem
    settings and the seed, as JSON."""
    import json

    parts = {k: OmegaConf.to_container(cfg[k], resolve=True, enum_to_str=True) for k in ("robot", "problem")}
    key = json.dumps({**parts, "seed": int(cfg.seed)}, sort_keys=True)
    if reuse and key in _instances:
        return key, _instances[key]
    robot = config.instantiate(cfg.robot, "robot")
    budget.check_config(cfg, robot)  # memory and time, before the problem is built (zrp_ga.budget)
    task = config.instantiate(cfg.problem, "problem", robot=robot, run_seed=int(cfg.seed))
    if reuse:
        _instances[key] = task
        while len(_instances) > MAX_INSTANCES:
            del _instances[next(iter(_instances))]
    return key, task


def _check_writable(out: Path) -> None:
    """The run directory ``out`` can be created and written: no file in the way, and the first
    existing folder on the way to it is writable."""
    for folder in (out, *out.parents):
        if folder.exists():
            if not folder.is_dir():
                raise ConfigError(f"hydra.run.dir: cannot create {out}: {folder} is a file, not a directory")
            if not os.access(folder, os.W_OK | os.X_OK):
                raise ConfigError(f"hydra.run.dir: cannot write into {folder} (permission denied)")
            return


def _resume(cfg: DictConfig) -> tuple[Path, dict, DictConfig]:
    """The run directory, checkpoint state and config of ``resume=DIR``; the other settings of
    the command line are refused (the run continues with its own)."""
    from zrp_ga import checkpoint

    out = Path(cfg.resume).expanduser()
    if not out.is_dir():
        raise ConfigError(f"resume: {out} is not a run directory")
    others = _other_overrides()
    if others:
        raise ConfigError(f"resume: a run continues with its own config; drop {' '.join(others)} "
                          "(or start a new run with them)")  # fmt: skip
    state = checkpoint.load(out / checkpoint.NAME)
    return out, state, OmegaConf.create(state.pop("config"))


def _other_overrides() -> list[str]:
    """The command line's settings other than resume, progress and Hydra's own."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return []
    return [o for o in HydraConfig.get().overrides.task if not o.lstrip("+~").startswith(("resume=", "progress=", "hydra."))]


def run(cfg: DictConfig, out_dir: str | Path, progress: bool | None = None) -> float:
    """Run one calibration as configured, write its files into ``out_dir`` (or, resuming, the
    run's own directory) and return the objective (``objective``: the final cost, or the final
    cost over the instance's floor). ``progress``: show the
    progress line (default: ``cfg.progress``)."""
    global _prepared
    p = prepare(cfg, Path(out_dir))
    _prepared = None
    return _run_prepared(p, p.cfg.progress if progress is None else progress)


def _run_prepared(p: Prepared, progress: bool) -> float:
    """Run ``p`` in ``p.out`` with ``status.json`` telling where it is: running, then done,
    failed or interrupted; the final cost."""
    from zrp_ga import records

    p.out.mkdir(parents=True, exist_ok=True)
    records.write_json(p.out / "status.json", {"status": "running"})
    try:
        _, written = execute(p, p.out, progress)
    except BaseException as exc:  # Ctrl-C or a crash: say so where the report will look
        status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
        records.write_json(p.out / "status.json", {"status": status, "error": repr(exc)})
        raise
    records.write_json(p.out / "status.json", {"status": "done"})
    return float(written["objective"])


def execute(p: Prepared, out: Path | None, progress: bool) -> tuple[Any, dict]:
    """Seed, optimise with the callbacks, summarise; with ``out``, write the run's files there
    (a convergence log and checkpoints as it goes, the rest at the end). Returns the result and
    the summary."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from zrp_ga import callbacks, checkpoint, summary

    cfg, task = p.cfg, p.task
    seed = int(cfg.seed)
    random.seed(seed)  # DEAP's own operators draw from `random`
    np.random.seed(seed % 2**32)
    rng = np.random.default_rng([seed, 0])  # the optimiser's stream; problems draw from [seed, 1] and up
    resolved = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    cbs = [callbacks.Timing(), callbacks.Validation(task.judge)]
    if out is not None:
        cbs.append(callbacks.ConvergenceLog(out / callbacks.CONVERGENCE, None if p.state is None else int(p.state["gen"])))
        if p.algorithm.checkpointable and cfg.checkpoint_every:
            cbs.append(callbacks.Checkpoint(out / checkpoint.NAME, int(cfg.checkpoint_every), resolved))
    if progress:
        cbs.append(callbacks.Progress())
    with threadpool_limits(limits=1, user_api="blas"):  # one BLAS thread: 50x faster on a busy 2-core machine
        diagnostics = summary.diagnostics(task, first=p.state is None, key=p.instance)
        result = p.algorithm.run(task.problem, rng, cbs, p.state)
    written, x = summary.build(task, result, cfg, resolved, diagnostics, p.algorithm.elapsed())
    with threadpool_limits(limits=1, user_api="blas"):
        written["objective"] = summary.objective(cfg, task, written, p.instance)
    if out is not None:
        summary.write(out, task, result, written, x)
    for w in written["warnings"]:
        log.warning(w)
    return result, written


def warm_up(cfg: DictConfig) -> None:
    """Load what the runs of a sweep need (modules, compiled code, the base config's problem
    instance) by building the sweep's base config and running one generation of it, writing
    nothing. zrp_ga's launcher calls it in each worker while Hydra still checks the sweep's jobs;
    whatever fails here fails again, with its message, in the job itself."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from zrp_ga import callbacks, checkpoint, records, summary  # noqa: F401 (imported for the runs)

    try:
        p = _build(_task_config(cfg), None, None, reuse=True)
        with threadpool_limits(limits=1, user_api="blas"):
            p.algorithm.setup(p.task.problem, np.random.default_rng(0))
            p.algorithm.initialize()
            if p.algorithm.has_next():
                p.algorithm.step()
            p.task.judge(p.algorithm.current()[0])
    except Exception as exc:
        log.debug("warm-up: %s", exc)


@hydra.main(version_base="1.3", config_path="pkg://zrp_ga.conf", config_name="config")
def main(cfg: DictConfig) -> float:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from zrp_ga import hydra_callbacks, summary

    hc = HydraConfig.get()
    out = Path(hc.runtime.output_dir)
    multirun = hc.mode == RunMode.MULTIRUN
    if multirun:
        try:
            objective = sweep_job(cfg, out)
        except KeyboardInterrupt:
            hydra_callbacks.record("interrupted", "KeyboardInterrupt: continue by running the sweep again")
            raise
    else:
        _started.append(Path(cfg.resume) if cfg.get("resume") else out)
        objective = run(cfg, out, progress=cfg.progress)
        out = _started[-1]
    summary.console(out, hc, multirun)
    return objective


def sweep_job(cfg: DictConfig, out: Path) -> float:
    """Run a job of a sweep in its directory ``out`` and return the final cost, continuing
    whatever a killed run of the same sweep left there: a finished run is kept as it is, a run
    with a checkpoint continues from it (to the same files an uninterrupted run writes), a
    partial run without one starts again. A run of another config in ``out`` is refused."""
    import json

    from zrp_ga import checkpoint

    cfg = _task_config(cfg)
    if cfg.get("resume"):
        raise ConfigError("resume: a sweep continues when it is run again into the same hydra.sweep.dir")
    done = out / "summary.json"
    if run_status(out) == "done" and done.exists():
        written = json.loads(done.read_text())
        _same_run(cfg, written.get("config"), out)
        log.info("%s: finished before; kept", out)
        value = written.get("objective", written["final_cost"])
        return float("nan") if value is None else float(value)
    state = None
    if (out / checkpoint.NAME).exists():
        try:
            state = checkpoint.load(out / checkpoint.NAME)
        except ValueError as exc:  # a checkpoint is written atomically: this is a damaged disk or a foreign file
            log.warning("%s; the run starts again", exc)
        else:
            _same_run(cfg, state.pop("config"), out)
            log.info("%s: continues from its checkpoint after generation %d", out, int(state["gen"]))
    return _run_prepared(_build(cfg, out, state, reuse=True), progress=False)


def run_status(out: Path) -> str | None:
    """The ``status`` in ``out/status.json``; None when there is none (or it cannot be read)."""
    import json

    try:
        return json.loads((out / "status.json").read_text()).get("status")
    except (OSError, ValueError, AttributeError):
        return None


def _same_run(cfg: DictConfig, stored: dict | None, out: Path) -> None:
    """Refuse to continue the run in ``out`` when its config (``stored``, from its summary or
    checkpoint) is not ``cfg`` (the progress line and resume setting aside)."""

    def plain(o: Any) -> Any:  # as JSON holds it: non-finite floats as null
        if isinstance(o, dict):
            return {str(k): plain(v) for k, v in o.items()}
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

    return min(leaves(a, b, ""), key=lambda k: k.count("."))


_started: list[Path] = []  # where the run writes, for the interrupt message


def cli() -> None:
    """The console script: :func:`main`, with the errors in the user's input (a bad key or value,
    a missing or malformed file) printed as one line, exit code 2, and Ctrl-C (or SIGTERM, as a
    cluster's job limit sends it) as a hint to resume.

    Hydra prints composition errors over several lines and exits with 1; with
    ``HYDRA_FULL_ERROR`` set it raises them instead, which is how they are caught here (set it
    yourself to see Hydra's full traceback)."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from zrp_ga.hydra_callbacks import Refused

    full = os.environ.get("HYDRA_FULL_ERROR") == "1"
    os.environ["HYDRA_FULL_ERROR"] = "1"
    signal.signal(signal.SIGTERM, _stop)  # a job limit or shutdown: stop as at Ctrl-C, checkpoints saved
    _register_launcher()
    from hydra_plugins.zrp_ga_launcher._compose import compose_once, group_options_once

    try:
        with compose_once(), group_options_once():
            main()
    except (HydraException, OmegaConfBaseException, ValueError, OSError, MemoryError, Refused) as exc:
        if full:
            raise
        print(f"zrp-ga: error: {one_line(getattr(exc, 'error', exc))}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        from zrp_ga import hydra_callbacks

        sweep = hydra_callbacks.sweep_dir
        if sweep is not None:
            print(f"\nzrp-ga: interrupted; the finished jobs are kept in {sweep} and the interrupted ones continue "
                  f"from their checkpoints: continue with the same command and hydra.sweep.dir={sweep}",
                  file=sys.stderr)  # fmt: skip
        else:
            where = _started[-1] if _started else "the run directory"
            print(f"\nzrp-ga: interrupted; the checkpoint and convergence.csv in {where} are complete up to the last "
                  f"finished generation: continue with  zrp-ga resume={where}", file=sys.stderr)  # fmt: skip
        sys.exit(130)


def _stop(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _register_launcher() -> None:
    """zrp_ga's launcher, registered by hand as well: Hydra finds plugins by listing the modules
    of the ``hydra_plugins`` namespace package, which an editable install (``pip install -e``)
    does not let it list."""
    from hydra.core.plugins import Plugins

    from hydra_plugins.zrp_ga_launcher.launcher import ZrpGaLauncher

    Plugins.instance().register(ZrpGaLauncher)


def one_line(exc: BaseException) -> str:
    """An error on one line: what is wrong and the key (or the options) it concerns."""
    for e in (exc.__cause__, exc):
        lines = [line.strip() for line in str(e or "").splitlines() if line.strip()]
        key = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("full_key:")), None)
        if key:
            return f"{lines[0]} (key: {key})"
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()] or [type(exc).__name__]
    heads = [k for k, line in enumerate(lines) if line.startswith("Available options in")]
    if heads:
        options = [line for line in lines[heads[0] + 1 :] if not line.startswith(("Config search path", "provider="))]
        return f"{lines[0]}; {lines[heads[0]].rstrip(':').lower()}: {', '.join(options)}"
    if isinstance(exc, OSError) and exc.filename:
        return f"{exc.filename}: {exc.strerror}"
    return lines[0]


if __name__ == "__main__":
    cli()
