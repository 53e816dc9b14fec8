"""Measurement files: a documented CSV format and the UR10 laser-tracker adapter.

The zrp_ga CSV format (comma-separated, decimal point, one header line, one row per measured
point; blank lines are skipped and do not change the line numbers of the others):

| column | required | what |
| --- | --- | --- |
| ``q1 .. qn`` | yes | joint values, one column per joint: ``angle_unit`` for revolute joints, ``length_unit`` for prismatic ones |
| ``x, y, z`` | yes | the measured point, in the instrument's frame (``length_unit``) |
| ``rx, ry, rz`` | no | measured orientation of the tool, in the convention stated by ``orientation_convention`` (``angle_unit``) |
| ``sx, sy, sz`` | no | standard deviations of x, y, z (``length_unit``, > 0), kept as the rows' weights |
| ``tool`` | no | which tool point was measured (a name, e.g. ``A``): several reflectors on the flange, one arm |

Units: ``length_unit`` ``m``, ``mm`` or ``auto`` (metres or millimetres, whichever puts the
points within the arm's reach: :func:`resolve_length_unit`); ``angle_unit`` ``rad``, ``deg`` or
``auto`` (degrees when a revolute joint value lies beyond any turn the arm can make in radians).
Orientation conventions: an Euler sequence as :func:`scipy.spatial.transform.Rotation.from_euler`
reads it (``XYZ``: intrinsic x-y'-z'', ``xyz``: extrinsic, any order), or ``rotvec``, the rotation
vector that Universal Robots' controllers report as ``rx, ry, rz``. Orientation columns are
ignored until a convention is stated.

``ur10_ipa`` reads the files of Landgraf et al. (semicolon-separated, decimal comma, joint
angles in rad, positions in mm, orientations in degrees, intrinsic XYZ Euler).

Every problem in a file is one ValueError naming the file, the line (as a text editor counts,
the header being line 1) and the column: a missing or unreadable file, no regular file (a FIFO,
a device: :func:`zrp_ga.core.files.regular_file`), a column name given twice, a missing column, a cell
that is empty, not a number, not finite or absurd (a length beyond 1e4 m, an angle beyond 100
rad, a joint value beyond any turn of the arm, a standard deviation <= 0), a point far outside
the arm's reach, rows that repeat earlier rows exactly. Rows with a bad cell and repeated rows
stop the reading unless ``drop_bad_rows`` is set, in which case they are dropped and listed in
the warning. Validation data that repeats calibration rows is named (:func:`check_shared`).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from zrp_ga.core.checks import ROTVEC, check_convention
from zrp_ga.core.errors import warn
from zrp_ga.core.files import as_path, regular_file
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import MAX_ANGLE_RAD, MAX_LENGTH_M, ZRPRobot

Array = NDArray[np.float64]

log = logging.getLogger(__name__)

LENGTH = {"m": 1.0, "mm": 1e-3}
ANGLE = {"rad": 1.0, "deg": np.pi / 180.0}
AUTO = "auto"
UR_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
TOOL_ALLOWANCE_M = 0.5  # how far a tool point may reach beyond the arm's end point, for unit checks


@dataclasses.dataclass(frozen=True)
class Format:
    """Where the numbers are in a file, and their units: ``length_unit`` for positions, standard
    deviations and prismatic joints, ``joint_unit`` for revolute joints, ``angle_unit`` for
    orientations (``auto`` as in the module docstring); ``orientation_convention`` an Euler
    sequence or ``rotvec``, None when unstated (the orientation columns are then not read)."""

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
    orientation_convention: str | None = None


def zrp_format(n: int, length_unit: str = "m", angle_unit: str = "rad", orientation_convention: str | None = None) -> Format:
    """The zrp_ga CSV format for an arm of n joints (module docstring)."""
    return Format(joints=[f"q{i}" for i in range(1, n + 1)], position=["x", "y", "z"], orientation=["rx", "ry", "rz"],
                  std=["sx", "sy", "sz"], tool="tool", length_unit=length_unit, angle_unit=angle_unit,
                  joint_unit=angle_unit, orientation_convention=orientation_convention)  # fmt: skip


UR10_IPA = Format(
    joints=UR_JOINTS, position=["measurement_x", "measurement_y", "measurement_z"],
    orientation=["measurement_rx", "measurement_ry", "measurement_rz"],
    std=["measurement_std_x", "measurement_std_y", "measurement_std_z"], sep=";", decimal=",",
    length_unit="mm", angle_unit="deg", joint_unit="rad", orientation_convention="XYZ",
)  # fmt: skip


def read(path: str | Path, fmt: Format, robot: ZRPRobot, drop_bad_rows: bool = False) -> Measurements:
    """Read a measurement file for ``robot`` (its joint types decide the joint units, its reach
    the checks and ``auto`` units); ValueError naming file, line and column for anything wrong."""
    path = as_path(path, "measurement data", " or, for data in memory, zrp_ga.model.poses.Measurements(q, p) with joint values q (M, n) in rad and positions p (M, 3) in m")
    _check_units(path, fmt)
    raw, lines = _table(path, fmt)
    return _checked(raw, lines, fmt, robot, drop_bad_rows, str(path), "line")


def from_table(table, fmt: Format, robot: ZRPRobot, drop_bad_rows: bool = False, source: str = "data") -> Measurements:
    """In-memory measurements (a pandas DataFrame with the columns of ``fmt``, numbers or text)
    checked and converted exactly as :func:`read` checks a file; a ValueError names ``source``,
    the row (counted from 0, as ``DataFrame.iloc`` counts) and the column."""
    import pandas as pd

    _check_units(source, fmt)
    if not isinstance(table, pd.DataFrame):
        raise ValueError(f"{source}: expected a pandas DataFrame, got {type(table).__name__}")
    names = [str(c).strip() for c in table.columns]
    refuse_repeated(names, source)
    raw = pd.DataFrame({c: [str(v) for v in table.iloc[:, j]] for j, c in enumerate(names)}, dtype=object)
    return _checked(raw, np.arange(len(raw)), fmt, robot, drop_bad_rows, source, "row")


def _checked(raw, lines, fmt: Format, robot: ZRPRobot, drop_bad_rows: bool, source: str, row: str) -> Measurements:
    """The table's cells (text) checked and converted: ``row`` is how its rows are named in
    messages (``line`` of a file, ``row`` of a DataFrame)."""
    path = source
    columns = _columns(path, raw, fmt, robot.n)
    values = np.column_stack([_numbers(raw[c], fmt.decimal) for c in columns]) if len(raw) else np.empty((0, len(columns)))
    tools = raw[fmt.tool].str.strip().to_numpy(dtype=str) if fmt.tool in raw.columns else None
    units = _resolve_units(path, fmt, robot, columns, values)
    bad = _bad_cells(values, columns, units, fmt, robot, tools)
    values, raw, lines, tools = _drop(path, bad, raw, columns, values, lines, tools, drop_bad_rows, row)
    if len(values) == 0:
        raise ValueError(f"{path}: no measurement rows")
    values, lines, tools = _drop_repeats(path, values, lines, tools, drop_bad_rows, row)
    m = _measurements(fmt, robot, columns, values, lines, tools, units, source)
    return m if row == "line" else dataclasses.replace(m, row_name=row)


def _check_units(path: Path | str, fmt: Format) -> None:
    for unit, table in ((fmt.length_unit, LENGTH), (fmt.angle_unit, ANGLE), (fmt.joint_unit, ANGLE)):
        if unit not in table and unit != AUTO:
            raise ValueError(f"{path}: unknown unit {unit!r}; known: {', '.join(table)}, {AUTO}")
    check_convention(fmt.orientation_convention, f"{path}: orientation convention")


def refuse_repeated(names: list[str], source: str) -> None:
    """A column name given twice in an in-memory table: which copy is meant cannot be told."""
    repeated = sorted({c for c in names if names.count(c) > 1})
    if repeated:
        raise ValueError(f"{source}: column {repeated[0]!r} appears {names.count(repeated[0])} times")


def _table(path: Path, fmt: Format):
    """The file's cells as text (pandas DataFrame) and each row's line in the file (:func:`read_cells`)."""
    return read_cells(path, fmt.sep)


def read_cells(path: Path, sep: str, what: str = "a measurement file (.csv)"):
    """The cells of a ``sep``-separated text file as text (pandas DataFrame, stripped column
    names) and each row's line in the file; blank lines are dropped after counting them. Every
    file of rows goes through here (measurements, robot programs): a regular file (``what`` it
    should be), text, no column name twice (:func:`_check_header`)."""
    import pandas as pd

    regular_file(path, what)
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
            header = head.split(b"\n", 1)[0] + (b"" if b"\n" in head else f.readline())
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if b"\0" in head:
        raise ValueError(f"{path}: not a text file")
    _check_header(path, header, sep)
    try:
        raw = pd.read_csv(path, sep=sep, dtype=str, keep_default_na=False, skip_blank_lines=False)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise ValueError(f"{path}: cannot be read as a '{sep}'-separated file ({exc})".replace("\n", " ")) from None
    raw.columns = [str(c).strip() for c in raw.columns]
    lines = np.arange(len(raw)) + 2  # the header is line 1
    filled = (raw.apply(lambda col: col.str.strip()) != "").any(axis=1).to_numpy() if len(raw) else np.zeros(0, bool)
    return raw[filled].reset_index(drop=True), lines[filled]


def _check_header(path: Path, header: bytes, sep: str) -> None:
    """Column names that appear more than once (a controller's x, y, z beside a tracker's):
    which copy is meant cannot be told, so the file is refused naming them and their columns."""
    import csv

    names = [c.strip() for c in next(csv.reader([header.decode("utf-8", "replace").rstrip("\r\n")], delimiter=sep), [])]
    seen: dict[str, list[int]] = {}
    for k, name in enumerate(names, start=1):
        if name:
            seen.setdefault(name, []).append(k)
    twice = {name: cols for name, cols in seen.items() if len(cols) > 1}
    if twice:
        listed = "; ".join(f"{name!r} in columns {', '.join(map(str, cols))}" for name, cols in twice.items())
        raise ValueError(f"{path}, line 1: duplicate column names ({listed}); which copy to use cannot be told: "
                         "rename or remove all but one")  # fmt: skip


def _columns(path: Path | str, raw, fmt: Format, n: int) -> list[str]:
    """The numeric columns to read: joints and positions, orientation (with a stated convention)
    and standard deviations when all three of a group are present."""
    if fmt.joints[0] == "q1":  # generic format: count the q columns to name a wrong joint count
        qs = [c for c in raw.columns if c.startswith("q") and c[1:].isdigit()]
        if qs and len(qs) != n:
            raise ValueError(f"{path}: {len(qs)} joint columns ({', '.join(qs)}), but the robot has {n} joints")
    if len(fmt.joints) != n:
        raise ValueError(f"{path}: the format has {len(fmt.joints)} joint columns, the robot has {n} joints")
    required = fmt.joints + fmt.position
    missing = [c for c in required if c not in raw.columns]
    if missing:
        hint = ""
        if len(raw.columns) == 1 and any(s in raw.columns[0] for s in ";\t,"):
            hint = f"; is the file separated by something else than {fmt.sep!r}?"
        raise ValueError(f"{path}: missing column {missing[0]!r}" + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
                         + f"; columns found: {', '.join(raw.columns)}{hint}")  # fmt: skip
    groups = [fmt.std] + ([fmt.orientation] if fmt.orientation_convention else [])
    return required + [c for g in groups if g and all(c in raw.columns for c in g) for c in g]


def _numbers(column, decimal: str) -> Array:
    import pandas as pd

    text = column.str.strip().str.replace(decimal, ".", regex=False)
    return pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)


@dataclasses.dataclass(frozen=True)
class _Units:
    """SI factors of a file: ``length`` (positions, std, prismatic joints), ``joint`` (revolute
    joints), ``angle`` (orientations), and their names in that order."""

    length: float
    joint: float
    angle: float
    names: tuple[str, str, str]


def _resolve_units(path: Path | str, fmt: Format, robot: ZRPRobot, columns: list[str], values: Array) -> _Units:
    """The file's units, ``auto`` ones decided from its numbers (rows with a cell that no unit
    makes sensible left out: they are refused by line and column afterwards); a stated length
    unit that cannot be right for this arm is an error with a hint."""
    pos = values[:, [columns.index(c) for c in fmt.position]]
    rev = values[:, [columns.index(c) for c, t in zip(fmt.joints, robot.joint_types) if t == "R"]]
    with np.errstate(invalid="ignore"):
        sane = np.all(np.isfinite(values), axis=1) & np.all(np.abs(pos) * LENGTH["mm"] <= MAX_LENGTH_M, axis=1)
        sane &= np.all(np.abs(rev) * ANGLE["deg"] <= MAX_ANGLE_RAD, axis=1)
    length = resolve_length_unit(path, pos[sane], robot, fmt.length_unit)
    joint = resolve_joint_unit(rev[sane], robot, fmt.joint_unit)
    angle = joint if fmt.angle_unit == AUTO else fmt.angle_unit
    return _Units(LENGTH[length], ANGLE[joint], ANGLE[angle], (length, joint, angle))


def reach_m(robot: ZRPRobot) -> float:
    """How far the end point can be from the point on axis 1 (m): the body vectors' lengths and
    the prismatic joints' largest extensions."""
    stroke = np.abs(robot.joint_limits[robot.prismatic]).max(axis=1).sum() if robot.prismatic.any() else 0.0
    return float(np.linalg.norm(robot.b0[1:], axis=1).sum() + stroke)


