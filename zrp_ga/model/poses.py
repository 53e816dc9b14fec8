"""Measured poses, the data a calibration fits: :class:`Measurements` (joint values, measured
points and orientations, their standard deviations, which tool point each row measured, and
where each row came from). Files are read into it by :mod:`zrp_ga.io.measurements`."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class Measurements:
    """Measured points, SI units: joint values ``q`` (M, n) as given to the model (rad, m),
    positions ``p`` (M, 3) m, orientations ``R`` (M, 3, 3) or None for position-only data;
    optional position weights (M, 3) on the position errors, the positions' standard deviations
    ``std`` (M, 3) m; which tool point each row measured, ``tool`` (M,) indices into
    ``tool_names`` (None: one tool); where the rows came from (``source`` and each row's file
    ``lines``, or rows of in-memory data: ``row_name``) and the ``units`` (length, angle) the file
    was read in."""

    q: Array
    p: Array
    R: Array | None = None
    weights: Array | None = None
    std: Array | None = None
    source: str = "measurements"
    lines: NDArray[np.int64] | None = None
    tool: NDArray[np.int64] | None = None
    tool_names: tuple[str, ...] = ()
    units: tuple[str, str] = ("m", "rad")
    row_name: str = "line"  # what ``lines`` count: a file's lines, or an in-memory table's rows (from 0)

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        M = q.shape[0]
        checks = [("q", q, q.shape if q.ndim == 2 else (M, -1)), ("p", self.p, (M, 3))]
        checks += [(k, getattr(self, k), s) for k, s in (("R", (M, 3, 3)), ("weights", (M, 3)), ("std", (M, 3)))
                   if getattr(self, k) is not None]  # fmt: skip
        for name, value, shape in checks:
            a = np.asarray(value, dtype=float)
            if a.shape != shape:
                raise ValueError(f"measurements.{name}: expected shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"measurements.{name}: NaN or inf at index {tuple(np.argwhere(~np.isfinite(a))[0])}")
            object.__setattr__(self, name, a)
        lines = np.arange(M) + 1 if self.lines is None else np.asarray(self.lines, dtype=np.int64)
        object.__setattr__(self, "lines", lines)
        if self.tool is not None:
            tool = np.asarray(self.tool, dtype=np.int64)
            if tool.shape != (M,) or (M and (tool.min() < 0 or tool.max() >= len(self.tool_names))):
                raise ValueError(f"measurements.tool: expected {M} indices into tool_names {self.tool_names}")
            object.__setattr__(self, "tool", tool)
            object.__setattr__(self, "tool_names", tuple(self.tool_names))

    @property
    def M(self) -> int:
        return self.q.shape[0]

    @property
    def position_only(self) -> bool:
        return self.R is None

    @property
    def tools(self) -> NDArray[np.int64]:
        """Tool index of every row (M,): zeros when the data name no tools."""
        return np.zeros(self.M, dtype=np.int64) if self.tool is None else self.tool

    def where(self, row: int) -> str:
        """Row ``row`` as messages name it (``line 12`` of a file, ``row 11`` of a DataFrame)."""
        assert self.lines is not None  # __post_init__ numbers the rows when none were given
        return f"{self.row_name} {self.lines[row]}"

    def for_calibration(self, orientation: bool = False, weights: bool = False) -> Measurements:
        """What a problem sees: orientations only if asked; with ``weights``, each position error
        weighted by the median standard deviation over its own (so the cost stays in metres)."""
        w = None
        if weights and self.std is not None:
            w = np.median(self.std) / np.maximum(self.std, 1e-12)
        return dataclasses.replace(self, R=self.R if orientation else None, weights=w)

    def subset(self, rows: NDArray) -> Measurements:
        """The rows ``rows`` (indices or a mask), with their file lines."""
        pick = lambda a: None if a is None else a[rows]
        assert self.lines is not None  # __post_init__ numbers the rows when none were given
        return dataclasses.replace(self, q=self.q[rows], p=self.p[rows], R=pick(self.R), weights=pick(self.weights),
                                   std=pick(self.std), lines=self.lines[rows], tool=pick(self.tool))  # fmt: skip

    def with_tool_names(self, names: tuple[str, ...] | list[str]) -> Measurements:
        """The same rows with tool indices into ``names``; a tool not among them is an error
        naming the file, the line and the column."""
        names = tuple(names)
        if self.tool is None:
            return dataclasses.replace(self, tool=np.zeros(self.M, dtype=np.int64), tool_names=names[:1] or ("tool",))
        index = {name: k for k, name in enumerate(names)}
        for k, name in enumerate(self.tool_names):
            if name not in index:
                row = int(np.flatnonzero(self.tool == k)[0])
                raise ValueError(f"{self.source}, {self.where(row)}, column 'tool': tool {name!r} is neither among the "
                                 f"calibration's tools ({', '.join(names)}) nor a known tool (problem.known_tools)")  # fmt: skip
        remap = np.array([index[name] for name in self.tool_names], dtype=np.int64)
        return dataclasses.replace(self, tool=remap[self.tool], tool_names=names)
