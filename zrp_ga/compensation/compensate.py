"""Compensation: a calibration turned into corrected joint values and corrected Cartesian targets
for a robot program (Albright and Schroer's practical compensation for
off-line programming).

The controller computes joint values from the nominal model; the arm behaves like the
calibrated one. For each target ``T*`` (a pose, or a position) in the robot's base frame:

1. ``q_nom``: the nominal solution. A joint-value program gives it (``T* = FK_nom(q_prog)``,
   the pose the program means); for a Cartesian program it is the nominal inverse kinematics
   ``IK_nom(T*)`` from a seed configuration (see :func:`compensate`).
2. ``q* = IK_cal(T*)``: damped least squares on the calibrated model
   (``scipy.optimize.least_squares``, trust-region reflective, joint limits as bounds, the
   geometric Jacobian), started from ``q_nom``, so that the arm stays on the program's branch.
3. Joint compensation: send ``q*``. Cartesian compensation: send ``T_c = FK_nom(q*)``; a
   controller solving ``IK_nom(T_c)`` on the same branch gets ``q*`` back.

Beside each target: the predicted residual ``FK_cal(q*) - T*`` (mm, deg), the error the
calibrated model predicts for the uncompensated program ``FK_cal(q_nom) - T*`` and the size of
the correction, ``|q* - q_nom|`` (deg for revolute, mm for prismatic joints) and
``|T_c - T*|`` (mm, deg). A target the calibrated arm cannot reach within its joint limits (to
``tolerance_m`` and ``tolerance_rad``) is named with its line and why.

Frames. Targets are in the robot's base frame, the frame of the nominal model that the
controller uses. A run on measured data identifies the arm in the instrument's frame and
exports it (``calibrated_robot.yaml``) in the base frame found by its registration: the same
frame, so programs go in unchanged. Targets in the instrument's frame (a point measured by the
tracker) go through the run's base transform (``frame="instrument"``): ``T_base = base^-1 T``.

Orientation. Arms of six joints or more get full poses (position and orientation) unless
``position_only``; arms with fewer joints cannot reach arbitrary orientations and get
positions only (their hand orientation then follows from the solution).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from zrp_ga.core.checks import ROTVEC, check_convention
from zrp_ga.io.measurements import ANGLE, LENGTH, reach_m, turn_rad
from zrp_ga.model import kinematics, so3
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.run import directory

Array = NDArray[np.float64]
TOLERANCE_M = 1e-6  # a target counts as reached within this position residual, m
TOLERANCE_RAD = 1e-6  # and this orientation residual, rad
ORIENTATION_LENGTH_M = 1.0  # 1 rad of orientation residual weighs as this many metres in the fit
NEWTON_STEPS = 20  # Gauss-Newton steps before the bounded solver takes over
NEWTON_DONE = 1e-14  # residual norm (m, rad) at which the steps stop: round-off
KINDS = ("auto", "joints", "cartesian")
RUN_MODEL = "calibrated_robot.yaml"


# --- the calibration ------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Arms:
    """The calibrated and the nominal arm (the same joints, base frame), the base transform (4, 4)
    from the robot's base to the instrument's frame (None when the calibration had none), where
    they came from, what to know about them and the calibration's tool (4, 4) in the hand frame
    (None: the calibration measured the end point itself)."""

    calibrated: ZRPRobot
    nominal: ZRPRobot
    base: Array | None = None
    source: str = "calibration"
    notes: tuple[str, ...] = ()
    tool: Array | None = None  # (4, 4) the calibration's (first) measured tool point in the hand frame


def load_arms(calibration: Any, nominal: ZRPRobot | str | Path | None = None) -> Arms:
    """The arms of ``calibration``: a run directory of ``zrp-ga`` (its ``calibrated_robot.yaml``;
    the nominal arm from ``summary.json``), a calibrated robot file (any file
    :func:`zrp_ga.io.robot_files.read_robot` reads, in the robot's base frame; the nominal arm from
    ``summary.json`` beside it or ``nominal``), a :class:`ZRPRobot` or what
    :func:`zrp_ga.calibrate` returns. ``nominal`` (a robot, a preset name or a robot file)
    replaces the run's nominal arm."""
    from zrp_ga.io.robot_files import read_robot

    base, notes, nom, tool = None, [], None, None
    if isinstance(calibration, ZRPRobot):
        cal, source = calibration, "the calibrated robot"
    elif hasattr(calibration, "task") and hasattr(calibration, "summary"):  # zrp_ga.api.Calibration
        task = calibration.task
        x = np.array([calibration.summary["best_genome"][k] for k in task.problem.names])
        cal, base, tools = task.export(x)
        tool = next(iter(tools.values()), None)
        nom, source = task.robot, "the calibration"
    else:
        path = Path(calibration)
        run = path if path.is_dir() else path.parent if (path.parent / directory.SUMMARY).is_file() else None
        if path.is_dir():
            _check_run_dir(path)
            path = path / RUN_MODEL
        elif run is not None and path.suffix.lower() in (".urdf", ".xml"):
            raise ValueError(f"{path}: a run's URDF carries its base and tool frames (an instrument's frame); "
                             f"give the run directory {run} (or its {RUN_MODEL}, the arm in its base frame)")  # fmt: skip
        cal, source = read_robot(path), str(path)
        if run is not None:
            nom, base, tool, notes = _run_info(run)
    if nominal is not None:
        nom = _robot(nominal)
    if nom is None:
        raise ValueError(f"{source}: no nominal robot with it; give the nominal arm (a preset name or a robot file)")
    if (nom.n, nom.joint_types) != (cal.n, cal.joint_types):
        raise ValueError(f"{source}: the calibrated arm has joints {cal.joint_types}, the nominal {nom.name} "
                         f"{nom.joint_types}: not the same arm")  # fmt: skip
    return Arms(cal, nom, base, source, tuple(notes), tool)