def resolve_length_unit(path: Path | str, points: Array, robot: ZRPRobot, unit: str) -> str:
    """``m`` or ``mm`` for measured points (M, 3) in file units. Points a tool on the arm can
    reach spread over at most twice its reach plus a tool (the spread: twice the median
    distance from the median point, so that absurd cells in fewer than half of the rows do not
    decide it; they are refused later, by line and column); a calibration's spread over more
    than 1% of the reach. ``auto`` takes the one unit in which both hold (none or both: an
    error asking for the unit); a stated unit in which the points spread too far, or too little
    while the other unit fits (metres read as millimetres), is an error naming the unit that
    would fit."""
    if len(points) < 2:
        return "m" if unit == AUTO else unit
    spread = 2.0 * float(np.median(np.linalg.norm(points - np.median(points, axis=0), axis=1)))
    reach = reach_m(robot)
    within = {u for u in LENGTH if spread * LENGTH[u] <= 2.0 * (reach + TOOL_ALLOWANCE_M)}
    fits = [u for u in LENGTH if u in within and spread * LENGTH[u] >= 0.01 * reach]
    where = f"{path}: the measured points spread over {spread:.4g} file units and {robot.name} reaches {reach:.3g} m"
    if unit == AUTO:
        if len(fits) != 1:
            raise ValueError(f"{where}: cannot tell metres from millimetres; set problem.length_unit=m or mm")
        return fits[0]
    if unit not in within:
        hint = f" (problem.length_unit={fits[0]}?)" if fits else ""
        raise ValueError(f"{where}: they cannot be in {unit}{hint}")
    if unit not in fits and fits:  # e.g. metres with mm stated: a few millimetres of spread
        raise ValueError(f"{where}: in {unit} they would spread over {spread * LENGTH[unit] * 1e3:.3g} mm, less than 1% of "
                         f"its reach; they cannot be in {unit} (problem.length_unit={fits[0]}?)")  # fmt: skip
    return unit


