"""A run checked and built from its config, before any work and before its directory exists.

:func:`prepare` is the one check every entry point passes (``zrp-ga``, :func:`zrp_ga.calibrate`,
the experiments, the launcher's workers): the config's values, the run directory (writable,
holding no other run), ``resume`` (a checkpoint, no other settings), what the problem kind
allows (``objective=over_floor`` needs a floor). Every error is a
:class:`~zrp_ga.core.schema.ConfigError` (or an OSError) naming what is wrong in one line.

The config is the typed :class:`~zrp_ga.core.schema.Config` (Hydra's composition, the command
line's, turned typed by :mod:`zrp_ga.config`; a checkpoint's, by
:func:`~zrp_ga.core.schema.from_dict`); its robot, problem and optimiser are built from their
``_target_`` specs by :func:`zrp_ga.core.targets.create`.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from zrp_ga.algorithms import Algorithm, State
from zrp_ga.core import checks, schema, targets
from zrp_ga.core.schema import Config, ConfigError, Objective
from zrp_ga.problems import Task
from zrp_ga.problems.protocol import SelfJudging
from zrp_ga.run import budget, directory
from zrp_ga.run.shared import CACHE, Cache

# Command-line settings that a resumed run accepts besides resume (they change no result).
RESUME_KEEPS = ("resume=", "progress=", "hydra.")


@dataclasses.dataclass
class Prepared:
    """A checked config and what it builds."""

    cfg: Config  # the run's config
    task: Task  # the problem instance
    algorithm: Algorithm  # the optimiser, built from cfg.algorithm
    state: State | None  # a checkpoint's state when resuming
    out: Path | None  # the run directory (None: no files)
    instance: str  # the problem instance's key (zrp_ga.run.shared)
    choices: dict[str, Any] = dataclasses.field(default_factory=dict)  # the config's group options, for summary.json
    resolved: dict[str, Any] = dataclasses.field(default_factory=dict)  # cfg as plain values (schema.to_dict), for the files


def prepare(cfg: Config, out: Path | None, overrides: Sequence[str] = (), choices: dict[str, Any] | None = None,
            cache: Cache = CACHE, task: Task | None = None) -> Prepared:  # fmt: skip
    """Check ``cfg`` and build its objects, before ``out`` is created (None: no run directory).
    With ``resume``, the checkpoint's run instead, in its own directory; ``overrides``: the
    command line's settings, of which a resumed run accepts none but ``progress``. ``choices``:
    the config groups' options (Hydra's), recorded in ``summary.json``. ``task``: the problem
    instance, when it was built from data in memory (:func:`zrp_ga.calibrate`) rather than
    from the config's files (then with a ``cache`` of its own: the key does not describe it)."""
    state = None
    if cfg.resume:
        out, state, cfg = _resume(cfg.resume, overrides)
        choices = state.pop("choices", None) or {}
        recorded = state.pop("inputs", None)
        _not_in_use(out)  # before any work: building the problem and hashing its files
        p = build(cfg, out, state, choices, cache, task)
        check_inputs(p, recorded)
        return p
    elif out is not None:
        check_writable(out)
        if directory.holds_run(out):
            raise ConfigError(f"output directory {out} already holds a run; choose another hydra.run.dir, "
                              f"or continue it with resume={out}")  # fmt: skip
        _not_in_use(out)
    return build(cfg, out, state, choices or {}, cache, task)


def build(cfg: Config, out: Path | None, state: State | None, choices: dict[str, Any], cache: Cache = CACHE,
          task: Task | None = None) -> Prepared:  # fmt: skip
    """The robot, problem and optimiser of the checked task config ``cfg``; the problem
    instance ``task`` if given, else from ``cache`` when it was built before."""
    from threadpoolctl import threadpool_limits

    if cfg.checkpoint_every < 0:
        raise ConfigError(f"checkpoint_every: must be >= 0, got {cfg.checkpoint_every}")
    checks.run_settings(cfg)  # seeds, an optimiser's needs of the shared settings (zrp_ga.core.checks)
    resolved = schema.to_dict(cfg)
    key = instance_key(cfg, resolved)
    if task is None:
        def limited() -> Task:
            with threadpool_limits(limits=1, user_api="blas"):  # the problem's SVDs: see zrp_ga.run.execute
                return _instance(cfg)

        task = cache.instance(key, limited)  # built once per instance (threadpoolctl's set-up costs ms)
    algorithm: Algorithm = targets.create(cfg.algorithm, "algorithm")
    if state is not None and not algorithm.checkpointable:
        raise ConfigError(f"resume: {type(algorithm).__name__} runs keep no checkpoints")
    if cfg.objective is Objective.over_floor and isinstance(task, SelfJudging):
        raise ConfigError("objective: over_floor divides by a calibration's floor; this problem kind has none (use final_cost)")
    return Prepared(cfg, task, algorithm, state, out, key, dict(choices), resolved)


def instance_key(cfg: Config, resolved: dict[str, Any] | None = None) -> str:
    """The problem instance's key: the robot and problem settings as plain values and the seed,
    as JSON, with the size and modification time of the files they name (an edited file is
    another instance). ``resolved``: ``cfg`` as plain values already (:func:`schema.to_dict`)."""
    parts = {k: resolved[k] if resolved is not None else schema.to_dict(getattr(cfg, k)) for k in ("robot", "problem")}
    return json.dumps({**parts, "seed": int(cfg.seed), "files": _stamps(cfg)}, sort_keys=True)


