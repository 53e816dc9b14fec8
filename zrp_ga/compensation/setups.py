"""Setups as on the shop floor: the robot's base frame, the flange and the measured tool, and
work objects, applied to the arms of a calibration (:class:`zrp_ga.compensation.arms.Arms`).

**Base setup** (``base_setup``). A calibration on a tracker's points identifies the arm in the
tracker's frame; which frame is "the robot's base" is a choice the points cannot make (a
joint-1 zero offset and a turn of the base about axis 1 give the same points; so do a base
height and the first link's length). The choices:

- ``"axes"`` (the default for a calibration with an instrument frame): the base frame that axes
  1 and 2 of the calibrated arm fix by convention (:func:`zrp_ga.compensation.frames.conventional_base`);
- measured circles (a measurement file, or :class:`~zrp_ga.model.poses.Measurements`, of a
  point on the arm while joint 1 turns with the others held, and while joint 2 turns): the
  same convention on the axes the circles show, as a tracker's base setup measures them;
- ``"calibration"``: the frame the calibration exported (for a measured run, the nominal
  arm's best fit to the points: it moves with the errors of the nominal arm, by the size said
  in ``compensation.json``).

**Tool setup** (``probe_in_flange``). The calibration measured a tool point (a reflector, a 6D
probe) on the flange; how the calibrated end splits into the last link and the probe is not
determined by its data (the two trade off exactly). Targets of the measured point
(``tool="calibration"``) do not depend on the split; flange targets and tools given in the
flange frame do. Given the probe's transform in the flange (from its mount), the flange is
``probe probe_in_flange^-1``; without it, the calibration's split, whose size is said.

**Work objects** (``work_object``): a transform (4, 4), three points O, X, Y (3, 3), or a file
of them (:func:`read_work_object`), in the instrument's or the base frame.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.compensation import frames
from zrp_ga.compensation.arms import Arms, tool_transform, with_tool
from zrp_ga.io import measurements
from zrp_ga.io.measurements import reach_m
from zrp_ga.model import so3
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
BASE_SETUPS = ("auto", "axes", "calibration")
MIN_CIRCLE_POINTS = 3
MIN_CIRCLE_RAD = np.radians(10.0)  # a circle's joint must turn at least this much


# --- the base --------------------------------------------------------------------------------------
def set_base(arms: Arms, setup: Any) -> Arms:
    """``arms`` in the base frame ``setup`` gives (module docstring): ``"auto"``, ``"axes"``,
    ``"calibration"``, or measured circles (a file path or Measurements)."""
    if isinstance(setup, str) and setup in BASE_SETUPS:
        if setup == "calibration" or (setup == "auto" and arms.base is None):
            return _as_calibrated(arms)
        return _moved(arms, frames.conventional_base(_in_outer(arms), arms.nominal), "axes",
                      "the base frame axes 1 and 2 of the calibrated arm fix (frames.conventional_base)")  # fmt: skip
    if not isinstance(setup, (str, os.PathLike, Measurements)):
        raise TypeError(f"base_setup: expected 'auto', 'axes', 'calibration', a file of measured circles or Measurements; "
                        f"got a {type(setup).__name__}")  # fmt: skip
    if arms.base is None:
        raise ValueError("base_setup: circles measured in an instrument's frame need a calibration in that frame (a measured run)")
    B, said = circles_base(setup, arms.nominal)
    axes = frames.conventional_base(_in_outer(arms), arms.nominal)
    apart_m, apart_rad = frames.pose_difference(axes, B, reach_m(arms.nominal))
    moved = _moved(arms, B, "circles", said)
    moved.frames["base"].update(circles_vs_calibrated_axes_mm=apart_m * 1e3, circles_vs_calibrated_axes_deg=np.degrees(apart_rad))
    return moved


def _in_outer(arms: Arms) -> ZRPRobot:
    """The calibrated arm in the instrument's frame (in its own when it has none)."""
    B = np.eye(4) if arms.base is None else arms.base
    return arms.calibrated.transformed(B[:3, :3], B[:3, 3])


