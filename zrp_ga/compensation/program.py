"""Robot programs (and work-object files) read for a compensation: a CSV file, a pandas
DataFrame, a dict of columns or an array, checked as measurement files are checked and converted
to SI units.

Columns: ``x, y, z`` (a Cartesian program) with the orientation in its convention's columns
(:mod:`zrp_ga.compensation.orientation`: ``A, B, C`` for KUKA's ZYX, ``W, P, R`` for Fanuc's
xyz, ``q1..q4`` for a quaternion, ``rx, ry, rz`` in a stated convention) and optional joint
columns as each row's seed configuration; or joint columns only (a joint-value program). Joint
columns are ``q1 .. qn`` or the robot's joint names. Any column may carry its unit after an
underscore (``x_mm``, ``q1_deg``, ``A_deg``, ``q3_mm``), as the tables this package writes do;
with a quaternion, joint columns must (``q1_deg``), since ``q1..q4`` are the quaternion's.

Units (``length_unit``, ``angle_unit``: ``auto``, or ``m``/``mm`` and ``rad``/``deg``): a unit
in a column's name is the column's; a stated one must agree with it. ``auto`` finds them from the
data as the measurement reader does (:mod:`zrp_ga.io.measurements`): positions are metres or
millimetres, whichever puts the targets' median distance from the arm's base point between 1 %
of its reach and its reach plus a tool (:func:`length_unit_of`); revolute joint values are
degrees when one lies beyond any turn the arm can make in radians, or outside a joint's limits
in radians but inside them in degrees (:func:`joint_unit_of`); orientation angles are degrees
when one lies beyond a turn, or when the joints are in degrees. A stated unit that cannot be
right while the other one fits is refused with a line naming the setting.

Every problem is one ValueError naming the source, the row (a file's line, a table's row) and
the column; what is not a program at all (None, a number) is a TypeError naming ``program``.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.compensation import frames, orientation
from zrp_ga.core.checks import ROTVEC
from zrp_ga.io import measurements
from zrp_ga.io.measurements import ANGLE, AUTO, LENGTH, TOOL_ALLOWANCE_M, reach_m, turn_rad
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
KINDS = ("auto", "joints", "cartesian")
UNITS = {"mm": "length", "m": "length", "deg": "angle", "rad": "angle"}  # column-name suffixes
SETTING = {"length": "length_unit (--length-unit)", "angle": "angle_unit (--angle-unit)"}
NEAR_BASE = 0.01  # targets nearer the base point than this share of the reach are inside the robot
Locate = Callable[[Array, str], Array]  # positions (M, 3) m in the program's frame, their unit -> distances (M,) m from the base point


@dataclasses.dataclass(frozen=True)
class Program:
    """A program in SI units: ``kind`` ``joints`` (``q`` (M, n) the program) or ``cartesian``
    (``p`` (M, 3) m in the program's frame, ``R`` (M, 3, 3) or None, ``q`` (M, n) seed
    configurations or None); each row's place ``where`` ("line 7" of a file, "row 3" of a
    table), the joint column names (without units), the units it was written in, its orientation
    ``convention`` and its own orientation numbers ``angles`` (M, 3) rad or (M, 4), so that the
    corrected ones are written beside them; whether anything said its angle unit."""

    kind: str
    q: Array | None
    p: Array | None
    R: Array | None
    where: tuple[str, ...]
    source: str
    joint_columns: tuple[str, ...]
    length_unit: str = "m"
    angle_unit: str = "rad"
    convention: str | None = None
    angles: Array | None = None
    orientation_unit: str = "rad"
    angle_unit_found: bool = True  # False: nothing in the program or the settings said its angle unit (a seed's is then found from it)

    @property
    def M(self) -> int:
        return len(self.where)


@dataclasses.dataclass(frozen=True)
class Cells:
    """A table's cells as text: ``raw`` (pandas DataFrame), each row's place and the source."""

    raw: Any
    where: tuple[str, ...]
    source: str


@dataclasses.dataclass(frozen=True)
class Columns:
    """Which columns hold what: joint columns (actual names) and their base names, positions,
    orientation, its convention, and each group's unit from the names (None: not stated)."""

    joints: tuple[str, ...] | None
    joint_names: tuple[str, ...] | None
    position: tuple[str, ...] | None
    orientation: tuple[str, ...] | None
    convention: str | None
    units: dict[str, str | None]