def turn_rad(robot: ZRPRobot) -> float:
    """The largest revolute joint value (rad) a file may hold: the largest stated limit, at
    least a full turn, plus 5%."""
    limits = np.abs(robot.joint_limits[~robot.prismatic])
    return 1.05 * max(2 * np.pi, float(limits.max(initial=0.0)))


def resolve_joint_unit(q: Array, robot: ZRPRobot, unit: str) -> str:
    """``rad`` or ``deg`` for revolute joint values (M, r) in file units: ``auto`` reads radians
    unless a value lies beyond :func:`turn_rad`."""
    if unit != AUTO:
        return unit
    return "rad" if q.size == 0 or float(np.abs(q).max()) <= turn_rad(robot) else "deg"


def _bad_cells(values: Array, columns: list[str], u: _Units, fmt: Format, robot: ZRPRobot, tools) -> list[tuple[int, int, str | None]]:
    """(row, column, what) of every bad cell (what None: empty or not a finite number, said by
    :func:`_drop` from the text): absurd for its kind, a joint value beyond any turn, a standard
    deviation <= 0, a point far from the others; an empty tool name (column ``len(columns)``)."""
    kind = {c: "P" if t == "P" else "R" for c, t in zip(fmt.joints, robot.joint_types)}
    kind.update({c: "L" for c in fmt.position}, **{c: "S" for c in fmt.std or ()}, **{c: "A" for c in fmt.orientation or ()})
    length, joint, angle = u.names
    hint = "; in degrees? problem.angle_unit=deg" if joint == "rad" else ""
    bounds = {"P": (u.length, MAX_LENGTH_M, "m", length, "absurd", ""), "L": (u.length, MAX_LENGTH_M, "m", length, "absurd", ""),
              "S": (u.length, MAX_LENGTH_M, "m", length, "absurd", ""), "A": (u.angle, MAX_ANGLE_RAD, "rad", angle, "absurd", ""),
              "R": (u.joint, turn_rad(robot), "rad", joint, f"beyond any turn of {robot.name}", hint)}  # fmt: skip
    bad: list[tuple[int, int, str | None]] = []
    with np.errstate(invalid="ignore"):
        for j, c in enumerate(columns):
            scale, bound, si, unit, what, more = bounds[kind[c]]
            v = values[:, j]
            bad += [(int(r), j, None) for r in np.flatnonzero(~np.isfinite(v))]
            bad += [(int(r), j, f"{v[r]:g} {unit} is {what} (more than {bound:.4g} {si}{more})")
                    for r in np.flatnonzero(np.abs(v) * scale > bound)]  # fmt: skip
            if kind[c] == "S":
                bad += [(int(r), j, f"{v[r]:g}: a standard deviation must be > 0") for r in np.flatnonzero(v <= 0)]
    bad += _far_points(values, columns, fmt, u, robot, {r for r, _, _ in bad})
    if tools is not None:
        bad += [(int(r), len(columns), "empty") for r in np.flatnonzero(tools == "")]
    return sorted(bad, key=lambda b: (b[0], b[1]))