def _moved(arms: Arms, B: Array, name: str, how: str) -> Arms:
    """``arms`` with the calibrated arm re-expressed in the base frame ``B`` (4, 4), given in the
    instrument's frame, and how far that frame is from the calibration's."""
    old = np.eye(4) if arms.base is None else arms.base
    inv = frames.inverse(B)
    cal = _in_outer(arms).transformed(inv[:3, :3], inv[:3, 3])
    apart_m, apart_rad = frames.pose_difference(old, B, reach_m(arms.nominal))
    info = {"setup": name, "how": how, "moved_from_calibration_mm": apart_m * 1e3, "moved_from_calibration_deg": np.degrees(apart_rad)}
    notes = []
    if frames.parallel_axes(arms.nominal):
        notes.append("base frame: axes 1 and 2 are parallel; the base's height along axis 1 is the calibration's point on "
                     "axis 1 (no axis fixes it)")  # fmt: skip
    out = dataclasses.replace(arms, calibrated=cal, base=None if arms.base is None else B, frames={**arms.frames, "base": info})
    return out.noted(*notes)


def _as_calibrated(arms: Arms) -> Arms:
    """The calibration's own base frame; for a measured run, how far the conventional one lies
    from it (what base-frame targets are off by if the controller's base is the conventional one)."""
    info: dict[str, Any] = {"setup": "calibration", "how": "the base frame the calibration exported"}
    if arms.base is None:
        return dataclasses.replace(arms, frames={**arms.frames, "base": info})
    axes = frames.conventional_base(_in_outer(arms), arms.nominal)
    apart_m, apart_rad = frames.pose_difference(arms.base, axes, reach_m(arms.nominal))
    info.update(conventional_base_apart_mm=apart_m * 1e3, conventional_base_apart_deg=np.degrees(apart_rad))
    note = (f"base frame: the calibration's (the nominal arm's best fit to the measured points), {apart_m * 1e3:.3g} mm (at "
            f"{reach_m(arms.nominal):.3g} m) and {np.degrees(apart_rad):.3g} deg from the base frame that the calibrated axes 1 and "
            "2 fix; base-frame targets are off by up to that much if the controller's base is set up from the axes; "
            "base_setup='axes' (--base-setup axes) or measured circles remove it")  # fmt: skip
    return dataclasses.replace(arms, frames={**arms.frames, "base": info}).noted(note)


def circles_base(circles: Any, nominal: ZRPRobot) -> tuple[Array, str]:
    """The base frame (4, 4) in the instrument's frame from measured circles of joints 1 and 2
    (module docstring), and a sentence on the fit."""
    data = _circle_data(circles, nominal)
    axis1, r1, rms1 = _circle(data, nominal, 0)
    axis2, r2, rms2 = _circle(data, nominal, 1)
    q1 = float(data.q[_rows_of(data, 1)[0], 0])
    axis2 = frames.turned(axis2, axis1, -q1)  # axis 2 at joint 1's zero
    C = frames.axes_frame(axis1, axis2) @ frames.inverse(frames.axes_frame(*frames.arm_axes(nominal)))
    said = (f"circles of joints 1 and 2 in {data.source} (radii {r1 * 1e3:.4g} and {r2 * 1e3:.4g} mm, points off the "
            f"circles by {rms1 * 1e3:.3g} and {rms2 * 1e3:.3g} mm RMS)")  # fmt: skip
    return C, said


def _circle_data(circles: Any, nominal: ZRPRobot) -> Measurements:
    if isinstance(circles, Measurements):
        return circles
    fmt = measurements.zrp_format(nominal.n, "auto", "auto")
    return measurements.read(circles, fmt, nominal)


def _rows_of(data: Measurements, j: int) -> Array:
    """The rows of the largest group in which joint ``j`` alone moves (the other joints and the
    tool the same)."""
    others = np.delete(data.q, j, axis=1)
    key = np.column_stack([others, data.tools])
    _, group = np.unique(key, axis=0, return_inverse=True)
    best = np.array([], dtype=int)
    for g in np.unique(group):
        rows = np.flatnonzero(group == g)
        if len(np.unique(data.q[rows, j])) > len(np.unique(data.q[best, j])):
            best = rows
    return best