def read_program(
    program: Any, robot: ZRPRobot, kind: str = "auto", length_unit: str = AUTO, angle_unit: str = AUTO,
    orientation_convention: str | None = None, sep: str = ",", decimal: str = ".", locate: Locate | None = None,
) -> Program:  # fmt: skip
    """A program from a CSV file, a pandas DataFrame, a dict of columns or an array (module
    docstring). Arrays: ``kind="joints"`` (M, n), or ``"cartesian"`` positions (M, 3) or poses
    (M, 4, 4), SI units. ``locate``: the distance (m) of positions (M, 3) m in the program's frame
    from the arm's base point, given the length unit they were read in (a work object given in
    the program's units moves with it; default: targets in the base frame), for the length unit."""
    check_settings(kind, length_unit, angle_unit, orientation_convention)
    if isinstance(program, (np.ndarray, list, tuple)):
        return _array_program(program, robot, kind, orientation_convention)
    cells = table_cells(program, sep, "program")
    cols = columns_of(cells, robot, kind, orientation_convention)
    locate = locate or (lambda p, unit: np.linalg.norm(p - robot.b0[0], axis=1))
    number = lambda c: column(cells, c, decimal)
    q_file = None if cols.joints is None else np.column_stack([number(c) for c in cols.joints])
    p_file = None if cols.position is None else np.column_stack([number(c) for c in cols.position])
    length = length_unit_of(cells.source, robot, _stated(cols.units["position"], cols.units["joints_length"], length_unit,
                            "length", cells.source), p_file, q_file, locate)  # fmt: skip
    joint = joint_unit_of(cells, cols, robot, q_file, angle_unit)
    q = None if q_file is None else q_file * np.where(robot.prismatic, LENGTH[length], ANGLE[joint])
    if q is not None:
        check_joints(q, robot, cols.joint_names, cells, {"length": length, "angle": joint})
    p = None if p_file is None else p_file * LENGTH[length]
    R, angles, unit = _orientation(cells, cols, number, angle_unit, joint)
    found = cols.joints is not None or angle_unit != AUTO
    if not found and angles is not None and orientation.is_angle(_convention(cols)):
        joint, found = unit, True  # no joint columns: the program's angles are in its orientations' unit
    names = cols.joint_names or tuple(f"q{i + 1}" for i in range(robot.n))
    kind = "cartesian" if cols.position is not None else "joints"
    return Program(kind, q, p, R, cells.where, cells.source, names, length, joint, cols.convention, angles, unit, found)


def check_settings(kind: Any, length_unit: Any, angle_unit: Any, convention: Any) -> None:
    """The reading settings' values; ValueError naming the one that is not one of its choices."""
    if kind not in KINDS:
        raise ValueError(f"kind: {kind!r}, expected one of {', '.join(KINDS)}")
    for name, value, table in (("length_unit", length_unit, LENGTH), ("angle_unit", angle_unit, ANGLE)):
        if value != AUTO and value not in table:
            raise ValueError(f"{name}: {value!r}, expected one of {', '.join(table)}, {AUTO}")
    if convention is not None and not isinstance(convention, str):
        raise TypeError(f"orientation_convention: expected a string (an Euler sequence, rotvec or quaternion), got {convention!r}")
    orientation.check(convention, "orientation_convention")


