"""Frames as robot programmers define them: work objects, the robot's base frame, transforms.

All frames are homogeneous transforms (4, 4), metres: ``T`` maps coordinates in the frame to
coordinates in the frame it is given in (``p_outer = T[:3, :3] p + T[:3, 3]``).

- **Work object** (user frame; a base in KUKA's terms) from three measured points O, X, Y:
  ``x = (X - O) / |X - O|``, ``z = x cross (Y - O)`` normalised, ``y = z cross x``, origin O.
- **The base frame by convention** (what a tracker's base setup measures): ``z`` along axis 1;
  ``x`` along ``u1 cross u2``, axis 2's direction at joint 1's zero made perpendicular to axis
  1 (for parallel axes 1 and 2: towards axis 2); origin at the foot on axis 1 of the common
  normal of axes 1 and 2. That frame ``C(arm)`` is fixed by the arm's own axes. The base frame
  of an arm is ``C(arm) C(nominal)^-1``: the base sits on axes 1 and 2 where the nominal arm's
  base sits on its own, so that the nominal arm's base frame is its own and a calibrated arm's is
  fixed by what the data identify. A tracker cannot tell a joint-1 zero offset from a turn of
  the base about axis 1 (the points are the same); this convention puts the joint's zero on
  the encoder's and the turn in the base, as tracker procedures do (RoboDK's base setup).
- **Axes from circles**: a point on the arm measured while one joint turns lies on a circle
  about that joint's axis; the plane's normal (the smallest principal direction of the points)
  is the axis, its sense the one the joint turns about, and the circle's centre (Kasa's
  algebraic fit in the plane, linear least squares) a point on it.

>>> T = work_object([1.0, 2.0, 0.0], [2.0, 2.0, 0.0], [1.0, 3.0, 0.0])
>>> T[:3, :3].round(12).tolist(), T[:3, 3].tolist()
([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [1.0, 2.0, 0.0])
"""

from __future__ import annotations

import dataclasses
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model import so3
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.model.so3 import ROTATION_TOL, check_rotations  # the one check of rotations, re-exported

Array = NDArray[np.float64]
PARALLEL_RAD = 1e-3  # axes 1 and 2 closer to parallel than this have no common normal's foot


def transform(R: ArrayLike, t: ArrayLike) -> Array:
    """The transform (4, 4) of rotation ``R`` (3, 3) and translation ``t`` (3,) m."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def inverse(T: Array) -> Array:
    """``T^-1`` of a rigid transform: ``(R^T, -R^T t)``."""
    return transform(T[:3, :3].T, -T[:3, :3].T @ T[:3, 3])


@overload
def apply(T: Array, p: Array, R: None = None) -> tuple[Array, None]: ...
@overload
def apply(T: Array, p: Array, R: Array) -> tuple[Array, Array]: ...
@overload
def apply(T: Array, p: Array, R: Array | None) -> tuple[Array, Array | None]: ...
def apply(T: Array, p: Array, R: Array | None = None) -> tuple[Array, Array | None]:
    """Positions (M, 3) and rotations (M, 3, 3) or None given in frame ``T``, in ``T``'s outer frame."""
    return p @ T[:3, :3].T + T[:3, 3], None if R is None else T[:3, :3] @ R


