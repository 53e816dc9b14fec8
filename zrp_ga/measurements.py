"""Measurement files: a documented CSV format and the UR10 laser-tracker adapter.

The zrp_ga CSV format (comma-separated, decimal point, one header line, one row per pose):

| column | required | what |
| --- | --- | --- |
| ``q1 .. qn`` | yes | joint values, one column per joint (``angle_unit`` for revolute joints, ``length_unit`` for prismatic ones) |
| ``x, y, z`` | yes | the measured point, in the instrument's frame (``length_unit``) |
| ``rx, ry, rz`` | no | measured orientation as Euler angles (``euler``, default ``XYZ`` = intrinsic x-y-z, ``angle_unit``) |
| ``sx, sy, sz`` | no | standard deviations of x, y, z (``length_unit``), kept as the rows' weights |
| ``tool`` | no | which tool point was measured (a name); one tool point per file is supported |

``ur10_ipa`` reads the files of Landgraf et al. (semicolon-separated, decimal comma, joint
angles in rad, positions in mm, orientations in degrees, intrinsic XYZ Euler).

Every problem in a file is reported by file, line (as a text editor counts, the header being
line 1) and column. Rows with a bad cell stop the reading unless ``drop_bad_rows`` is set, in
which case they are dropped and listed in the warning.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
from scipy.spatial.transform import Rotation


log = logging.getLogger(__name__)

LENGTH = {"m": 1.0, "mm": 1e-3}
ANGLE = {"rad": 1.0, "deg": np.pi / 180.0}
UR_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]


@dataclasses.dataclass(frozen=True)
class Format:
    """Where the numbers are in a file, and their units."""

    joints: list[str]
    position: list[str]
    orientation: list[str] | None = None
    std: list[str] | None = None
    tool: str | None = None
    sep: str = ","
    decimal: str = "."
    length_unit: str = "m"
    angle_unit: str = "rad"
    joint_unit: str = "rad"
    euler: str = "XYZ"


def zrp_format(n: int, length_unit: str = "m", angle_unit: str = "rad") -> Format:
    return Format(joints=[f"q{i}" for i in range(1, n + 1)], position=["x", "y", "z"], orientation=["rx", "ry", "rz"],
                  std=["sx", "sy", "sz"], tool="tool", length_unit=length_unit, angle_unit=angle_unit,
                  joint_unit=angle_unit)  # fmt: skip


UR10_IPA = Format(
    joints=UR_JOINTS, position=["measurement_x", "measurement_y", "measurement_z"],
    orientation=["measurement_rx", "measurement_ry", "measurement_rz"],
    std=["measurement_std_x", "measurement_std_y", "measurement_std_z"], sep=";", decimal=",",
    length_unit="mm", angle_unit="deg", joint_unit="rad", euler="XYZ",
)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Measurements:
    """Measured poses, SI units: joint values ``q`` (M, n) as given to the model (rad, m),
    positions ``p`` (M, 3) m, orientations ``R`` (M, 3, 3) or None for position-only data;
    optional position weights (M, 3) on the position errors, the positions' standard deviations
    ``std`` (M, 3) m, and where the rows came from (``source`` and each row's file ``lines``)."""

    q: Array
    p: Array
    R: Array | None = None
    weights: Array | None = None
    std: Array | None = None
    source: str = "measurements"
    lines: NDArray[np.int64] | None = None

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

    @property
    def M(self) -> int:
        return self.q.shape[0]

    @property
    def position_only(self) -> bool:
        return self.R is None

    def for_calibration(self, orientation: bool = False, weights: bool = False) -> Measurements:
        """What a problem sees: orientations only if asked; with ``weights``, each position error
        weighted by the median standard deviation over its own (so the cost stays in metres)."""
        w = None
        if weights and self.std is not None:
            w = np.median(self.std) / np.maximum(self.std, 1e-12)
        return dataclasses.replace(self, R=self.R if orientation else None, weights=w)

    def subset(self, rows: NDArray) -> Measurements:
        """The rows ``rows`` (indices or a mask), with their file lines."""
        pick = lambda a: None if a is None else a[rows]  # noqa: E731
        return dataclasses.replace(self, q=self.q[rows], p=self.p[rows], R=pick(self.R), weights=pick(self.weights),
                                   std=pick(self.std), lines=self.lines[rows])  # fmt: skip


def read(path: str | Path, fmt: Format, n_joints: int, drop_bad_rows: bool = False) -> Measurements:
    """Read a measurement file; ValueError naming file, line and column for anything wrong."""
    import pandas as pd

    path = Path(path)
    for unit, table in ((fmt.length_unit, LENGTH), (fmt.angle_unit, ANGLE), (fmt.joint_unit, ANGLE)):
        if unit not in table:
            raise ValueError(f"{path}: unknown unit {unit!r}; known: {', '.join(table)}")
    if len(fmt.joints) != n_joints:
        raise ValueError(f"{path}: the format has {len(fmt.joints)} joint columns, the robot has {n_joints} joints")
    try:
        raw = pd.read_csv(path, sep=fmt.sep, dtype=str, keep_default_na=False)
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise ValueError(f"{path}: cannot be read as a '{fmt.sep}'-separated file ({exc})".replace("\n", " ")) from None
    raw.columns = [c.strip() for c in raw.columns]
    if fmt.joints[0] == "q1":  # generic format: count the q columns to name a wrong joint count
        qs = [c for c in raw.columns if c.startswith("q") and c[1:].isdigit()]
        if qs and len(qs) != n_joints:
            raise ValueError(f"{path}: {len(qs)} joint columns ({', '.join(qs)}), but the robot has {n_joints} joints")
    required = fmt.joints + fmt.position
    missing = [c for c in required if c not in raw.columns]
    if missing:
        raise ValueError(f"{path}: missing column {missing[0]!r}" + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
                         + f"; columns found: {', '.join(raw.columns)}")  # fmt: skip
    optional = [c for group in (fmt.orientation, fmt.std) if group and all(c in raw.columns for c in group) for c in group]
    columns = required + optional
    values = pd.DataFrame({c: pd.to_numeric(raw[c].str.strip().str.replace(fmt.decimal, ".", regex=False), errors="coerce")
                           for c in columns})  # fmt: skip
    bad = ~np.isfinite(values.to_numpy(dtype=float))
    lines = np.arange(len(raw)) + 2  # the header is line 1
    if bad.any():
        cells = [(int(lines[r]), columns[c], raw[columns[c]].iloc[r]) for r, c in zip(*np.nonzero(bad))]
        line, col, text = cells[0]
        what = "empty" if text.strip() == "" else f"{text!r} is not a finite number"
        first = f"{path}, line {line}, column {col!r}: {what}"
        rows = np.unique(np.nonzero(bad)[0])
        if not drop_bad_rows:
            more = f" ({len(cells) - 1} more bad cells in {len(rows)} rows)" if len(cells) > 1 else ""
            raise ValueError(first + more + "; set problem.drop_bad_rows=true to drop such rows")
        log.warning("%s; dropped %d rows with bad cells (lines %s)", first, len(rows),
                    ", ".join(str(lines[r]) for r in rows[:20]) + (" ..." if len(rows) > 20 else ""))  # fmt: skip
        keep = np.setdiff1d(np.arange(len(raw)), rows)
        values, raw, lines = values.iloc[keep], raw.iloc[keep], lines[keep]
    if len(values) == 0:
        raise ValueError(f"{path}: no measurement rows")
    if fmt.tool and fmt.tool in raw.columns and raw[fmt.tool].nunique() > 1:
        raise ValueError(f"{path}, column {fmt.tool!r}: {raw[fmt.tool].nunique()} tool points; one per file is supported")
    length, angle = LENGTH[fmt.length_unit], ANGLE[fmt.angle_unit]
    q = values[fmt.joints].to_numpy(dtype=float) * ANGLE[fmt.joint_unit]
    p = values[fmt.position].to_numpy(dtype=float) * length
    R = std = None
    if fmt.orientation and all(c in values for c in fmt.orientation):
        R = Rotation.from_euler(fmt.euler, values[fmt.orientation].to_numpy(dtype=float) * angle).as_matrix()
    if fmt.std and all(c in values for c in fmt.std):
        std = values[fmt.std].to_numpy(dtype=float) * length
    return Measurements(q, p, R, std=std, source=str(path), lines=lines)


def split(data: Measurements, fraction: float, rng: np.random.Generator) -> tuple[Measurements, Measurements]:
    """A random split of one file: ``fraction`` of the rows for validation."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"problem.validation_fraction: must be in (0, 1), got {fraction}")
    order = rng.permutation(len(data.q))
    k = int(round(fraction * len(order)))
    return data.subset(np.sort(order[k:])), data.subset(np.sort(order[:k]))