def _check_run_dir(path: Path) -> None:
    if (path / RUN_MODEL).is_file():
        return
    jobs = sorted(p.parent.name for p in path.glob(f"*/{RUN_MODEL}"))
    hint = f"; a sweep directory? give one of its jobs ({path / jobs[0]}, ...)" if jobs else ""
    raise ValueError(f"{path}: not a calibration run directory (no {RUN_MODEL}){hint}")


def _run_info(run: Path) -> tuple[ZRPRobot | None, Array | None, Array | None, list[str]]:
    """The nominal arm, the base transform, the first tool and notes from a run's ``summary.json``."""
    path = run / directory.SUMMARY
    if not path.is_file():
        return None, None, None, []
    try:
        s = json.loads(path.read_text())
    except ValueError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from None
    nominal = ZRPRobot.from_dict(s["robot_model"], source=f"{path}: robot_model") if "robot_model" in s else None
    files = s.get("calibrated_robot") or {}
    base, tool = files.get("base"), next(iter((files.get("tools") or {}).values()), None)
    notes = []
    if s.get("returned") == "nominal":
        notes.append(f"{path}: the run returned the nominal arm (it fitted no better): nothing to correct")
    problem = (s.get("config") or {}).get("problem") or {}
    if problem.get("position_only") or problem.get("use_orientation") is False:
        notes.append("the arm was calibrated on positions only: its orientations are not all identified; "
                     "position targets (position_only) of the measured point (tool='calibration') are what it predicts best")
    arr = lambda a: None if a is None else np.array(a, dtype=float)
    return nominal, arr(base), arr(tool), notes


def _robot(robot: ZRPRobot | str | Path) -> ZRPRobot:
    from zrp_ga.io import presets
    from zrp_ga.io.robot_files import read_robot

    if isinstance(robot, ZRPRobot):
        return robot
    return presets.get(str(robot)) if str(robot) in presets.names() else read_robot(robot)


def with_tool(robot: ZRPRobot, tool: ArrayLike | None) -> ZRPRobot:
    """``robot`` ending at a tool: ``tool`` an offset (3,) m or a transform (4, 4) in the hand frame."""
    if tool is None:
        return robot
    T = np.asarray(tool, dtype=float)
    if T.shape == (3,):
        return robot.with_tool(T)
    if T.shape != (4, 4) or not np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-9):
        raise ValueError(f"tool: expected an offset (3,) or a 4x4 transform, got shape {T.shape}")
    return robot.with_tool(T[:3, 3]).replace(R_h0=robot.R_h0 @ T[:3, :3])


# --- the program ----------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Program:
    """A program in SI units: ``kind`` ``joints`` (``q`` (M, n) the program) or ``cartesian``
    (``p`` (M, 3) m, ``R`` (M, 3, 3) or None, ``q`` (M, n) seed configurations or None); each
    row's place ``where`` ("line 7" of a file, "row 3" of a table), the joint column names and
    the units it was written in."""

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

    @property
    def M(self) -> int:
        return len(self.where)