def _circle(data: Measurements, nominal: ZRPRobot, j: int) -> tuple[frames.Line, float, float]:
    rows = _rows_of(data, j)
    q = data.q[rows, j]
    if len(np.unique(q)) < MIN_CIRCLE_POINTS or np.ptp(q) < MIN_CIRCLE_RAD:
        raise ValueError(f"base_setup: {data.source}: no circle of joint {j + 1}: at least {MIN_CIRCLE_POINTS} rows in which "
                         f"joint {j + 1} alone turns, over {np.degrees(MIN_CIRCLE_RAD):.0f} deg or more, with the other joints "
                         f"held (found {len(np.unique(q))} rows over {np.degrees(np.ptp(q)) if len(q) else 0:.3g} deg)")  # fmt: skip
    line, radius, rms = frames.fit_circle(data.p[rows], q)
    if radius < 1e-3:
        raise ValueError(f"base_setup: {data.source}: the point measured while joint {j + 1} turns lies on its axis "
                         f"(a circle of radius {radius * 1e3:.3g} mm); measure a point off the axis")  # fmt: skip
    return line, radius, rms


# --- the flange ----------------------------------------------------------------------------------------
def set_flange(arms: Arms, probe_in_flange: Any) -> Arms:
    """``arms`` whose calibrated arm ends at the flange that ``probe_in_flange`` (the measured
    tool's offset (3,) m or transform (4, 4) in the flange frame) implies: ``probe
    probe_in_flange^-1``. With positions only, the probe's orientation was not measured and the
    calibrated hand's orientation is the flange's: the flange is the probe's point moved back by
    the offset, and the given rotation is the probe's orientation in it (taken as given)."""
    T = tool_transform(probe_in_flange, "probe_in_flange")
    if T is None:
        return arms
    if arms.tool is None:
        raise ValueError(f"probe_in_flange: {arms.source} measured no tool point on the flange (it has no tool to split)")
    back = T if arms.orientations else frames.transform(np.eye(3), T[:3, 3])
    flange = arms.tool @ frames.inverse(back)  # the new flange in the old hand frame
    info = {"setup": "probe_in_flange", "moved_from_calibration_mm": float(np.linalg.norm(flange[:3, 3]) * 1e3),
            "moved_from_calibration_deg": float(np.degrees(np.linalg.norm(so3.log(flange[:3, :3]))))}  # fmt: skip
    cal = with_tool(arms.calibrated, flange)
    return dataclasses.replace(arms, calibrated=cal, tool=T, frames={**arms.frames, "flange": info})


def link_scale(arms: Arms) -> tuple[float, float]:
    """How wrong a link of this arm may be, as the calibration found the others: the RMS change
    (mm) of the body vectors between the first and the last joint, and the largest turn (deg) it
    gave an axis, calibrated against nominal in the base frame."""
    cal, nom = arms.calibrated, arms.nominal
    mm = float(np.sqrt(np.mean(np.sum((cal.b0[1:-1] - nom.b0[1:-1]) ** 2, axis=1))) * 1e3) if cal.n > 1 else 0.0
    cos = np.clip(np.sum(cal.u0 * nom.u0, axis=1), -1.0, 1.0)
    return mm, float(np.degrees(np.arccos(cos).max()))


def flange_split(arms: Arms) -> tuple[float, float]:
    """What flange targets may be off by (mm, deg) when the split between the last link and the
    measured tool is not known: the larger of how far the calibrated flange lies from the nominal
    one at the end of the last link (the last body vectors and hand orientations in the base
    frame) and how wrong a link typically is (:func:`link_scale`): the data cannot tell the last
    link's error from the tool's."""
    cal, nom = arms.calibrated, arms.nominal
    mm = float(np.linalg.norm(cal.b0[-1] - nom.b0[-1]) * 1e3)
    deg = float(np.degrees(np.linalg.norm(so3.log(cal.R_h0 @ nom.R_h0.T))))
    link_mm, link_deg = link_scale(arms)
    return max(mm, link_mm), max(deg, link_deg)