def _far_points(values: Array, columns: list[str], fmt: Format, u: _Units, robot: ZRPRobot, skip: set) -> list:
    """Points farther from the median point than the arm can carry a tool (three times its
    reach plus a tool): the cell of x, y or z farthest off is named."""
    cols = [columns.index(c) for c in fmt.position]
    rows = np.array([r for r in range(len(values)) if r not in skip], dtype=int)
    if len(rows) < 3:
        return []
    off = values[np.ix_(rows, np.array(cols, dtype=int))] * u.length
    off -= np.median(off, axis=0)
    reach = reach_m(robot)
    out = []
    for k in np.flatnonzero(np.linalg.norm(off, axis=1) > 3.0 * (reach + TOOL_ALLOWANCE_M)):
        j = cols[int(np.argmax(np.abs(off[k])))]
        out.append((rows[k], j, f"{values[rows[k], j]:g} {u.names[0]} puts the point {np.linalg.norm(off[k]):.4g} m from the "
                                f"others; {robot.name} reaches {reach:.3g} m"))  # fmt: skip
    return out


def _drop(path: Path | str, bad: list, raw, columns: list[str], values: Array, lines, tools, drop_bad_rows: bool, row: str = "line"):
    """Stop at the first bad cell, or (``drop_bad_rows``) drop the rows that have one."""
    if not bad:
        return values, raw, lines, tools
    names = columns + ["tool"]
    cells = []
    for r, j, what in bad:
        text = raw[names[j]].iloc[r] if names[j] in raw.columns else ""
        if what is None:
            what = "empty" if text.strip() == "" else f"{text.strip()!r} is not a finite number"
        cells.append((int(lines[r]), names[j], what))
    line, col, what = cells[0]
    first = f"{path}, {row} {line}, column {col!r}: {what}"
    rows = np.unique([r for r, _, _ in bad])
    if not drop_bad_rows:
        more = f" ({len(cells) - 1} more bad cells in {len(rows)} rows)" if len(cells) > 1 else ""
        raise ValueError(first + more + "; set problem.drop_bad_rows=true to drop such rows")
    warn(f"{first}; dropped {len(rows)} rows with bad cells ({row}s {_listed(lines[rows])})", log)
    keep = np.setdiff1d(np.arange(len(values)), rows)
    return values[keep], raw.iloc[keep], lines[keep], None if tools is None else tools[keep]