def read_program(
    program: Any, robot: ZRPRobot, kind: str = "auto", length_unit: str = "m", angle_unit: str = "rad",
    orientation_convention: str | None = None, sep: str = ",", decimal: str = ".",
) -> Program:  # fmt: skip
    """A program from a CSV file, a pandas DataFrame or an array.

    Columns: ``x, y, z`` (a Cartesian program; ``rx, ry, rz`` for the orientation, in
    ``orientation_convention``: an Euler sequence as scipy reads it, or ``rotvec``) with
    optional joint columns as each row's seed configuration; or joint columns only (a
    joint-value program). Joint columns are ``q1 .. qn`` or the robot's joint names. Units:
    ``length_unit`` (m, mm) for positions and prismatic joints, ``angle_unit`` (rad, deg) for
    revolute joints and orientations. Arrays: ``kind="joints"`` (M, n), or ``"cartesian"``
    positions (M, 3) or poses (M, 4, 4), SI units.
    """
    if kind not in KINDS:
        raise ValueError(f"kind: {kind!r}, expected one of {', '.join(KINDS)}")
    if length_unit not in LENGTH or angle_unit not in ANGLE:
        raise ValueError(f"units: length {length_unit!r}, angle {angle_unit!r}; expected {'/'.join(LENGTH)} and {'/'.join(ANGLE)}")
    check_convention(orientation_convention, "orientation convention")
    units = dict(length_unit=length_unit, angle_unit=angle_unit, convention=orientation_convention)
    if isinstance(program, np.ndarray | list | tuple):
        return _array_program(np.asarray(program, dtype=float), robot, kind, **units)
    import pandas as pd

    if isinstance(program, pd.DataFrame):
        raw, source = program.astype(str), "the program"
        where = tuple(f"row {i}" for i in program.index)
    else:
        raw, where, source = _read_csv(Path(program), sep)
    raw.columns = [str(c).strip() for c in raw.columns]
    if len(raw) == 0:
        raise ValueError(f"{source}: no program rows")
    joints = _joint_columns(raw, robot, source)
    has_xyz = all(c in raw.columns for c in "xyz")
    if kind == "auto":
        kind = "cartesian" if has_xyz else "joints"
    if kind == "cartesian" and not has_xyz:
        missing = next(c for c in "xyz" if c not in raw.columns)
        raise ValueError(f"{source}: missing column {missing!r} of a Cartesian program; columns found: {', '.join(raw.columns)}")
    if kind == "joints" and joints is None:
        raise ValueError(f"{source}: missing joint columns q1 .. q{robot.n} (or {', '.join(robot.joint_names or ())}); "
                         f"columns found: {', '.join(raw.columns)}".replace(" (or )", ""))  # fmt: skip
    number = lambda c: _column(raw, c, where, source, decimal)
    q = None
    if joints is not None:
        L, A = LENGTH[length_unit], ANGLE[angle_unit]
        q = np.column_stack([number(c) * (L if t == "P" else A) for c, t in zip(joints, robot.joint_types)])
        _check_joints(q, robot, joints, where, source, units)
    p = R = None
    if kind == "cartesian":
        p = np.column_stack([number(c) for c in "xyz"]) * LENGTH[length_unit]
        if any(c in raw.columns for c in ("rx", "ry", "rz")):
            absent = [c for c in ("rx", "ry", "rz") if c not in raw.columns]
            if absent:
                raise ValueError(f"{source}: missing column {absent[0]!r} (an orientation takes rx, ry and rz)")
            if not orientation_convention:
                raise ValueError(f"{source}: columns rx, ry, rz need their orientation convention (an Euler sequence such "
                                 "as XYZ intrinsic or xyz extrinsic, or rotvec as UR controllers use)")  # fmt: skip
            angles = np.column_stack([number(c) for c in ("rx", "ry", "rz")]) * ANGLE[angle_unit]
            rot = Rotation.from_rotvec(angles) if orientation_convention == ROTVEC else Rotation.from_euler(orientation_convention, angles)
            R = rot.as_matrix()
    names = tuple(joints or (f"q{i + 1}" for i in range(robot.n)))
    return Program(kind, q, p, R, where, source, names, **units)


def _read_csv(path: Path, sep: str):
    """The cells of a CSV file as text, and each row's line (the header is line 1; blank lines skipped)."""
    import pandas as pd

    if not path.exists():
        raise ValueError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected a program file (.csv)")
    try:
        raw = pd.read_csv(path, sep=sep, dtype=str, keep_default_na=False, skip_blank_lines=False)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise ValueError(f"{path}: cannot be read as a '{sep}'-separated file ({exc})".replace("\n", " ")) from None
    lines = np.arange(len(raw)) + 2
    filled = (raw.apply(lambda col: col.str.strip()) != "").any(axis=1).to_numpy() if len(raw) else np.zeros(0, bool)
    if not filled.any():
        raise ValueError(f"{path}: no program rows")
    return raw[filled].reset_index(drop=True), tuple(f"line {k}" for k in lines[filled]), str(path)


def _joint_columns(raw, robot: ZRPRobot, source: str) -> tuple[str, ...] | None:
    """``q1 .. qn`` or the robot's joint names, if the table has them (a wrong count is an error)."""
    qs = [c for c in raw.columns if c.startswith("q") and c[1:].isdigit()]
    if qs:
        want = [f"q{i + 1}" for i in range(robot.n)]
        if sorted(qs) != sorted(want):
            raise ValueError(f"{source}: joint columns {', '.join(qs)}, but {robot.name} has {robot.n} joints (q1 .. q{robot.n})")
        return tuple(want)
    if robot.joint_names and all(c in raw.columns for c in robot.joint_names):
        return tuple(robot.joint_names)
    return None


