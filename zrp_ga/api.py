"""The Python entry point for scripts and notebooks: :func:`calibrate`.

It composes the same config as ``zrp-ga`` (so that the defaults are the command line's) and
builds the problem from the arm and the measurements given in memory. Nothing is written unless
``out`` is given, and matplotlib's backend is left alone: figures are made on demand.

>>> import zrp_ga
>>> cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm")
>>> bool(cal.summary["validation_rms_mm"]["calibrated"] < 0.1 * cal.summary["validation_rms_mm"]["nominal"])
True
>>> cal.robot.n, list(cal.history.columns[:3])
(6, ['gen', 'nevals', 'best'])
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga import config
from zrp_ga.algorithms import Result
from zrp_ga.measurements import Measurements
from zrp_ga.problems import Task
from zrp_ga.robot import ZRPRobot


@dataclasses.dataclass
class Calibration:
    """What :func:`calibrate` found: the calibrated ``robot`` (in the measurements' frame for
    measured data), the optimiser's ``result``, the run's ``summary`` (as ``summary.json``) and
    the ``task`` it solved."""

    robot: ZRPRobot
    result: Result
    summary: dict
    task: Task

    @property
    def history(self):
        """One row per generation (pandas DataFrame), the columns of ``convergence.csv``."""
        return self.result.history

    def plot(self, ax=None):
        """The convergence curve (best cost per evaluation) on ``ax``, or on a new figure that is
        returned without being shown (``matplotlib.figure.Figure``: no backend is chosen)."""
        if ax is None:
            from matplotlib.figure import Figure

            ax = Figure(figsize=(6, 4)).subplots()
        h = self.history
        ax.semilogy(h["nevals"], h["best"], marker=".")
        ax.set_xlabel("evaluations")
        ax.set_ylabel("best cost")
        ax.set_title(self.summary["instance"], fontsize=9)
        return ax.figure


def _overrides(algorithm: str, seed: int, settings: dict[str, Any]) -> list[str]:
    """Command-line overrides of keyword settings: ``crossover="sbx"`` chooses an option,
    ``population={"mu": 50}`` sets keys, ``checkpoint_every=0`` sets a top-level key."""
    out = [f"algorithm={algorithm}", f"seed={seed}"]
    for key, value in settings.items():
        if isinstance(value, dict):
            out += [f"{key}.{k}={_value(v)}" for k, v in value.items()]
        else:
            out.append(f"{key}={_value(value)}")
    return out


def _value(v: Any) -> str:
    return "null" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def calibrate(
    robot: ZRPRobot | str | Path,
    data: Measurements | str | Path | None = None,
    *,
    validation: Measurements | str | Path | None = None,
    algorithm: str = "ga",
    seed: int = 0,
    out: str | Path | None = None,
    progress: bool = False,
    **settings: Any,
) -> Calibration:
    """Calibrate ``robot`` (a :class:`ZRPRobot`, a preset name or a robot file) on ``data``
    (:class:`~zrp_ga.measurements.Measurements` in an instrument's frame, or a measurement file
    in the zrp CSV format), validated on ``validation``; without data, on the simulated problem
    of the config (the paper's case study unless ``problem=...`` says otherwise).

    ``algorithm``: ``"ga"``, ``"lm"`` or ``"cmaes"``; ``settings``: any setting of ``zrp-ga``,
    e.g. ``population={"mu": 50, "generations": 30}``, ``crossover="sbx"``,
    ``problem={"cost": "nonlinear"}``. ``out``: a directory to write the run's files into (as
    ``zrp-ga`` writes them, with the same checks: a directory holding a run is refused).
    """
    from zrp_ga import robots
    from zrp_ga.problems import measured
    from zrp_ga.run import build, execute
    from zrp_ga.run.shared import Cache

    over = _overrides(algorithm, seed, settings)
    if data is not None and not isinstance(settings.get("problem"), str):  # problem={...}: the measured problem's keys
        over.insert(0, "problem=measured")
    cfg = config.load(over + ["problem.calibration_file=memory"] if data is not None else over)
    arm = robot if isinstance(robot, ZRPRobot) else robots.load(**_robot_source(robot))
    if data is None:
        task = config.instantiate(cfg.problem, "problem", robot=arm, run_seed=seed)
    else:
        conf = config.section(config.MeasuredConf, {k: v for k, v in cfg.problem.items() if k != "_target_"}, "problem")
        task = measured.from_measurements(arm, _measurements(data, arm, conf), _measurements(validation, arm, conf), conf)
    cache = Cache()  # the instance is the one built here, not the config's
    prepared = build.prepare(cfg, None if out is None else Path(out), cache=cache, task=task)
    if out is None:
        result, summary = execute.execute(prepared, None, progress, cache=cache)
    else:
        result, summary = execute.run_prepared(prepared, progress, cache=cache)
    x = np.array([summary["best_genome"][k] for k in task.problem.names])
    return Calibration(task.calibrated_robot(x), result, summary, task)


def _robot_source(robot: str | Path) -> dict:
    from zrp_ga import robots

    return {"name": str(robot)} if str(robot) in robots.names() else {"file": str(robot)}


def _measurements(data, robot: ZRPRobot, c: config.MeasuredConf) -> Measurements | None:
    if data is None or isinstance(data, Measurements):
        return data
    from zrp_ga import measurements

    fmt = measurements.zrp_format(robot.n, c.length_unit, c.angle_unit, c.orientation_convention)
    return measurements.read(Path(data), fmt, robot, c.drop_bad_rows)