def check_transform(T: ArrayLike, what: str) -> Array:
    """``T`` as a (4, 4) rigid transform; ValueError naming ``what`` for another shape, a
    non-finite number, a rotation part that is no rotation (``R^T R != I`` or ``det R != 1``
    beyond :data:`ROTATION_TOL`: a scaled, sheared or mirrored frame) or a last row other than
    ``0 0 0 1``."""
    try:
        T = np.asarray(T, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a 4x4 transform of numbers, got {T!r}") from None
    if T.shape != (4, 4):
        raise ValueError(f"{what}: expected a 4x4 transform, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{what}: NaN or inf in the transform")
    check_rotations(T[None, :3, :3], what)
    if np.abs(T[3] - [0, 0, 0, 1]).max() > ROTATION_TOL:
        raise ValueError(f"{what}: the last row of a transform is 0 0 0 1, got {T[3].tolist()}")
    return T


def work_object(origin: ArrayLike, on_x: ArrayLike, in_xy: ArrayLike) -> Array:
    """The work object (4, 4) of three points (3,) m: the origin O, a point X on its x axis and
    a point Y in its xy plane on the side of +y (module docstring); ValueError for points that
    do not span a plane."""
    o, x_point, y_point = (np.asarray(v, dtype=float) for v in (origin, on_x, in_xy))
    ox, oy = x_point - o, y_point - o
    if np.linalg.norm(ox) < 1e-6:
        raise ValueError("work object: the points O and X coincide")
    x = ox / np.linalg.norm(ox)
    z = np.cross(x, oy)
    if np.linalg.norm(z) < 1e-6 * max(float(np.linalg.norm(oy)), 1e-6) or np.linalg.norm(oy) < 1e-6:
        raise ValueError("work object: the points O, X and Y lie on one line; Y must be off the x axis")
    z /= np.linalg.norm(z)
    return transform(np.column_stack([x, np.cross(z, x), z]), o)


# --- the base frame by convention --------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Line:
    """A joint axis: a ``point`` (3,) m on it and its unit ``direction`` (3,) (the sense the
    joint turns about, right-handed)."""

    point: Array
    direction: Array


def arm_axes(robot: ZRPRobot) -> tuple[Line, Line]:
    """Axes 1 and 2 of ``robot`` at joint 1's zero, in its frame."""
    points = np.cumsum(robot.b0, axis=0)
    return Line(points[0], robot.u0[0]), Line(points[1], robot.u0[1])


def axes_frame(axis1: Line, axis2: Line) -> Array:
    """``C`` (4, 4): the frame axes 1 and 2 define (module docstring)."""
    z = axis1.direction / np.linalg.norm(axis1.direction)
    c = np.cross(z, axis2.direction)
    if np.linalg.norm(c) > np.sin(PARALLEL_RAD):
        x = c / np.linalg.norm(c)
        d = axis2.point - axis1.point
        # the foot on axis 1 of the common normal: o1 + s z with s = ((o2 - o1) x u2) . c / |c|^2
        s = np.dot(np.cross(d, axis2.direction), c) / np.dot(c, c)
        origin = axis1.point + s * z
    else:  # parallel: x towards axis 2, the origin where axis 1 meets the plane through axis 1's point
        origin = axis1.point
        r = axis2.point - origin
        x = r - np.dot(r, z) * z
        if np.linalg.norm(x) < 1e-9:
            raise ValueError("base frame: axes 1 and 2 coincide; no convention fixes the base's x axis")
        x /= np.linalg.norm(x)
    return transform(np.column_stack([x, np.cross(z, x), z]), origin)


def conventional_base(robot: ZRPRobot, nominal: ZRPRobot) -> Array:
    """The base frame (4, 4) of ``robot`` in ``robot``'s frame: ``C(robot) C(nominal)^-1``
    (module docstring). The nominal arm's is the identity."""
    return axes_frame(*arm_axes(robot)) @ inverse(axes_frame(*arm_axes(nominal)))


def parallel_axes(nominal: ZRPRobot) -> bool:
    """Whether axes 1 and 2 are parallel (then the base's height along axis 1 is not fixed by
    them: :func:`axes_frame` takes it from the arm's point on axis 1)."""
    return bool(np.linalg.norm(np.cross(nominal.u0[0], nominal.u0[1])) <= np.sin(PARALLEL_RAD))


# --- axes from measured circles ------------------------------------------------------------------
def fit_circle(points: ArrayLike, q: ArrayLike) -> tuple[Line, float, float]:
    """The axis a point turned about (:class:`Line`), the circle's radius (m) and the RMS
    distance (m) of the points from the fitted circle; ``points`` (m, 3) measured at the joint
    values ``q`` (m,) rad of the one joint that moved (module docstring)."""
    P, q = np.asarray(points, dtype=float), np.asarray(q, dtype=float)
    centre = P.mean(axis=0)
    _, _, Vt = np.linalg.svd(P - centre)
    e1, e2, normal = Vt
    uv = np.column_stack([(P - centre) @ e1, (P - centre) @ e2])
    A = np.column_stack([2 * uv, np.ones(len(uv))])
    (cu, cv, c), *_ = np.linalg.lstsq(A, (uv**2).sum(axis=1), rcond=None)
    radius = float(np.sqrt(c + cu**2 + cv**2))
    on = centre + cu * e1 + cv * e2
    order = np.argsort(q)
    turns = np.cross(P[order[:-1]] - on, P[order[1:]] - on) @ normal
    direction = normal if np.sum(turns) > 0 else -normal
    off_plane = (P - centre) @ normal
    off_circle = np.linalg.norm(uv - [cu, cv], axis=1) - radius
    return Line(on, direction), radius, float(np.sqrt(np.mean(off_plane**2 + off_circle**2)))


def turned(line: Line, about: Line, angle: float) -> Line:
    """``line`` turned by ``angle`` (rad) about the axis ``about``."""
    R = so3.rodrigues(angle, about.direction)
    return Line(about.point + R @ (line.point - about.point), R @ line.direction)


def pose_difference(A: Array, B: Array, reach: float) -> tuple[float, float]:
    """How far apart two frames (4, 4) are: the largest distance (m) between them over a ball of
    radius ``reach`` about A's origin (the origin's offset plus the angle times the reach) and
    the angle (rad) between them."""
    angle = float(np.linalg.norm(so3.log(A[:3, :3].T @ B[:3, :3])))
    return float(np.linalg.norm(A[:3, 3] - B[:3, 3]) + angle * reach), angle