def _column(raw, column: str, where: tuple[str, ...], source: str, decimal: str) -> Array:
    import pandas as pd

    text = raw[column].str.strip()
    values = pd.to_numeric(text.str.replace(decimal, ".", regex=False), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        what = "empty" if text.iloc[k] == "" else f"{text.iloc[k]!r} is not a finite number"
        raise ValueError(f"{source}, {where[k]}, column {column!r}: {what}")
    return values


def _check_joints(q: Array, robot: ZRPRobot, names, where, source: str, units: dict) -> None:
    """Joint values within the robot's limits (revolute values beyond any turn: degrees?)."""
    lim = robot.joint_limits
    for j, (name, t) in enumerate(zip(names, robot.joint_types)):
        scale, unit = (LENGTH[units["length_unit"]], units["length_unit"]) if t == "P" else (ANGLE[units["angle_unit"]], units["angle_unit"])
        for k in np.flatnonzero((q[:, j] < lim[j, 0] - 1e-12) | (q[:, j] > lim[j, 1] + 1e-12))[:1]:
            hint = "; in degrees? give the angle unit deg" if t == "R" and unit == "rad" and abs(q[k, j]) > turn_rad(robot) else ""
            raise ValueError(f"{source}, {where[k]}, column {name!r}: {q[k, j] / scale:.6g} {unit} is outside joint {j + 1}'s "
                             f"limits [{lim[j, 0] / scale:.6g}, {lim[j, 1] / scale:.6g}] {unit}{hint}")  # fmt: skip


def _array_program(a: Array, robot: ZRPRobot, kind: str, **units) -> Program:
    if a.size == 0:
        raise ValueError("program: no program rows")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"program: NaN or inf at index {tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])}")
    where = tuple(f"row {k}" for k in range(len(a)))
    names = tuple(f"q{i + 1}" for i in range(robot.n))
    si = dict(length_unit="m", angle_unit="rad", convention=units["convention"])
    if kind == "joints" and a.ndim == 2 and a.shape[1] == robot.n:
        _check_joints(a, robot, names, where, "program", si)
        return Program("joints", a, None, None, where, "program", names, **si)
    if kind == "cartesian" and a.ndim == 2 and a.shape[1] == 3:
        return Program("cartesian", None, a, None, where, "program", names, **si)
    if kind == "cartesian" and a.shape[1:] == (4, 4):
        return Program("cartesian", None, a[:, :3, 3], a[:, :3, :3], where, "program", names, **si)
    raise ValueError(f"program: an array of shape {a.shape} with kind={kind!r}; expected kind='joints' with (M, {robot.n}) "
                     "or kind='cartesian' with (M, 3) positions or (M, 4, 4) poses")  # fmt: skip


# --- inverse kinematics -----------------------------------------------------------------------------
def forward_jacobian(robot: ZRPRobot, q: ArrayLike) -> tuple[Array, Array, Array]:
    """Hand orientation R (3, 3), position p (3,) m and the geometric Jacobian J (6, n) at ``q``
    (n,): rows 0-2 the hand's angular velocity, rows 3-5 its linear velocity per unit joint
    velocity. Joint i turns about ``u_i = R_{i-1} u0_i`` through the point ``o_i`` on it
    (Eq. 1-5 of the ZRP paper): revolute ``[u_i; u_i x (p - o_i)]``, prismatic ``[0; u_i]``."""
    q = np.asarray(q, dtype=float)
    R, p = np.eye(3), np.zeros(3)
    axes, points = np.empty((robot.n, 3)), np.empty((robot.n, 3))
    for i in range(robot.n):
        p = p + R @ robot.b0[i]
        axes[i], points[i] = R @ robot.u0[i], p
        if robot.prismatic[i]:
            p = p + q[i] * axes[i]
        else:
            R = R @ so3.rodrigues(q[i], robot.u0[i])
    p = p + R @ robot.b0[robot.n]
    rev = ~robot.prismatic
    J = np.zeros((6, robot.n))
    J[:3, rev] = axes[rev].T
    J[3:, rev] = np.cross(axes[rev], p - points[rev]).T
    J[3:, ~rev] = axes[~rev].T
    return R @ robot.R_h0, p, J


@dataclasses.dataclass(frozen=True)
class Solution:
    """One inverse-kinematics solve: joint values ``q``, whether the target was reached, the
    position and orientation residuals (m, rad; orientation 0 for position targets) and the
    joints held at a limit."""

    q: Array
    reached: bool
    position_m: float
    orientation_rad: float
    at_limit: tuple[int, ...]


