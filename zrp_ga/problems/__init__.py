"""Problem kinds: what the config's ``problem`` group builds. Each kind is one module here with a
``build(robot, run_seed, **settings) -> Task`` function and one config file in ``conf/problem``
naming it by ``_target_`` (and a schema in :mod:`zrp_ga.config`). ``run_seed`` is the run's
seed; ``settings`` are the ``problem`` node's keys, its own ``seed`` among them (a named
instance's, which the run's seed must not replace).

A :class:`Task` is a problem instance (:class:`zrp_ga.problem.CalibrationProblem`, what the
optimisers see) with what judges its answers (:class:`zrp_ga.metrics.Judge`: validation poses,
the truth in simulation) and what a run writes about it beyond the common files.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from zrp_ga.config import ProblemConf
from zrp_ga.layout import Layout, fixed_summary, mask
from zrp_ga.metrics import Judge
from zrp_ga.problem import CalibrationProblem
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


@dataclasses.dataclass
class Task:
    """A calibration problem instance, named, with its judge; ``robot`` is the arm as given
    (before any registration), ``info`` goes into ``summary.json``, ``warnings`` (found while
    building it) into its warnings. ``nominal_if_worse``: a result that fits the calibration
    data worse than the nominal arm is replaced by the nominal arm (:mod:`zrp_ga.summary`)."""

    name: str
    problem: CalibrationProblem
    judge: Judge
    robot: ZRPRobot
    info: dict[str, Any] = dataclasses.field(default_factory=dict)
    warnings: list[str] = dataclasses.field(default_factory=list)
    nominal_if_worse: ClassVar[bool] = False

    @property
    def truth(self) -> Array | None:
        return self.judge.truth

    def calibrated_robot(self, x: Array) -> ZRPRobot:
        p = self.problem
        return p.layout.robot(p.nominal, x, name=f"{p.nominal.name} calibrated")

    def export(self, x: Array) -> tuple[ZRPRobot, Array | None, dict[str, Array]]:
        """The calibrated arm as robot files carry it: the arm, the pose (4, 4) of its base frame
        in the outer frame (None: the same), and tool frames (4, 4) in its hand frame by name."""
        return self.calibrated_robot(x), None, {}

    def report(self, x: Array) -> dict[str, Any]:
        """Entries of this kind for ``summary.json`` about the calibrated genome ``x``."""
        return {}

    def write(self, out: Path, x: Array) -> None:
        """Files of this kind beyond the common ones."""


def masked(c: ProblemConf, layout: Layout, info: dict[str, Any] | None = None) -> Layout:
    """``layout`` with the parameters ``problem.fixed`` / ``problem.free`` name held at nominal
    (:func:`zrp_ga.layout.mask`; an unknown name is one line naming the key and the valid
    names); what is fixed goes into ``info["fixed"]`` (``summary.json``)."""
    out = mask(layout, c.fixed, c.free, "problem")
    if info is not None and out.fixed:
        info["fixed"] = fixed_summary(out)
    return out


def half_ranges(c: ProblemConf, layout: Layout) -> Array:
    """Half widths (K,) of the gene ranges: ``axis_error`` on the axes and the hand (rad),
    ``body_error`` on the body vectors and the base point (m), times ``search_scale``."""
    half = np.empty(layout.size)
    for name, block in layout.blocks.items():
        half[block] = c.axis_error if name in ("u0", "hand") else c.body_error
    return half * c.search_scale