def _drop_repeats(path: Path | str, values: Array, lines, tools, drop_bad_rows: bool, row: str = "line"):
    """Rows that repeat an earlier row exactly (every number and the tool): a copy, not a new
    measurement (a tracker never reads the same point twice to the last digit)."""
    import pandas as pd

    frame = pd.DataFrame(values)
    if tools is not None:
        frame["tool"] = tools
    repeat = frame.duplicated(keep="first").to_numpy()
    if not repeat.any():
        return values, lines, tools
    first = int(np.flatnonzero(repeat)[0])
    same = int(np.flatnonzero((frame == frame.iloc[first]).all(axis=1).to_numpy())[0])
    what = (f"{path}: {int(repeat.sum())} rows repeat earlier rows exactly (first: {row} {lines[first]} repeats "
            f"{row} {lines[same]})")  # fmt: skip
    if not drop_bad_rows:
        raise ValueError(what + "; remove them, or set problem.drop_bad_rows=true to drop them")
    warn(f"{what}; dropped them ({row}s {_listed(lines[repeat])})", log)
    keep = ~repeat
    return values[keep], lines[keep], None if tools is None else tools[keep]


def _listed(lines) -> str:
    return ", ".join(str(v) for v in lines[:20]) + (" ..." if len(lines) > 20 else "")