def solve(robot: ZRPRobot, p: ArrayLike, R: ArrayLike | None, q0: ArrayLike,
          tolerance_m: float = TOLERANCE_M, tolerance_rad: float = TOLERANCE_RAD) -> Solution:  # fmt: skip
    """Joint values within the limits that put ``robot``'s hand on position ``p`` (3,) m and,
    if given, orientation ``R`` (3, 3), from ``q0`` (n,). The residual is ``[p(q) - p;
    ORIENTATION_LENGTH_M log(R(q) R^T)]``, its Jacobian the geometric one mapped through the
    inverse left Jacobian of SO(3). Gauss-Newton steps (least-norm ``numpy.linalg.lstsq``, as
    long as each lowers the residual and stays within the limits) reach a nearby solution in a
    few steps; anything else goes on with ``scipy.optimize.least_squares`` (trust-region
    reflective, the limits as bounds), which also says which joints a limit holds."""
    p = np.asarray(p, dtype=float)
    lower, upper = robot.joint_limits.T
    span = upper - lower
    x0 = np.clip(np.asarray(q0, dtype=float), lower + 1e-9 * span, upper - 1e-9 * span)

    def fun(q):
        Rq, pq, _ = forward_jacobian(robot, q)
        if R is None:
            return pq - p
        return np.concatenate([pq - p, ORIENTATION_LENGTH_M * so3.log(Rq @ R.T)])

    def jac(q):
        Rq, _, J = forward_jacobian(robot, q)
        if R is None:
            return J[3:]
        phi = so3.log(Rq @ R.T)
        return np.vstack([J[3:], ORIENTATION_LENGTH_M * np.linalg.solve(so3.left_jacobian(phi), J[:3])])

    q, r = x0, fun(x0)
    for _ in range(NEWTON_STEPS):
        if np.linalg.norm(r) <= NEWTON_DONE:
            break
        q_new = q + np.linalg.lstsq(jac(q), -r, rcond=None)[0]
        r_new = fun(q_new)
        if np.any(q_new < lower) or np.any(q_new > upper) or not np.linalg.norm(r_new) < np.linalg.norm(r):
            break
        q, r = q_new, r_new
    held: tuple[int, ...] = ()
    if np.linalg.norm(r) > NEWTON_DONE:
        fit = least_squares(fun, np.clip(q, lower + 1e-9 * span, upper - 1e-9 * span), jac=jac, bounds=(lower, upper),
                            method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=30 * robot.n)  # fmt: skip
        q, held = np.clip(fit.x, lower, upper), tuple(int(i) for i in np.flatnonzero(fit.active_mask))
    Rq, pq = kinematics.forward(robot, q)
    dp = float(np.linalg.norm(pq - p))
    dr = 0.0 if R is None else _angle(Rq, R)
    reached = dp <= tolerance_m and dr <= tolerance_rad
    return Solution(q, reached, dp, dr, held)


def _angle(A: Array, B: Array) -> float:
    """The angle (rad) of the rotation between A and B (3, 3)."""
    return float(np.linalg.norm(so3.log(A @ B.T)))