# --- the cells ------------------------------------------------------------------------------------------
def table_cells(table: Any, sep: str, what: str) -> Cells:
    """The cells of a file (through the measurement reader's checks: a regular file, text, no
    column twice: :func:`zrp_ga.io.measurements.read_cells`), a DataFrame or a dict of columns."""
    import pandas as pd

    if isinstance(table, dict):
        try:
            table = pd.DataFrame(table)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{what}: a dict that is no table of columns ({exc})") from None
    if isinstance(table, pd.DataFrame):
        names = [str(c).strip() for c in table.columns]
        measurements.refuse_repeated(names, what)
        raw = pd.DataFrame({c: [str(v) for v in table.iloc[:, j]] for j, c in enumerate(names)}, dtype=object)
        return _filled(Cells(raw, tuple(f"row {i}" for i in range(len(raw))), what), what)
    if not isinstance(table, (str, os.PathLike)):
        kind = "None" if table is None else type(table).__name__
        raise TypeError(f"{what}: expected a CSV file path, a pandas DataFrame, a dict of columns or an array; got {kind}")
    raw, lines = measurements.read_cells(Path(table), sep, f"a {what} file (.csv)")
    return _filled(Cells(raw, tuple(f"line {k}" for k in lines), str(table)), what)


def _filled(cells: Cells, what: str) -> Cells:
    if len(cells.raw) == 0:
        raise ValueError(f"{cells.source}: no {what} rows")
    return cells


