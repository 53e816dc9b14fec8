"""Compensation: a calibration turned into corrected joint values and corrected Cartesian targets
for a robot program (Albright and Schroer's practical compensation for off-line programming).

The controller computes joint values from the nominal model; the arm behaves like the
calibrated one. For each target ``T*`` (a pose, or a position) in the robot's base frame:

1. ``q_nom``: the nominal solution. A joint-value program gives it (``T* = FK_nom(q_prog)``,
   the pose the program means); for a Cartesian program it is the nominal inverse kinematics
   ``IK_nom(T*)`` from a seed configuration (see :func:`compensate`).
2. ``q* = IK_cal(T*)``: damped least squares on the calibrated model
   (:mod:`zrp_ga.compensation.ik`), started from ``q_nom``, so that the arm stays on the
   program's branch. The full model: the parametric one (geometry and non-geometric terms) and,
   when the calibration has one, its residual model's correction
   (:meth:`zrp_ga.compensation.arms.Arms.correction`; a fixed-point iteration on the
   parametric solver, :func:`zrp_ga.compensation.ik.solve`).
3. Joint compensation: send ``q*``. Cartesian compensation: send ``T_c = FK_nom(q*)``; a
   controller solving ``IK_nom(T_c)`` on the same branch (the row's ``cf`` and branch signs)
   gets ``q*`` back.

Beside each target: the predicted residual ``FK_cal(q*) - T*`` (mm, deg), the error the
calibrated model predicts for the uncompensated program ``FK_cal(q_nom) - T*`` and the size of
the correction, ``|q* - q_nom|`` (deg for revolute, mm for prismatic joints) and
``|T_c - T*|`` (mm, deg); with a run directory or a calibration, how sure the calibrated model
is there (``sigma_mm``, ``sigma_deg``: its 1-sigma error from the parameter covariance) and
whether ``q*`` lies outside the calibration poses' region (``outside``, ``distance_ratio``,
``beyond_range_deg``: :func:`zrp_ga.compensation.result.predicted`). A target the calibrated arm cannot reach within its joint limits (to
``tolerance_m`` and ``tolerance_rad``) is named with its line and why.

Frames (:mod:`zrp_ga.compensation.setups`). Targets are in the robot's base frame (``frame=
"base"``), in the calibration's instrument frame (``"instrument"``: a tracker's) or in a work
object (``"work object"``: three measured points or a pose, given in the instrument's or the
base frame). For a calibration in an instrument's frame the base frame is, by default, the one
its calibrated axes 1 and 2 fix (``base_setup``), as a tracker's base setup measures it; the
flange is the calibration's split of its measured tool unless the probe's transform in the
flange is given (``probe_in_flange``). Where a requested correction depends on what the data
cannot determine, ``compensation.json`` and the console say so with its size.

Orientation. Arms of six joints or more get full poses (position and orientation) unless
``position_only``; arms with fewer joints cannot reach arbitrary orientations and get
positions only (their hand orientation then follows from the solution).

Input is checked as measurement files are (:mod:`zrp_ga.compensation.program`): regular files
only, units found from the data, no column twice, rotations that are rotations; the output
directory is checked, and the size estimated (:mod:`zrp_ga.compensation.size`), before any work.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.compensation import frames, orientation, setups, size
from zrp_ga.compensation.arms import Arms, _robot, load_arms, tool_transform, with_tool  # noqa: F401 (re-exported)
from zrp_ga.compensation.ik import (  # noqa: F401 (re-exported: the public names of this module before the split)
    TOLERANCE_M,
    TOLERANCE_RAD,
    Solution,
    forward_jacobian,
    nominal_solution,
    solve,
    why,
)
from zrp_ga.compensation.program import Program, read_program, read_work_object, revolute_unit
from zrp_ga.compensation.result import Compensation, evaluated
from zrp_ga.core.files import writable_dir
from zrp_ga.io.measurements import ANGLE, LENGTH
from zrp_ga.model import kinematics
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
FRAMES = ("base", "instrument", "work object")
INSTRUMENT = "instrument"
WORK_OBJECT = "work object"


def compensate(
    calibration: Any,
    program: Any,
    *,
    nominal: ZRPRobot | str | Path | None = None,
    kind: str = "auto",
    q_seed: ArrayLike | None = None,
    tool: Any = None,
    position_only: bool = False,
    frame: str | None = None,
    work_object: Any = None,
    work_object_frame: str | None = None,
    base_setup: Any = "auto",
    probe_in_flange: Any = None,
    length_unit: str = "auto",
    angle_unit: str = "auto",
    orientation_convention: str | None = None,
    sep: str = ",",
    decimal: str = ".",
    unreachable: str = "error",
    tolerance_m: float = TOLERANCE_M,
    tolerance_rad: float = TOLERANCE_RAD,
    out: str | Path | None = None,
    say: Callable[[str], None] | None = None,
) -> Compensation:
    """Corrected joint values and Cartesian targets that bring the calibrated arm to a program's
    targets (module docstring).

    ``calibration``: a ``zrp-ga`` run directory, a calibrated robot file, a :class:`ZRPRobot`
    or what :func:`zrp_ga.calibrate` returns (:func:`~zrp_ga.compensation.arms.load_arms`);
    ``nominal``: the nominal arm when the calibration does not record it (one that is not the
    recorded one is refused). ``program``: a CSV file, a DataFrame, a dict of columns or an
    array (:func:`~zrp_ga.compensation.program.read_program`; ``kind``, the units (``auto``:
    found from the data), the orientation convention, ``sep`` and ``decimal`` say how to read it).

    Frames: ``frame`` ``"base"`` (default), ``"instrument"`` or ``"work object"`` (the default
    when ``work_object`` is given: a transform (4, 4) m, three points O, X, Y (3, 3) m, a file of
    them or of a pose, or a text of nine numbers in the program's length unit), the work object
    given in ``work_object_frame`` (``"instrument"``, the default for a calibration that has
    one, or ``"base"``). ``base_setup``: ``"auto"`` (``"axes"`` for a calibration in an
    instrument's frame, else ``"calibration"``), ``"axes"``, ``"calibration"``, or measured
    circles of joints 1 and 2 (a measurement file or Measurements). ``probe_in_flange``: the
    calibration's measured tool in the flange frame, an offset (3,) m or a transform (4, 4).

    Seeds of a Cartesian program (where the nominal inverse kinematics starts, which decides
    the branch: elbow up or down, wrist flipped): the row's own joint columns if the program has
    them; else the previous row's nominal solution, and for the first row ``q_seed`` (n,) in the
    program's joint units (default: the middle of the joint limits). A target the seed does not
    lead to is tried from ``q_seed``, then from a few random configurations (seeded by the row:
    the same every time); give seeds where the branch matters.

    ``tool``: an offset (3,) m or a transform (4, 4) in the flange frame, a text of numbers in
    the program's units and orientation convention (``"x, y, z"`` or with the orientation's
    three angles, or four for a quaternion), or ``"calibration"``: the point the calibration
    measured (a run's first tool); default: the flange. ``probe_in_flange`` takes the same forms. ``unreachable``: ``"error"`` (a
    ValueError naming the first target not reached, its line and why) or ``"keep"`` (such rows
    are kept, empty and named in ``status``). ``out``: a directory to write ``joints.csv``,
    ``targets.csv`` and ``compensation.json`` into, checked before any work. ``say``: where a
    long compensation's estimate goes (default: the log).

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
    frame = _check_arguments(frame, work_object, unreachable, tolerance_m, tolerance_rad, q_seed, out)
    arms = load_arms(calibration, nominal)
    size.check(size.of_program(program, arms.nominal.n), _name(program), say)
    arms = setups.set_base(arms, base_setup)
    place = _placement(arms, frame, work_object, work_object_frame, (length_unit, angle_unit, orientation_convention, sep, decimal))  # fmt: skip
    locate = lambda p, unit: np.linalg.norm(frames.apply(place.to_base(unit), p)[0] - arms.nominal.b0[0], axis=1)
    pr = read_program(program, arms.nominal, kind, length_unit, angle_unit, orientation_convention, sep, decimal, locate)
    T = place.to_base(pr.length_unit)
    arms = setups.set_flange(arms, _transform_text(probe_in_flange, pr, "probe_in_flange (--probe-in-flange)"))
    arms, tool_T = _with_tool(arms, tool, pr)
    orient = _orient(pr, arms, position_only)
    arms = _notes(arms, tool, tool_T, probe_in_flange, orient, place, pr)
    p, R = _targets(pr, arms, T, orient)
    tol = dict(tolerance_m=tolerance_m, tolerance_rad=tolerance_rad)
    q_nom, q_cal, reached, reasons = _solve_all(pr, arms, p, R, _first_seed(q_seed, arms.nominal, pr), tol)
    comp = evaluated(pr, arms, q_cal, q_nom, p, R, reached, reasons, frame=frame, to_base=T, frame_source=place.source)
    _refuse_unreached(comp, unreachable)
    if out is not None:
        comp.write(out)
    return comp


def _check_arguments(frame, work_object, unreachable, tolerance_m, tolerance_rad, q_seed, out) -> str:
    """The settings that need nothing read: their values, and the output directory writable."""
    if unreachable not in ("error", "keep"):
        raise ValueError(f"unreachable: {unreachable!r}, expected 'error' or 'keep'")
    if frame is None:
        frame = WORK_OBJECT if work_object is not None else "base"
    frame = frame.replace("_", " ").replace("-", " ") if isinstance(frame, str) else frame
    if frame not in FRAMES:
        raise ValueError(f"frame: {frame!r}, expected one of {', '.join(map(repr, FRAMES))}")
    if (frame == WORK_OBJECT) != (work_object is not None):
        raise ValueError("frame: 'work object' goes with a work_object (--work-object), and a work_object with frame 'work object'")
    for name, v in (("tolerance_m", tolerance_m), ("tolerance_rad", tolerance_rad)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
            raise ValueError(f"{name}: must be a number > 0, got {v!r}")
    if isinstance(q_seed, (dict, str, set)):
        raise TypeError(f"q_seed: expected n joint values (a list or array), got a {type(q_seed).__name__}")
    if out is not None:
        writable_dir(out, "out (-o)")
    return frame


def _name(program: Any) -> str:
    return str(program) if isinstance(program, (str, os.PathLike)) else "the program"


# --- frames and tools -----------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Placement:
    """Where the program's targets are: ``to_base`` the program's frame in the base frame (4, 4)
    as a function of the program's length unit (a work object given as numbers is in it), what
    the frame is, and a work object's three points (3, 3) m in its outer frame (None: none)."""

    frame: str
    to_base: Callable[[str], Array]
    source: str
    points: Callable[[str], Array] | None = None


def _placement(arms: Arms, frame: str, work_object: Any, wo_frame: str | None, reading: tuple) -> Placement:
    """The :class:`Placement` of ``frame`` (and ``work_object``, given in ``wo_frame``)."""
    if frame == "base":
        return Placement(frame, lambda unit: np.eye(4), "the robot's base frame")
    wo_frame = wo_frame or (INSTRUMENT if arms.base is not None else "base")
    if wo_frame not in ("base", INSTRUMENT):
        raise ValueError(f"work_object_frame: {wo_frame!r}, expected 'instrument' or 'base'")
    if arms.base is None and INSTRUMENT in (frame, wo_frame):
        where = "frame" if frame == INSTRUMENT else "work_object_frame"
        raise ValueError(f"{where}: {arms.source} has no base transform (no instrument frame); give targets "
                         + ("and work objects " if frame == WORK_OBJECT else "") + "in the base frame")  # fmt: skip
    to_instrument = np.eye(4) if arms.base is None else frames.inverse(arms.base)
    if frame == INSTRUMENT:
        return Placement(frame, lambda unit: to_instrument, "the instrument's frame (the calibration's)")
    outer = to_instrument if wo_frame == INSTRUMENT else np.eye(4)
    W, said, points = _work_object(work_object, arms, outer, reading)
    return Placement(frame, lambda unit: outer @ W(unit), f"the work object ({said}, in the {wo_frame} frame)", points)


def _work_object(
    value: Any, arms: Arms, outer: Array, reading: tuple
) -> tuple[Callable[[str], Array], str, Callable[[str], Array] | None]:
    """The work object (4, 4) in its outer frame and its three points (3, 3) m (or None), as
    functions of the program's length unit, and what it was."""
    length_unit, angle_unit, convention, sep, decimal = reading
    if isinstance(value, str) and (v := _numbers(value)) is not None:
        if len(v) != 9:
            raise ValueError(f"work_object (--work-object): {value!r}: expected nine numbers (points O, X, Y) or a file")
        points = lambda unit: np.reshape(v, (3, 3)) * LENGTH[unit]
        return (lambda unit: setups.work_object_transform(points(unit))), "three points O, X, Y", points
    if isinstance(value, np.ndarray | list | tuple):
        W = setups.work_object_transform(value)
        given = np.asarray(value, dtype=float)
        return (lambda unit: W), "given in memory", ((lambda unit: given) if given.shape == (3, 3) else None)
    locate = lambda p, unit: np.linalg.norm(frames.apply(outer, p)[0] - arms.nominal.b0[0], axis=1)
    W, said, found = read_work_object(value, arms.nominal, length_unit, angle_unit, convention, sep, decimal, locate)
    return (lambda unit: W), said, (None if found is None else lambda unit: found)


def _numbers(text: str) -> list[float] | None:
    """The numbers of a text (separated by spaces, commas or semicolons), or None if it is not one."""
    try:
        return [float(v) for v in text.replace(";", " ").replace(",", " ").split()]
    except ValueError:
        return None


def _transform_text(value: Any, pr: Program, what: str) -> Any:
    """A text of numbers in the program's units as an offset (3,) m, or with three angles (or a
    quaternion) in the program's orientation convention as a transform (4, 4); anything else as
    it is."""
    if not isinstance(value, str) or value == "calibration":
        return value
    v = _numbers(value)
    convention = pr.convention or "rotvec"
    k = len(orientation.columns(convention))
    if v is None or len(v) not in (3, 3 + k):
        raise ValueError(f"{what}: {value!r}: expected x, y, z (the program's length unit, {pr.length_unit}) and optionally "
                         f"the orientation's {', '.join(orientation.columns(convention))} ({convention})")  # fmt: skip
    t = np.array(v[:3]) * LENGTH[pr.length_unit]
    if len(v) == 3:
        return t
    angles = np.array([v[3:]]) * (ANGLE[pr.orientation_unit] if orientation.is_angle(convention) else 1.0)
    return frames.transform(orientation.to_matrices(angles, convention)[0], t)


def _with_tool(arms: Arms, tool: Any, pr: Program) -> tuple[Arms, Array | None]:
    """Both arms ending at ``tool`` (module docstring of :func:`compensate`), and the tool (4, 4)
    in the flange frame (None: the flange)."""
    if isinstance(tool, str) and tool == "calibration":
        if arms.tool is None:
            raise ValueError(f"tool: {arms.source} carries no tool (it measured the end point itself)")
        tool = arms.tool
    T = tool_transform(_transform_text(tool, pr, "tool (--tool)"))
    return dataclasses.replace(arms, calibrated=with_tool(arms.calibrated, T), nominal=with_tool(arms.nominal, T)), T


def _orient(pr: Program, arms: Arms, position_only: bool) -> bool:
    """Whether orientations are matched: poses for arms of six joints or more (a Cartesian
    program's when it gives them), unless ``position_only``."""
    nom = arms.nominal
    if pr.kind == "cartesian" and pr.R is not None and nom.n < 6 and not position_only:
        raise ValueError(f"{pr.source}: {nom.name} has {nom.n} joints and cannot reach arbitrary orientations; "
                         "give positions only (x, y, z) or set position_only (--position-only)")  # fmt: skip
    return not position_only and (pr.R is not None if pr.kind == "cartesian" else nom.n >= 6)


def _notes(arms: Arms, tool: Any, tool_T: Array | None, probe_in_flange: Any, orient: bool, place: Placement, pr: Program) -> Arms:
    """What the targets depend on that the data cannot determine, with its size."""
    notes = []
    measured_point = isinstance(tool, str) and tool == "calibration"
    if arms.tool is not None and probe_in_flange is None and not measured_point:
        notes.append(setups.split_note(arms, orient and arms.orientations))
    if measured_point and orient and not arms.orientations and probe_in_flange is None:
        notes.append(setups.point_tool_note())
    if not arms.orientations and (orient or not measured_point):
        at = np.zeros(3) if tool_T is None else tool_T[:3, 3]
        off = 0.0 if measured_point or arms.tool is None else float(np.linalg.norm(at - arms.tool[:3, 3]))
        if orient or off > 0:
            notes.append(setups.orientation_note(arms, off))
    if place.points is not None and pr.p is not None:
        o, x, y = place.points(pr.length_unit)
        axis = (x - o) / np.linalg.norm(x - o)
        apart = float(min(np.linalg.norm(x - o), np.linalg.norm((y - o) - np.dot(y - o, axis) * axis)))
        notes.append(setups.work_object_note(apart, float(np.linalg.norm(pr.p, axis=1).max()), arms.noise_mm))
    if place.frame != "base":
        notes.append(f"the targets were given in {place.source} and mapped to the base frame; the corrected Cartesian "
                     "targets are in " + ("the work object" if place.frame == WORK_OBJECT else "the base frame"))  # fmt: skip
    return arms.noted(*notes)


def _targets(pr: Program, arms: Arms, T: Array, orient: bool) -> tuple[Array, Array | None]:
    """The targets (M, 3) m and (M, 3, 3) or None, in the robot's base frame."""
    if pr.kind == "joints":
        assert pr.q is not None  # a joint program is its joint values
        R, p = kinematics.forward(arms.nominal, pr.q)
        return p, R if orient else None
    assert pr.p is not None  # a Cartesian program has its positions
    return frames.apply(T, pr.p, pr.R if orient else None)


# --- solving ----------------------------------------------------------------------------------------
def _first_seed(q_seed: ArrayLike | None, robot: ZRPRobot, pr: Program) -> Array:
    """The first seed (n,) in SI units, from the program's joint units, or from its own values
    when nothing said them (:func:`zrp_ga.compensation.program.revolute_unit`); default: the
    middle of the joint limits."""
    if q_seed is None:
        return robot.joint_limits.mean(axis=1)
    try:
        q = np.asarray(q_seed, dtype=float)
    except (TypeError, ValueError):
        q = np.array([np.nan])
    if q.shape != (robot.n,) or not np.all(np.isfinite(q)):
        raise ValueError(f"q_seed (--seed-q): expected {robot.n} finite joint values ({pr.angle_unit}, {pr.length_unit}), got {q_seed!r}")
    unit = pr.angle_unit if pr.angle_unit_found else revolute_unit(q, robot)
    return q * np.where(robot.prismatic, LENGTH[pr.length_unit], ANGLE[unit])


def _solve_all(pr: Program, arms: Arms, p: Array, R: Array | None, first: Array, tol: dict):
    """Nominal and calibrated solutions (M, n) of every target, whether each was reached and why not."""
    cal, nom = arms.calibrated, arms.nominal
    M, n = pr.M, nom.n
    q_nom, q_cal = np.full((M, n), np.nan), np.full((M, n), np.nan)
    reached, reasons = np.zeros(M, dtype=bool), [""] * M
    seed = first
    for k in range(M):
        R_k = None if R is None else R[k]
        if pr.kind == "joints":
            assert pr.q is not None  # a joint program is its joint values
            q_nom[k] = pr.q[k]
        else:
            s = nominal_solution(nom, p[k], R_k, pr.q[k] if pr.q is not None else seed, first, k, tol)
            q_nom[k] = s.q
            if s.reached:
                seed = s.q
        s = solve(cal, p[k], R_k, q_nom[k], **tol, correction=None if arms.residual is None else arms.correction)
        q_cal[k], reached[k] = s.q, s.reached
        if not s.reached:
            reasons[k] = why(cal, p[k], s, R is not None)
    return q_nom, q_cal, reached, reasons


def _refuse_unreached(comp: Compensation, unreachable: str) -> None:
    reached, pr = comp.reached, comp.program
    if unreachable == "error" and not reached.all():
        k = int(np.flatnonzero(~reached)[0])
        more = f" ({int((~reached).sum()) - 1} more targets not reached)" if (~reached).sum() > 1 else ""
        raise ValueError(f"{pr.source}, {pr.where[k]}: target not reached: {comp.reasons[k]}{more}; "
                         "keep such rows with unreachable='keep' (--keep-unreachable)")  # fmt: skip