# --- compensation ---------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Compensation:
    """The compensated program (:func:`compensate`), per target (M rows): the corrected joint
    values ``q`` (M, n) (rad, m; NaN where not reached), the nominal solution ``q_nominal``, the
    targets ``p`` (M, 3) m and ``R`` (M, 3, 3) (None for positions), the corrected Cartesian
    targets ``p_corrected``, ``R_corrected`` (what a controller using the nominal model is
    sent), the predicted residuals and uncompensated errors (mm, deg), the correction sizes, and
    ``reasons`` (empty where reached)."""

    program: Program
    arms: Arms
    q: Array
    q_nominal: Array
    p: Array
    R: Array | None
    p_corrected: Array
    R_corrected: Array
    residual_mm: Array
    residual_deg: Array
    uncompensated_mm: Array
    uncompensated_deg: Array
    reached: NDArray[np.bool_]
    reasons: tuple[str, ...]

    @property
    def unreachable(self) -> list[str]:
        """``"line 7: why"`` for every target not reached."""
        return [f"{w}: {r}" for w, r, ok in zip(self.program.where, self.reasons, self.reached) if not ok]

    def correction(self) -> dict[str, Array]:
        """Size of the correction per target: the largest revolute joint change ``dq_deg`` and
        prismatic ``dq_mm`` (absent without prismatic joints), the Cartesian ``dx_mm`` and ``dr_deg``."""
        dq = np.abs(self.q - self.q_nominal)
        pri = self.arms.calibrated.prismatic
        out = {"dq_deg": np.degrees(dq[:, ~pri].max(axis=1, initial=0.0))}
        if pri.any():
            out["dq_mm"] = dq[:, pri].max(axis=1) * 1e3
        out["dx_mm"] = np.linalg.norm(self.p_corrected - self.p, axis=1) * 1e3
        R_ref, _ = kinematics.forward(self.arms.nominal, self.q_nominal)
        out["dr_deg"] = np.degrees(np.linalg.norm(so3.log(self.R_corrected @ np.swapaxes(R_ref, 1, 2)), axis=-1))
        return {k: np.where(self.reached, v, np.nan) for k, v in out.items()}

    def tables(self) -> tuple[list[dict], list[dict]]:
        """Rows of ``joints.csv`` and ``targets.csv`` (:meth:`write`), in the program's units."""
        pr = self.program
        L, A = LENGTH[pr.length_unit], ANGLE[pr.angle_unit]
        scale = np.where(self.arms.calibrated.prismatic, L, A)
        convention = pr.convention or ROTVEC
        rot = Rotation.from_matrix(self.R_corrected)
        angles = (rot.as_rotvec() if convention == ROTVEC else rot.as_euler(convention)) / A
        stats = self._stats()
        joints, targets = [], []
        for k in range(pr.M):
            ok = bool(self.reached[k])
            head = {"line": pr.where[k].split()[-1], "status": "ok" if ok else f"unreachable: {self.reasons[k]}"}
            joints.append({**head, **{c: self.q[k, j] / scale[j] if ok else "" for j, c in enumerate(pr.joint_columns)},
                           **stats[k]})  # fmt: skip
            pose = {c: self.p_corrected[k, j] / L if ok else "" for j, c in enumerate("xyz")}
            pose.update({c: angles[k, j] if ok else "" for j, c in enumerate(("rx", "ry", "rz"))})
            targets.append({**head, **pose, **stats[k]})
        return joints, targets

    def _stats(self) -> list[dict]:
        cols = {"residual_mm": self.residual_mm, "uncompensated_mm": self.uncompensated_mm}
        if self.R is not None:
            cols.update(residual_deg=self.residual_deg, uncompensated_deg=self.uncompensated_deg)
        cols.update(self.correction())
        return [{k: float(v[i]) if np.isfinite(v[i]) else "" for k, v in cols.items()} for i in range(self.program.M)]

    def summary(self) -> dict[str, Any]:
        """What ``compensation.json`` holds: sources, frame, units, counts, the largest and RMS
        residuals and corrections, the unreachable targets."""
        ok = self.reached
        stat = lambda v: {"max": float(np.max(v[ok])), "rms": float(np.sqrt(np.mean(v[ok] ** 2)))} if ok.any() else None
        cols = {"residual_mm": self.residual_mm, "uncompensated_mm": self.uncompensated_mm}
        if self.R is not None:
            cols.update(residual_deg=self.residual_deg, uncompensated_deg=self.uncompensated_deg)
        cols.update(self.correction())
        pr, arms = self.program, self.arms
        return {
            "calibration": arms.source, "program": pr.source, "kind": pr.kind,
            "calibrated_robot": arms.calibrated.name, "nominal_robot": arms.nominal.name,
            "frame": "the robot's base frame (the nominal model's, the controller's)",
            "targets": "poses" if self.R is not None else "positions",
            "units": {"length": pr.length_unit, "angle": pr.angle_unit, "orientation_convention": pr.convention or ROTVEC},
            "rows": pr.M, "reached": int(ok.sum()), "unreachable": self.unreachable,
            "stats": {k: stat(v) for k, v in cols.items()}, "notes": list(arms.notes),
        }  # fmt: skip

    def write(self, out: str | Path) -> dict[str, Path]:
        """``joints.csv`` (line, status, corrected joint values in the program's columns and units,
        the residuals and correction sizes), ``targets.csv`` (the same with the corrected
        Cartesian targets x, y, z, rx, ry, rz) and ``compensation.json`` (:meth:`summary`) in ``out``."""
        from zrp_ga.core import fileio

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        joints, targets = self.tables()
        paths = {"joints": out / "joints.csv", "targets": out / "targets.csv", "summary": out / "compensation.json"}
        fileio.write_csv(paths["joints"], joints)
        fileio.write_csv(paths["targets"], targets)
        fileio.write_json(paths["summary"], self.summary())
        return paths


