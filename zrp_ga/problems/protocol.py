"""What a calibration problem offers beyond the generic parts of :mod:`zrp_ga.core.problem`:

- :class:`Identifiable`: the calibration data behind the problem (``nominal`` arm, ``layout``,
  ``data``) and ``identifiability()``, for the diagnostics a run records;
- :class:`SelfJudging`: a task whose genomes are not parameter errors (pose selection) judges its
  own result.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from zrp_ga.model.error_model import IdentifiabilityReport
    from zrp_ga.model.layout import Layout
    from zrp_ga.model.poses import Measurements
    from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


@runtime_checkable
class Identifiable(Protocol):
    """The calibration data behind the problem and the identifiability of its parameters."""

    @property
    def nominal(self) -> ZRPRobot: ...

    @property
    def layout(self) -> Layout: ...

    @property
    def data(self) -> Measurements: ...

    def identifiability(self) -> IdentifiabilityReport: ...


class Found(Protocol):
    """What an optimiser found, as a task judges it (:class:`zrp_ga.algorithms.Result` has it):
    the best genome (None: no genome had a finite cost) and its cost."""

    @property
    def x(self) -> Array | None: ...

    @property
    def cost(self) -> float: ...


@runtime_checkable
class SelfJudging(Protocol):
    """A task (:class:`zrp_ga.problems.Task`) whose genomes are not parameter errors judges its
    own result: ``judged(result) -> (summary entries, reported genome)`` and writes its own
    ``best_params.csv`` rows, ``params_table(x)``; it has no calibration floor."""

    def judged(self, result: Found) -> tuple[dict[str, Any], NDArray[Any]]: ...

    def params_table(self, x: ArrayLike) -> list[dict[str, Any]]: ...