def _measurements(fmt: Format, robot: ZRPRobot, columns: list[str], values: Array, lines, tools, u: _Units, source: str) -> Measurements:
    """The checked numbers in SI units; tools numbered in the order they first appear."""
    col = {c: values[:, j] for j, c in enumerate(columns)}
    q = np.column_stack([col[c] * (u.length if t == "P" else u.joint) for c, t in zip(fmt.joints, robot.joint_types)])
    p = np.column_stack([col[c] for c in fmt.position]) * u.length
    R = std = None
    if fmt.orientation and fmt.orientation[0] in col:
        angles = np.column_stack([col[c] for c in fmt.orientation]) * u.angle
        conv = fmt.orientation_convention
        R = (Rotation.from_rotvec(angles) if conv == ROTVEC else Rotation.from_euler(conv, angles)).as_matrix()
    if fmt.std and fmt.std[0] in col:
        std = np.column_stack([col[c] for c in fmt.std]) * u.length
    tool: NDArray[np.int64] | None = None
    names: tuple[str, ...] = ()
    if tools is not None:
        names = tuple(dict.fromkeys(tools.tolist()))  # first appearance order
        index = {name: k for k, name in enumerate(names)}
        tool = np.array([index[t] for t in tools], dtype=np.int64)
    return Measurements(q, p, R, std=std, source=source, lines=lines, tool=tool, tool_names=names, units=u.names[:2])


def shared_rows(calib: Measurements, val: Measurements) -> list[tuple[int, int]]:
    """(validation line, calibration line) of every validation row that repeats a calibration
    row exactly: the same joint values, point and tool (SI units, as read)."""

    def key(m: Measurements, k: int) -> bytes:
        tool = m.tool_names[m.tool[k]] if m.tool is not None else ""
        return m.q[k].tobytes() + m.p[k].tobytes() + str(tool).encode()

    assert calib.lines is not None and val.lines is not None  # Measurements numbers its rows
    first: dict[bytes, int] = {}
    for k in range(calib.M):
        first.setdefault(key(calib, k), int(calib.lines[k]))
    return [(int(val.lines[k]), first[key(val, k)]) for k in range(val.M) if key(val, k) in first]


def check_shared(calib: Measurements, val: Measurements) -> list[str]:
    """Validation data that is the calibration data again: refused when every row repeats a
    calibration row (the same file given twice: its errors would be called errors on unseen
    poses), a warning naming the rows when some do."""
    pairs = shared_rows(calib, val)
    if not pairs:
        return []
    shown = ", ".join(f"{v} = {c}" for v, c in pairs[:5]) + (", ..." if len(pairs) > 5 else "")
    what = f"of the validation data {val.source} repeat rows of the calibration data {calib.source} (lines {shown})"
    if len(pairs) == val.M:
        raise ValueError(f"problem.validation_file: all {val.M} rows {what}: its errors would not be on unseen poses; give "
                         "other measurements, or problem.validation_fraction to hold out part of the calibration file")  # fmt: skip
    return [f"{len(pairs)} of the {val.M} rows {what}: the validation error is partly on poses the calibration saw"]


def split(data: Measurements, fraction: float, rng: np.random.Generator) -> tuple[Measurements, Measurements]:
    """A random split of one file: ``fraction`` of the rows for validation."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"problem.validation_fraction: must be in (0, 1), got {fraction}")
    order = rng.permutation(len(data.q))
    k = round(fraction * len(order))
    return data.subset(np.sort(order[k:])), data.subset(np.sort(order[:k]))