def compensate(
    calibration: Any,
    program: Any,
    *,
    nominal: ZRPRobot | str | Path | None = None,
    kind: str = "auto",
    q_seed: ArrayLike | None = None,
    tool: ArrayLike | None = None,
    position_only: bool = False,
    frame: str = "base",
    length_unit: str = "m",
    angle_unit: str = "rad",
    orientation_convention: str | None = None,
    sep: str = ",",
    decimal: str = ".",
    unreachable: str = "error",
    tolerance_m: float = TOLERANCE_M,
    tolerance_rad: float = TOLERANCE_RAD,
    out: str | Path | None = None,
) -> Compensation:
    """Corrected joint values and Cartesian targets that bring the calibrated arm to a program's
    targets (module docstring).

    ``calibration``: a ``zrp-ga`` run directory, a calibrated robot file, a :class:`ZRPRobot`
    or what :func:`zrp_ga.calibrate` returns (:func:`load_arms`); ``nominal``: the nominal arm
    when the calibration does not carry it. ``program``: a CSV file, a DataFrame or an array
    (:func:`read_program`; ``kind``, the units, the orientation convention, ``sep`` and
    ``decimal`` say how to read it), targets in the robot's base frame (``frame="instrument"``:
    in the calibration's instrument frame).

    Seeds of a Cartesian program (where the nominal inverse kinematics starts, which decides
    the branch: elbow up or down, wrist flipped): the row's own joint columns if the program has
    them; else the previous row's nominal solution, and for the first row ``q_seed`` (n,) in the
    program's units (default: the middle of the joint limits). A target the seed does not lead
    to is tried from ``q_seed``, then from a few random configurations (seeded by the row:
    the same every time); give seeds where the branch matters.

    ``tool``: an offset (3,) m or a transform (4, 4) in the hand frame, for targets of a tool
    point, or ``"calibration"``: the point the calibration measured (a run's first tool,
    ``calibrated_robot_frames.yaml``); default: the arms' end point (the hand). ``unreachable``: ``"error"`` (a ValueError naming the
    first target not reached, its line and why) or ``"keep"`` (such rows are kept, empty and
    named in ``status``). ``out``: a directory to write ``joints.csv``, ``targets.csv`` and
    ``compensation.json`` into.

    A PUMA 560 whose second joint sits 1 mm off along x: the program as written misses by 1 mm,
    the corrected joints (a tenth of a degree or so on joints 2 to 6: the wrist keeps the
    orientation) do not.

    >>> from zrp_ga.io import presets
    >>> nominal = presets.get("puma560")
    >>> shift = np.zeros((7, 3))
    >>> shift[1, 0] = 0.001  # m
    >>> arm = nominal.replace(b0=nominal.b0 + shift)
    >>> c = compensate(arm, [[0.1, -0.5, 0.3, 0.2, 0.6, -0.1]], nominal=nominal, kind="joints")
    >>> round(float(c.uncompensated_mm[0]), 9), bool(c.residual_mm[0] < 1e-9)
    (1.0, True)
    >>> np.round(np.degrees(c.q[0] - [0.1, -0.5, 0.3, 0.2, 0.6, -0.1]), 3) + 0.0  # deg
    array([ 0.   , -0.033,  0.154,  0.035, -0.118, -0.042])
    """
    if unreachable not in ("error", "keep"):
        raise ValueError(f"unreachable: {unreachable!r}, expected 'error' or 'keep'")
    if frame not in ("base", "instrument"):
        raise ValueError(f"frame: {frame!r}, expected 'base' or 'instrument'")
    arms = load_arms(calibration, nominal)
    if isinstance(tool, str):
        if tool != "calibration":
            raise ValueError(f"tool: {tool!r}, expected 'calibration', an offset (3,) or a transform (4, 4)")
        if arms.tool is None:
            raise ValueError(f"tool: {arms.source} carries no tool (it measured the end point itself)")
        tool = arms.tool
    arms = dataclasses.replace(arms, calibrated=with_tool(arms.calibrated, tool), nominal=with_tool(arms.nominal, tool))
    cal, nom = arms.calibrated, arms.nominal
    pr = read_program(program, nom, kind, length_unit, angle_unit, orientation_convention, sep, decimal)
    orient = not position_only and (pr.R is not None if pr.kind == "cartesian" else nom.n >= 6)
    if pr.kind == "cartesian" and pr.R is not None and nom.n < 6 and not position_only:
        raise ValueError(f"{pr.source}: {nom.name} has {nom.n} joints and cannot reach arbitrary orientations; "
                         "give positions only (x, y, z) or set position_only")  # fmt: skip
    p, R = _targets(pr, arms, frame, orient)
    if frame == "instrument":
        note = "the targets were given in the instrument's frame and mapped through the run's base transform; the outputs are in the base frame"
        arms = dataclasses.replace(arms, notes=(*arms.notes, note))
    tol = dict(tolerance_m=tolerance_m, tolerance_rad=tolerance_rad)
    M, n = pr.M, nom.n
    q_nom, q_cal = np.full((M, n), np.nan), np.full((M, n), np.nan)
    reached, reasons = np.zeros(M, dtype=bool), [""] * M
    seed = first = nom.joint_limits.mean(axis=1) if q_seed is None else _seed(q_seed, nom, pr)
    for k in range(M):
        R_k = None if R is None else R[k]
        if pr.kind == "joints":
            q_nom[k] = pr.q[k]
        else:
            s = _nominal_solution(nom, p[k], R_k, pr.q[k] if pr.q is not None else seed, first, k, tol)
            q_nom[k] = s.q
            if s.reached:
                seed = s.q
        s = solve(cal, p[k], R_k, q_nom[k], **tol)
        q_cal[k], reached[k] = s.q, s.reached
        if not s.reached:
            reasons[k] = _why(cal, p[k], s, R is not None)
    return _result(pr, arms, q_cal, q_nom, p, R, reached, tuple(reasons), unreachable, out)


RESTARTS = 8  # random starts of the nominal inverse kinematics when the seeds do not reach a target