def column(cells: Cells, name: str, decimal: str = ".") -> Array:
    """The numbers of column ``name`` (file units); ValueError naming the row and column of an
    empty cell or one that is not a finite number."""
    import pandas as pd

    text = cells.raw[name].astype(str).str.strip()
    values = pd.to_numeric(text.str.replace(decimal, ".", regex=False), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        what = "empty" if text.iloc[k] == "" else f"{text.iloc[k]!r} is not a finite number"
        raise ValueError(f"{cells.source}, {cells.where[k]}, column {name!r}: {what}")
    return values


# --- which columns --------------------------------------------------------------------------------------
def split_unit(name: str) -> tuple[str, str | None]:
    """A column name and the unit after its last underscore (``x_mm`` -> ``("x", "mm")``)."""
    base, _, unit = name.rpartition("_")
    return (base, unit) if base and unit in UNITS else (name, None)


def columns_of(cells: Cells, robot: ZRPRobot, kind: str, convention: str | None) -> Columns:
    """What the columns hold (module docstring); ValueError for a column given twice (with and
    without a unit), missing columns, a kind the columns do not have."""
    names = list(cells.raw.columns)
    convention = convention or orientation.implied({split_unit(n)[0] for n in names})
    quaternion = convention == orientation.QUATERNION
    base = {n: _key(n, quaternion) for n in names}
    for n in names:
        twins = [m for m in names if base[m] == base[n]]
        if len(twins) > 1:
            raise ValueError(f"{cells.source}: columns {', '.join(map(repr, twins))} both give {base[n]!r}; which to use "
                             "cannot be told: remove all but one")  # fmt: skip
    by_base = {base[n]: n for n in names}
    joints, joint_names = _joint_columns(cells, robot, by_base, quaternion)
    has_xyz = all(c in by_base for c in "xyz")
    if kind == "cartesian" and not has_xyz:
        missing = next(c for c in "xyz" if c not in by_base)
        raise ValueError(f"{cells.source}: missing column {missing!r} of a Cartesian program; columns found: {', '.join(names)}")
    if (kind == "joints" or not has_xyz) and joints is None:
        raise ValueError(f"{cells.source}: missing joint columns q1 .. q{robot.n} (or {', '.join(robot.joint_names or ())}); "
                         f"columns found: {', '.join(names)}".replace(" (or )", ""))  # fmt: skip
    cartesian = has_xyz and kind != "joints"
    position = tuple(by_base[c] for c in "xyz") if cartesian else None
    rot = _orientation_columns(cells, by_base, convention) if cartesian else None
    units = {"position": _group_unit(cells, position), "orientation": _group_unit(cells, rot),
             "joints_length": _group_unit(cells, _typed(joints, robot, "P")), "joints_angle": _group_unit(cells, _typed(joints, robot, "R"))}  # fmt: skip
    return Columns(joints, joint_names, position, rot, convention, units)


def _key(name: str, quaternion: bool) -> str:
    """What a column gives: its name without the unit; a quaternion's q1..q4 (no unit) apart from
    joint columns q1_deg .."""
    base, unit = split_unit(name)
    return f"quaternion {base}" if quaternion and unit is None and base in orientation.NAMED[orientation.QUATERNION] else base


def _typed(joints: tuple[str, ...] | None, robot: ZRPRobot, t: str) -> tuple[str, ...] | None:
    return None if joints is None else tuple(c for c, jt in zip(joints, robot.joint_types) if jt == t) or None


def _joint_columns(cells: Cells, robot: ZRPRobot, by_base: dict, quaternion: bool):
    """The joint columns (actual names) and their base names: ``q1 .. qn`` or the robot's joint
    names; with a quaternion, ``q`` columns with a unit or the joint names."""
    qs = [b for b in by_base if b.startswith("q") and b[1:].isdigit()]
    if qs:
        want = [f"q{i + 1}" for i in range(robot.n)]
        if sorted(qs) != sorted(want):
            raise ValueError(f"{cells.source}: joint columns {', '.join(by_base[b] for b in qs)}, but {robot.name} has {robot.n} "
                             f"joints (q1 .. q{robot.n})")  # fmt: skip
        return tuple(by_base[b] for b in want), tuple(want)
    if robot.joint_names and all(c in by_base for c in robot.joint_names):
        return tuple(by_base[c] for c in robot.joint_names), tuple(robot.joint_names)
    return None, None


def _orientation_columns(cells: Cells, by_base: dict, convention: str | None) -> tuple[str, ...] | None:
    """The orientation columns of ``convention`` (its own names, or rx, ry, rz for three
    angles), None when the program has none; ValueError for a partial group or rx, ry, rz
    without a stated convention."""
    own = orientation.columns(convention) if convention else ()
    if convention == orientation.QUATERNION:
        by_base = {k.removeprefix("quaternion "): v for k, v in by_base.items() if k.startswith("quaternion ")}
    groups = [own] + ([orientation.GENERIC] if convention is None or orientation.is_angle(convention) else [])
    for group in groups:
        present = [c for c in group if c in by_base]
        if not present:
            continue
        if len(present) < len(group):
            missing = next(c for c in group if c not in by_base)
            raise ValueError(f"{cells.source}: missing column {missing!r} (an orientation takes {', '.join(group)})")
        if convention is None:
            raise ValueError(f"{cells.source}: columns rx, ry, rz need their orientation convention, orientation_convention "
                             "(--orientation-convention): an Euler sequence (ZYX as KUKA's A, B, C; xyz as Fanuc's W, P, R; "
                             "XYZ intrinsic), rotvec (Universal Robots) or quaternion")  # fmt: skip
        return tuple(by_base[c] for c in group)
    return None


def _group_unit(cells: Cells, group: tuple[str, ...] | None) -> str | None:
    """The unit a group of columns states in its names (None: none); ValueError if they disagree."""
    if not group:
        return None
    units = {split_unit(c)[1] for c in group}
    if len(units) > 1:
        raise ValueError(f"{cells.source}: columns {', '.join(group)} state different units; give one unit to all of them")
    return units.pop()


# --- units ---------------------------------------------------------------------------------------------
def _stated(position: str | None, prismatic: str | None, setting: str, kind: str, source: str) -> str:
    """The length unit the column names or the setting state (``auto`` when neither does)."""
    named = {u for u in (position, prismatic) if u is not None}
    if len(named) > 1:
        raise ValueError(f"{source}: the positions' columns say {position}, the prismatic joints' {prismatic}; give one length unit")
    if named:
        unit = named.pop()
        if UNITS[unit] != kind:
            raise ValueError(f"{source}: a {kind} column named in {unit}")
        if setting not in (AUTO, unit):
            raise ValueError(f"{source}: the column names say {unit}, {SETTING[kind]} says {setting}; give one")
        return unit
    return setting


def fits(distances_m: Array, robot: ZRPRobot) -> bool:
    """Whether targets at these distances (m) from the base point can be a program of
    ``robot``: their median between :data:`NEAR_BASE` of its reach and its reach plus a tool."""
    reach = reach_m(robot)
    median = float(np.median(distances_m))
    return NEAR_BASE * reach <= median <= reach + TOOL_ALLOWANCE_M


def length_unit_of(source: str, robot: ZRPRobot, unit: str, p_file: Array | None, q_file: Array | None, locate: Locate) -> str:
    """``m`` or ``mm`` (module docstring): from the positions where there are some (``locate``
    maps them to distances from the base point), else from the prismatic joints' limits."""
    if p_file is None:
        return _prismatic_unit(robot, q_file, unit)
    ok = {u: fits(locate(p_file * LENGTH[u], u), robot) for u in LENGTH}
    median = {u: float(np.median(locate(p_file * LENGTH[u], u))) for u in LENGTH}
    where = f"{source}: the targets lie a median {{:.4g}} m from {robot.name}'s base point read in {{}}, and it reaches {reach_m(robot):.3g} m"
    if unit == AUTO:
        good = [u for u in LENGTH if ok[u]]
        if len(good) != 1:
            raise ValueError(where.format(median["m"], "m") + f": cannot tell metres from millimetres; set {SETTING['length']}")
        return good[0]
    other = next(u for u in LENGTH if u != unit)
    if not ok[unit] and ok[other]:
        raise ValueError(where.format(median[unit], unit) + f": they cannot be in {unit}; {SETTING['length']} {other}?")
    return unit


def _prismatic_unit(robot: ZRPRobot, q_file: Array | None, unit: str) -> str:
    """A joint program's length unit: metres if every prismatic value is within its limits in
    metres, else millimetres if so in millimetres."""
    if unit != AUTO:
        return unit
    if q_file is None or not robot.prismatic.any():
        return "m"
    lim, v = robot.joint_limits[robot.prismatic], q_file[:, robot.prismatic]
    within = lambda s: bool(np.all((v * s >= lim[:, 0] - 1e-12) & (v * s <= lim[:, 1] + 1e-12)))
    return "m" if within(1.0) or not within(LENGTH["mm"]) else "mm"


def joint_unit_of(cells: Cells, cols: Columns, robot: ZRPRobot, q_file: Array | None, setting: str) -> str:
    """``rad`` or ``deg`` for the revolute joint columns (module docstring)."""
    unit = cols.units["joints_angle"]
    if unit is not None:
        if UNITS[unit] != "angle":
            raise ValueError(f"{cells.source}: a revolute joint column named in {unit}")
        if setting not in (AUTO, unit):
            raise ValueError(f"{cells.source}: the joint columns' names say {unit}, {SETTING['angle']} says {setting}; give one")
        return unit
    if setting != AUTO or q_file is None:
        return "rad" if setting == AUTO else setting
    return revolute_unit(q_file, robot)


def revolute_unit(q_file: Array, robot: ZRPRobot) -> str:
    """``deg`` when a revolute joint value of ``q_file`` (M, n) lies beyond any turn in radians
    (:func:`zrp_ga.io.measurements.resolve_joint_unit`), or outside its joint's limits in
    radians but inside them in degrees; else ``rad``."""
    rev = ~robot.prismatic
    v, lim = np.atleast_2d(q_file)[:, rev], robot.joint_limits[rev]
    if measurements.resolve_joint_unit(v, robot, AUTO) == "deg":
        return "deg"
    outside = lambda s: bool(np.any((v * s < lim[:, 0] - 1e-12) | (v * s > lim[:, 1] + 1e-12)))
    return "deg" if outside(1.0) and not outside(ANGLE["deg"]) else "rad"


def check_joints(q: Array, robot: ZRPRobot, names, cells: Cells, units: dict) -> None:
    """Joint values (M, n) SI within the robot's limits (revolute values beyond any turn:
    degrees?); ValueError naming the row and column."""
    lim = robot.joint_limits
    for j, (name, t) in enumerate(zip(names, robot.joint_types)):
        unit = units["length"] if t == "P" else units["angle"]
        scale = LENGTH[unit] if t == "P" else ANGLE[unit]
        for k in np.flatnonzero((q[:, j] < lim[j, 0] - 1e-12) | (q[:, j] > lim[j, 1] + 1e-12))[:1]:
            hint = f"; in degrees? {SETTING['angle']} deg" if t == "R" and unit == "rad" and abs(q[k, j]) > turn_rad(robot) else ""
            raise ValueError(f"{cells.source}, {cells.where[k]}, column {name!r}: {q[k, j] / scale:.6g} {unit} is outside joint "
                             f"{j + 1}'s limits [{lim[j, 0] / scale:.6g}, {lim[j, 1] / scale:.6g}] {unit}{hint}")  # fmt: skip


def _orientation(cells: Cells, cols: Columns, number, setting: str, joint_unit: str):
    """Rotation matrices (M, 3, 3), the program's own numbers (rad, or quaternions) and their
    unit, or Nones; angles' unit from the names, the setting, or the data (module docstring)."""
    if cols.orientation is None:
        return None, None, joint_unit
    values = np.column_stack([number(c) for c in cols.orientation])
    conv = _convention(cols)
    if not orientation.is_angle(conv):
        bad = np.flatnonzero(orientation.quaternion_norms(values) > orientation.UNIT_QUATERNION_TOL)
        if bad.size:
            k = int(bad[0])
            raise ValueError(f"{cells.source}, {cells.where[k]}: the quaternion {', '.join(cols.orientation)} has norm "
                             f"{np.linalg.norm(values[k]):.6g}, not 1: not a rotation")  # fmt: skip
        return orientation.to_matrices(values / np.linalg.norm(values, axis=1, keepdims=True), conv), values, "rad"
    unit = _angle_unit(cells, cols, values, setting, joint_unit)
    angles = values * ANGLE[unit]
    return orientation.to_matrices(angles, conv), angles, unit


def _convention(cols: Columns) -> str:
    """The orientation columns' convention (there are orientation columns)."""
    assert cols.convention is not None  # orientation columns are found only with their convention (_orientation_columns)
    return cols.convention


def _angle_unit(cells: Cells, cols: Columns, values: Array, setting: str, joint_unit: str) -> str:
    named = cols.units["orientation"]
    if named is not None:
        if UNITS[named] != "angle" or setting not in (AUTO, named):
            raise ValueError(f"{cells.source}: the orientation columns' names say {named}, {SETTING['angle']} says {setting}")
        return named
    beyond = np.abs(values) > 1.05 * 2 * np.pi
    if setting == "rad" and beyond.any():
        k, j = (int(i) for i in np.argwhere(beyond)[0])
        assert cols.orientation is not None  # the values are the orientation columns' (_orientation)
        raise ValueError(f"{cells.source}, {cells.where[k]}, column {cols.orientation[j]!r}: {values[k, j]:g} rad is beyond any "
                         f"turn; in degrees? {SETTING['angle']} deg")  # fmt: skip
    if setting != AUTO:
        return setting
    return "deg" if beyond.any() or (joint_unit == "deg" and cols.joints is not None) else "rad"


# --- arrays -------------------------------------------------------------------------------------------
def _array_program(program: Any, robot: ZRPRobot, kind: str, convention: str | None) -> Program:
    """An array program in SI units (:func:`read_program`); poses' rotations checked."""
    try:
        a = np.asarray(program, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"program: not an array of numbers (rows of different lengths?): {exc}") from None
    if a.size == 0:
        raise ValueError("program: no program rows")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"program: NaN or inf at index {tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])}")
    where = tuple(f"row {k}" for k in range(len(a)))
    names = tuple(f"q{i + 1}" for i in range(robot.n))
    cells = Cells(None, where, "program")
    if kind == "joints" and a.ndim == 2 and a.shape[1] == robot.n:
        check_joints(a, robot, names, cells, {"length": "m", "angle": "rad"})
        return Program("joints", a, None, None, where, "program", names, length_unit="m", angle_unit="rad", convention=convention)
    if kind == "cartesian" and a.ndim == 2 and a.shape[1] == 3:
        return Program("cartesian", None, a, None, where, "program", names, length_unit="m", angle_unit="rad",
                       convention=convention)  # fmt: skip
    if kind == "cartesian" and a.shape[1:] == (4, 4):
        frames.check_rotations(a[:, :3, :3], "program", where)
        if np.abs(a[:, 3] - [0, 0, 0, 1]).max() > frames.ROTATION_TOL:
            raise ValueError("program: the last row of every pose (4, 4) is 0 0 0 1")
        return Program("cartesian", None, a[:, :3, 3], a[:, :3, :3], where, "program", names, length_unit="m",
                       angle_unit="rad", convention=convention or ROTVEC)  # fmt: skip
    raise ValueError(f"program: an array of shape {a.shape} with kind={kind!r}; expected kind='joints' with (M, {robot.n}) "
                     "or kind='cartesian' with (M, 3) positions or (M, 4, 4) poses")  # fmt: skip