def split_note(arms: Arms, orient: bool) -> str:
    """What flange targets of a calibration on a measured tool point leave open, with its size."""
    mm, deg = flange_split(arms)
    angle = f" and {deg:.3g} deg" if orient else ""
    return (f"flange targets: the data do not determine how the calibrated end splits into the last link and the measured "
            f"tool (they trade off exactly); flange targets may be off by about {mm:.3g} mm{angle} (the calibrated flange's "
            "distance from the nominal one, or a link's typical correction, whichever is larger); give the probe's "
            "transform in the flange (probe_in_flange, --probe-in-flange) to remove it, or give targets of the measured "
            "point (tool='calibration', --tool calibration)")  # fmt: skip


def orientation_note(arms: Arms, tool_offset_m: float) -> str:
    """What orientation targets of a positions-only calibration leave open, and what positions
    of a point ``tool_offset_m`` from the measured one carry of it."""
    _, deg = link_scale(arms)
    far = (f"; positions of a point {tool_offset_m * 1e3:.3g} mm from the measured one carry about {np.radians(deg) * tool_offset_m * 1e3:.3g} mm "
           "of it" if tool_offset_m > 1e-6 else "")  # fmt: skip
    return ("orientations: the calibration measured positions only, so the hand's orientation is not identified (the "
            "calibrated model keeps the nominal hand on the calibrated axes); orientation targets keep the nominal hand's "
            f"error, about {deg:.3g} deg if it is as wrong as an axis was (the largest turn the calibration gave one){far}; measure orientations (a "
            "6D probe) or compensate positions only (position_only, --position-only)")  # fmt: skip


def point_tool_note() -> str:
    """What orientation targets of the measured point leave open when the calibration measured
    positions only: the point has no orientation of its own, so it takes the flange's."""
    return ("tool orientation: the calibration measured positions only, so its measured point has no orientation of its "
            "own and tool='calibration' (--tool calibration) takes the flange's; orientation targets of a probe turned in "
            "its mount miss by that turn in full (the data do not hold it); give the probe's transform in the flange "
            "(probe_in_flange, --probe-in-flange) or compensate positions only (position_only, --position-only)")  # fmt: skip


def work_object_note(points_apart_m: float, reach_from_origin_m: float, noise_mm: float | None) -> str:
    """How much the errors of three measured points move targets in the work object: an error
    ``e`` (per coordinate) in O moves them by ``e``, in X and Y turns them by about ``sqrt 2 e /
    d`` (``d`` how far apart the points are), so a target ``r`` from O moves by about ``e sqrt(1
    + 2 (r / d)^2)``."""
    k = float(np.sqrt(1.0 + 2.0 * (reach_from_origin_m / points_apart_m) ** 2))
    size = f" (about {k * noise_mm:.3g} mm for points measured as the calibration's, e = {noise_mm:.3g} mm)" if noise_mm else ""
    return (f"work object: three points {points_apart_m * 1e3:.4g} mm apart (the least of |X - O| and Y's distance from the x "
            f"axis) place targets up to {reach_from_origin_m * 1e3:.4g} mm from O; an error e in the points moves them by "
            f"about {k:.3g} e{size}; points farther apart, or measured several times, lower it")  # fmt: skip


# --- work objects ---------------------------------------------------------------------------------------
def work_object_transform(value: Any, what: str = "work_object") -> Array:
    """A work object given in memory: a transform (4, 4) or three points O, X, Y (3, 3) m, one a
    row (:func:`zrp_ga.compensation.frames.work_object`)."""
    if isinstance(value, (dict, set)) or value is None:
        raise TypeError(f"{what}: expected a 4x4 transform, three points O, X, Y (3, 3) or a file; got {type(value).__name__}")
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a 4x4 transform or three points O, X, Y (3, 3) of numbers, got {value!r}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: NaN or inf")
    if a.shape == (3, 3):
        try:
            return frames.work_object(*a)
        except ValueError as exc:
            raise ValueError(f"{what}: {exc}".replace("work object: ", "")) from None
    if a.shape == (4, 4):
        return frames.check_transform(a, what)
    raise ValueError(f"{what}: expected a 4x4 transform or three points O, X, Y (3, 3), got shape {a.shape}")