def _nominal_solution(nom: ZRPRobot, p: Array, R: Array | None, start: Array, first: Array, row: int, tol: dict) -> Solution:
    """``IK_nom`` of one target from ``start``; failing that (and within reach), from the first
    seed, then from ``RESTARTS`` random configurations within the limits (seeded by the row)."""
    s = solve(nom, p, R, start, **tol)
    if s.reached or np.linalg.norm(p - nom.b0[0]) > reach_m(nom):
        return s
    lower, upper = nom.joint_limits.T
    rng = np.random.default_rng([row, 21])
    for q0 in [first, *rng.uniform(lower, upper, size=(RESTARTS, nom.n))]:
        t = solve(nom, p, R, q0, **tol)
        if t.reached:
            return t
    return s


def _targets(pr: Program, arms: Arms, frame: str, orient: bool) -> tuple[Array, Array | None]:
    """The targets (M, 3) m and (M, 3, 3) or None, in the robot's base frame."""
    if pr.kind == "joints":
        R, p = kinematics.forward(arms.nominal, pr.q)
        return p, R if orient else None
    p, R = pr.p, pr.R if orient else None
    if frame == "instrument":
        if arms.base is None:
            raise ValueError(f"frame: {arms.source} has no base transform (no instrument frame); give targets in the base frame")
        Rb, tb = arms.base[:3, :3], arms.base[:3, 3]
        p = (p - tb) @ Rb
        R = None if R is None else Rb.T @ R
    return p, R


def _seed(q_seed: ArrayLike, robot: ZRPRobot, pr: Program) -> Array:
    """The first seed (n,) in SI units, from the program's units."""
    q = np.asarray(q_seed, dtype=float)
    if q.shape != (robot.n,) or not np.all(np.isfinite(q)):
        raise ValueError(f"q_seed: expected {robot.n} finite joint values ({pr.angle_unit}, {pr.length_unit}), got {q_seed!r}")
    return q * np.where(robot.prismatic, LENGTH[pr.length_unit], ANGLE[pr.angle_unit])


def _why(robot: ZRPRobot, p: Array, s: Solution, pose: bool) -> str:
    """Why a target was not reached: beyond the arm's reach, a joint held at a limit, or no
    solution found from the start."""
    miss = f"the closest the calibrated arm gets is {s.position_m * 1e3:.4g} mm" + (
        f" and {np.degrees(s.orientation_rad):.4g} deg" if s.orientation_rad > 0 else "") + " away"  # fmt: skip
    far = float(np.linalg.norm(p - robot.b0[0]))
    if far > reach_m(robot):
        return f"out of reach ({far:.4g} m from the base point, {robot.name} reaches {reach_m(robot):.4g} m); {miss}"
    if s.at_limit:
        names = robot.joint_names or tuple(f"joint {i + 1}" for i in range(robot.n))
        held = ", ".join(f"{names[i]} at its limit {_limit_text(robot, i)}" for i in s.at_limit)
        return f"beyond the joint limits ({held}); {miss}"
    J = forward_jacobian(robot, s.q)[2]
    sv = np.linalg.svd(J if pose else J[3:], compute_uv=False)
    if sv[-1] < 1e-6 * sv[0]:
        return f"at a singular configuration (the edge of the calibrated arm's workspace, or a singularity); {miss}"
    return f"no solution found from the nominal solution; {miss}"


def _limit_text(robot: ZRPRobot, i: int) -> str:
    lo, hi = robot.joint_limits[i]
    if robot.prismatic[i]:
        return f"[{lo * 1e3:.6g}, {hi * 1e3:.6g}] mm"
    return f"[{np.degrees(lo):.6g}, {np.degrees(hi):.6g}] deg"


def _result(pr, arms, q_cal, q_nom, p, R, reached, reasons, unreachable, out) -> Compensation:
    cal, nom = arms.calibrated, arms.nominal
    if unreachable == "error" and not reached.all():
        k = int(np.flatnonzero(~reached)[0])
        more = f" ({int((~reached).sum()) - 1} more targets not reached)" if (~reached).sum() > 1 else ""
        raise ValueError(f"{pr.source}, {pr.where[k]}: target not reached: {reasons[k]}{more}; "
                         "keep such rows with unreachable='keep' (--keep-unreachable)")  # fmt: skip
    R_after, p_after = kinematics.forward(cal, q_cal)
    R_before, p_before = kinematics.forward(cal, q_nom)
    R_corr, p_corr = kinematics.forward(nom, q_cal)
    angle = lambda A: np.degrees(np.linalg.norm(so3.log(A @ np.swapaxes(R, 1, 2)), axis=-1)) if R is not None else np.zeros(pr.M)
    q = np.where(reached[:, None], q_cal, np.nan)
    comp = Compensation(
        pr, arms, q, q_nom, p, R, p_corr, R_corr,
        residual_mm=np.linalg.norm(p_after - p, axis=1) * 1e3, residual_deg=angle(R_after),
        uncompensated_mm=np.linalg.norm(p_before - p, axis=1) * 1e3, uncompensated_deg=angle(R_before),
        reached=reached, reasons=reasons,
    )  # fmt: skip
    if out is not None:
        comp.write(out)
    return comp
