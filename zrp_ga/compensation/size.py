"""The size of a compensation, estimated before any row is read: memory and time from the rows
(a file's rows estimated from its size, :func:`zrp_ga.problems.size.file_rows`) and the arm's
joints. A compensation whose estimate exceeds the memory this process may use
(:func:`zrp_ga.run.budget.available_bytes`; ``ZRP_GA_MEMORY`` replaces it) is refused with one
line; a long one is announced.

Memory: the file's text while pandas holds it (``CELL_BYTES`` a cell, the run budget's figure),
and per row about ``ROW_BYTES`` (the joint values, targets, rotations and solutions in float64,
the two output tables as pandas columns), times the run budget's margin. Time: ``SOLVE_S`` per
joint and inverse-kinematics solve, one solve per row for a joint program and two for a
Cartesian one (the nominal, then the calibrated arm), measured on a loaded 2-core machine
(PUMA 560, joint program: 25 ms a row at a load average of 7; the UR10's series C: 10 ms a row
at a lower load); a file's kind is not known before it is read, so its estimate spans both;
rows whose seeds do not lead to their target are solved again from up to
:data:`zrp_ga.compensation.ik.RESTARTS` other starts, so a Cartesian program without seeds may
take several times the estimate.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga.problems import size as problem_size
from zrp_ga.run import budget

log = logging.getLogger(__name__)
ROW_BYTES = 3000  # arrays and output columns of one row, float64, for a 6-joint arm (grows with the joints)
SOLVE_S = 3e-3  # per joint and solve
LONG_S = 30.0  # a compensation estimated to take longer is announced before it starts


@dataclasses.dataclass(frozen=True)
class Size:
    """What a compensation's size depends on: ``rows`` (estimated for a file), ``columns`` of
    its text, the arm's ``joints`` and whether it is ``cartesian`` (or unknown: None)."""

    rows: int
    columns: int
    joints: int
    cartesian: bool | None

    def memory(self) -> float:
        """Bytes it needs at most (module docstring)."""
        text = problem_size.CELL_BYTES * self.rows * self.columns
        return budget.MARGIN * (text + ROW_BYTES * self.rows * max(self.joints, 6) / 6)

    def seconds(self) -> tuple[float, float]:
        """Seconds it takes, roughly, at least and at most (module docstring)."""
        one = SOLVE_S * self.joints * self.rows
        return (2 * one if self.cartesian else one), (one if self.cartesian is False else 2 * one)


def of_program(program: Any, joints: int) -> Size:
    """The :class:`Size` of ``program`` (a file path, a table or an array) for an arm of
    ``joints`` joints; a file that is no regular file counts as empty (its reader says why)."""
    if isinstance(program, (str, os.PathLike)):
        rows = problem_size.file_rows(Path(program))
        columns = _header_columns(Path(program))
        return Size(rows, columns, joints, None)
    try:
        shape = np.shape(program) if isinstance(program, (np.ndarray, list, tuple)) else None
    except ValueError:  # rows of different lengths: the reader names them
        shape = (len(program),)
    if shape:
        return Size(shape[0], 0, joints, len(shape) > 1 and shape[1] != joints)
    if isinstance(program, dict):
        first = next(iter(program.values()), ())
        return Size(len(first) if hasattr(first, "__len__") else 1, 0, joints, None)
    return Size(len(program) if hasattr(program, "__len__") else 0, 0, joints, None)


def _header_columns(path: Path) -> int:
    """The number of columns of a text file's first line (0 when it cannot be read)."""
    try:
        if not path.is_file():
            return 0
        with open(path, "rb") as f:
            head = f.read(4096).split(b"\n", 1)[0]
    except OSError:
        return 0
    return max(head.count(b","), head.count(b";"), head.count(b"\t")) + 1


def human(b: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def duration(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.0f} min" if s < 7200 else f"{s / 3600:.1f} h"


def check(size: Size, source: str, say: Callable[[str], None] | None = None, available: float | None = None) -> None:
    """Refuse (ValueError, one line) a compensation whose memory estimate exceeds ``available``
    (default: :func:`zrp_ga.run.budget.available_bytes`); announce one estimated to take longer
    than :data:`LONG_S` through ``say`` (default: the log, as a warning)."""
    need = size.memory()
    have = budget.available_bytes() if available is None else available
    low, high = size.seconds()
    took = duration(low) if low == high else f"{duration(low)} to {duration(high)}"
    if need > have:
        raise ValueError(f"program: {source}: about {size.rows} rows would need about {human(need)} of memory "
                         f"(and {took}), this process may use {human(have)}: split the program into "
                         f"smaller files (or set {budget.ENV} to allow more)")  # fmt: skip
    if high > LONG_S:
        (say or log.warning)(f"{source}: about {size.rows} rows will take about {took} ({human(need)} of memory)")
