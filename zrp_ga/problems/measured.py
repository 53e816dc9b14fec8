"""Measured problems (``problem=measured``, ``problem=ur10_ipa``): poses read from files in an
instrument's frame. The nominal arm is registered to the calibration poses (base transform and
tool offset, :mod:`zrp_ga.registration`), then its parameters, the base point included (and the
hand orientation with measured orientations), are identified in the instrument's frame."""

from __future__ import annotations

import dataclasses
import importlib.resources
import logging
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga import measurements, metrics, records
from zrp_ga.config import Format, MeasuredConf, section
from zrp_ga.layout import Layout
from zrp_ga.measurements import Measurements
from zrp_ga.metrics import Judge
from zrp_ga.problem import CalibrationProblem
from zrp_ga.problems import Task, half_ranges
from zrp_ga.registration import Registration, register
from zrp_ga.robot import ZRPRobot

log = logging.getLogger(__name__)
POSE_ERRORS = "pose_errors.csv"


def data_path(name: str) -> Path:
    """A measurement file: ``pkg:REL`` is a file shipped in zrp_ga/data, anything else a path."""
    if name.startswith("pkg:"):
        return Path(str(importlib.resources.files("zrp_ga.data").joinpath(name[4:])))
    return Path(name).expanduser()


@dataclasses.dataclass
class MeasuredTask(Task):
    """A task on measured data: it also writes the registration, the calibrated arm in the
    instrument's frame and the position error of every pose before and after."""

    registration: Registration | None = None
    sets: dict[str, Measurements] = dataclasses.field(default_factory=dict)

    def errors(self, x: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Position errors (m) of every pose of each set, nominal and calibrated."""
        p = self.problem
        return {k: (metrics.position_errors(p.layout, p.nominal, np.zeros_like(x), m),
                    metrics.position_errors(p.layout, p.nominal, x, m)) for k, m in self.sets.items()}  # fmt: skip

    def report(self, x: np.ndarray) -> dict[str, Any]:
        mm = lambda e: {k: v * 1e3 if k != "poses" else v for k, v in metrics.summary(e).items()}  # noqa: E731
        return {
            "registration": self.registration.to_dict(),
            "position_error_mm": {k: {"nominal": mm(b), "calibrated": mm(a)} for k, (b, a) in self.errors(x).items()},
        }

    def write(self, out: Path, x: np.ndarray) -> None:
        records.write_json(out / "registration.json", self.registration.to_dict())
        self.calibrated_robot(x).to_yaml(out / "calibrated_robot.yaml")
        rows = [{"set": k, "line": int(line), "nominal_mm": b * 1e3, "calibrated_mm": a * 1e3}
                for k, (before, after) in self.errors(x).items()
                for line, b, a in zip(self.sets[k].lines, before, after)]  # fmt: skip
        records.write_csv(out / POSE_ERRORS, rows)


def build(robot: ZRPRobot, seed: int, **settings) -> MeasuredTask:
    """Read and split the measurement files of ``settings`` (``zrp_ga.config.MeasuredConf``'s
    keys), then :func:`from_measurements`."""
    c: MeasuredConf = section(MeasuredConf, settings, "problem")
    fmt = measurements.UR10_IPA if c.format is Format.ur10_ipa else measurements.zrp_format(robot.n, c.length_unit, c.angle_unit)
    calib = measurements.read(data_path(c.calibration_file), fmt, robot.n, c.drop_bad_rows)
    if c.validation_file:
        val = measurements.read(data_path(c.validation_file), fmt, robot.n, c.drop_bad_rows)
    elif c.validation_fraction:
        calib, val = measurements.split(calib, c.validation_fraction, np.random.default_rng([seed, 2]))
    else:
        val = None
    return from_measurements(robot, calib, val, c)


def from_measurements(robot: ZRPRobot, calib: Measurements, val: Measurements | None, c: MeasuredConf) -> MeasuredTask:
    """Register ``robot`` to the calibration poses, then the calibration problem in the
    instrument's frame; ``val`` (or None) validates."""
    if c.use_orientation and calib.R is None:
        raise ValueError(f"problem.use_orientation: {calib.source} has no orientation columns")
    if c.use_weights and calib.std is None:
        raise ValueError(f"problem.use_weights: {calib.source} has no standard-deviation columns")
    reg = register(robot, calib.q, calib.p, rotations=calib.R if c.use_orientation else None)
    log.info("registered %s to %s: %.3f mm RMS, tool offset %s mm", robot.name, calib.source, reg.rms * 1e3,
             np.round(reg.tool * 1e3, 2))  # fmt: skip
    nominal = reg.apply(robot)
    layout = Layout(robot.n, base=True, hand=bool(c.use_orientation))
    half = half_ranges(c, layout)
    data = calib.for_calibration(c.use_orientation, c.use_weights)
    problem = CalibrationProblem(nominal, data, layout, -half, half, c.cost, c.norm, c.orientation_weight, c.kernel)
    validation = val.for_calibration() if val is not None else None
    name = c.name or f"{robot.name}-{Path(calib.source).stem}"
    files = {"calibration": calib.source, "validation": val.source if val is not None else None}
    sets = {"calibration": calib, **({"validation": val} if val is not None else {})}
    return MeasuredTask(name, problem, Judge(layout, nominal, validation), robot, {"kind": "measured", "files": files},
                        registration=reg, sets=sets)  # fmt: skip