# --- work objects from files --------------------------------------------------------------------------
def read_work_object(source: Any, robot: ZRPRobot, length_unit: str, angle_unit: str, convention: str | None,
                     sep: str, decimal: str, locate: Locate) -> tuple[Array, str, Array | None]:  # fmt: skip
    """A work object (4, 4) m from a file or table: three rows O, X, Y of ``x, y, z`` (in that
    order, or named in a column ``point``), or one row of a pose (``x, y, z`` and an
    orientation's columns); what it was (for the record) and its three points (3, 3) m (None
    for a pose). Units as a program's
    (:func:`read_program`), ``locate`` as there, for the points' frame."""
    cells = table_cells(source, sep, "work object")
    cols = columns_of(cells, robot, "cartesian", convention)
    assert cols.position is not None  # columns_of refuses a Cartesian table without x, y, z
    p_file = np.column_stack([column(cells, c, decimal) for c in cols.position])
    length = length_unit_of(cells.source, robot, _stated(cols.units["position"], None, length_unit, "length", cells.source),
                            p_file, None, locate)  # fmt: skip
    p = p_file * LENGTH[length]
    if cols.orientation is not None:
        if len(p) != 1:
            raise ValueError(f"{cells.source}: a work object given as a pose is one row, got {len(p)}")
        R, _, _ = _orientation(cells, cols, lambda c: column(cells, c, decimal), angle_unit, "rad")
        return frames.transform(R[0], p[0]), f"the pose in {cells.source} ({length})", None
    if len(p) != 3:
        raise ValueError(f"{cells.source}: a work object is three points O, X, Y (or one pose with its orientation); got {len(p)} rows")
    order = _point_order(cells)
    try:
        return frames.work_object(*p[order]), f"three points O, X, Y in {cells.source} ({length})", p[order]
    except ValueError as exc:
        raise ValueError(f"{cells.source}: {exc}".replace("work object: ", "")) from None


def _point_order(cells: Cells) -> list[int]:
    if "point" not in cells.raw.columns:
        return [0, 1, 2]
    names = [str(v).strip().upper() for v in cells.raw["point"]]
    if sorted(names) != ["O", "X", "Y"]:
        raise ValueError(f"{cells.source}: column 'point' names {', '.join(names)}; expected O, X and Y")
    return [names.index(k) for k in ("O", "X", "Y")]