def _stamps(cfg: Config) -> list[list[str | int | None]]:
    from zrp_ga.data import resolve

    out: list[list[str | int | None]] = []
    for name in (cfg.robot.file, *(schema.setting(cfg.problem, k) for k in DATA_KEYS)):
        if name:
            try:
                st = resolve(str(name)).stat()
                out.append([str(name), st.st_size, st.st_mtime_ns])
            except OSError:
                out.append([str(name), None, None])
    return out


def _instance(cfg: Config) -> Task:
    robot = targets.create(cfg.robot, "robot")
    budget.check_config(cfg, robot)  # memory and time, before the problem is built (zrp_ga.run.budget)
    task: Task = targets.create(cfg.problem, "problem", robot=robot, run_seed=int(cfg.seed))
    return task


def _not_in_use(out: Path) -> None:
    """Refuse ``out`` now, before any work, when another run holds its lock (the run itself
    holds it throughout: :func:`zrp_ga.run.execute.run_prepared`)."""
    if out.is_dir() and os.access(out, os.W_OK):
        with directory.locked(out):
            pass


def check_writable(out: Path) -> None:
    """The run directory ``out`` can be created and written: no file in the way, and the first
    existing folder on the way to it is writable."""
    for folder in (out, *out.parents):
        if folder.exists():
            if not folder.is_dir():
                raise ConfigError(f"hydra.run.dir: cannot create {out}: {folder} is a file, not a directory")
            if not os.access(folder, os.W_OK | os.X_OK):
                raise ConfigError(f"hydra.run.dir: cannot write into {folder} (permission denied)")
            return


def _resume(resume: str, overrides: Sequence[str]) -> tuple[Path, State, Config]:
    """The run directory, checkpoint state and config of ``resume=DIR``; the other settings of
    the command line are refused (the run continues with its own)."""
    from zrp_ga.run import checkpoint

    out = Path(resume).expanduser()
    if not out.is_dir():
        raise ConfigError(f"resume: {out} is not a run directory")
    others = [o for o in overrides if not o.lstrip("+~").startswith(RESUME_KEEPS)]
    if others:
        raise ConfigError(f"resume: a run continues with its own config; drop {' '.join(others)} "
                          "(or start a new run with them)")  # fmt: skip
    if not (out / directory.CHECKPOINT).exists() and directory.status(out) == "done":
        raise ConfigError(f"resume: {out} is a finished run written without its final checkpoint (a sweep's run, "
                          f"outputs=study): nothing to continue; its results are in {out / directory.SUMMARY}")  # fmt: skip
    state = checkpoint.load(out / directory.CHECKPOINT)
    return out, state, typed(state.pop("config"))


def typed(stored: dict[str, Any]) -> Config:
    """A config read back from a file (plain values: Enums as their strings) with the schema's
    types again, so that a resumed run sees the same config as the run it continues; a value
    the schema refuses is a ConfigError naming the key."""
    try:
        return schema.from_dict(stored)
    except ConfigError as exc:
        raise ConfigError(f"resume: the checkpoint's config is not valid at {exc}") from None


DATA_KEYS = ("calibration_file", "validation_file")  # the problem's files, hashed into a checkpoint


def inputs(cfg: Config, task: Task) -> dict[str, str]:
    """What a run's result depends on besides its config, as hashes: the robot as built (its
    arrays and joint types) and the contents of the problem's data files, so that a resumed run
    can tell that they changed since its checkpoint."""
    import hashlib

    import numpy as np

    from zrp_ga.data import resolve

    h = hashlib.sha256()
    robot = task.robot
    for f in dataclasses.fields(robot):
        v = getattr(robot, f.name)
        if isinstance(v, np.ndarray):
            h.update(f.name.encode() + np.ascontiguousarray(v, dtype=float).tobytes())
        elif isinstance(v, str):
            h.update(f.name.encode() + v.encode())
    out = {"robot": h.hexdigest()}
    for key in DATA_KEYS:
        name = schema.setting(cfg.problem, key)
        if name:
            try:
                out[f"problem.{key}"] = hashlib.sha256(resolve(str(name)).read_bytes()).hexdigest()
            except OSError:
                out[f"problem.{key}"] = "unreadable"
    return out


def check_inputs(p: Prepared, recorded: dict[str, str] | None, what: str = "resume") -> None:
    """Refuse to continue a checkpoint whose robot or data files (``recorded``:
    :func:`inputs` when it was written) are not those of ``p`` now."""
    if not recorded:
        return
    now = inputs(p.cfg, p.task)
    changed = [k for k in recorded if now.get(k) != recorded[k]]
    if changed:
        k = changed[0]
        name = "the robot" if k == "robot" else f"{k} ({schema.setting(p.cfg.problem, k.split('.', 1)[1])})"
        raise ConfigError(f"{what}: {name} changed since the checkpoint in {p.out} was written; "
                          "the run cannot continue on it (start a new run)")  # fmt: skip
