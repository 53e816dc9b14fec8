"""DH and modified-DH tables: the table, its forward kinematics, and the table of a ZRP arm.

Conventions (lengths m, angles rad); a revolute joint adds q_i to theta_i, a prismatic one to d_i:

- ``"dh"`` (standard, distal): ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; joint i turns
  about the z axis of frame i-1.
- ``"mdh"`` (modified, proximal, Craig): ``A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``;
  row i holds ``a_{i-1}, alpha_{i-1}, d_i, theta_i`` and joint i turns about the z axis of frame i.

The hand pose is ``base A_1(q_1) ... A_n(q_n) tool`` (``base``, ``tool``: 4x4 transforms).

:func:`to_dh` finds the table of a ZRP arm by walking its axes at q = 0 (docs/model.md, section 5):
frame x axes lie along the common normals of consecutive axes, z axes along the joint axes (the
ZRP direction, so that q turns the same way). Choices where the geometry leaves freedom:

- base frame: z along axis 1, origin at the foot of the perpendicular from the world origin to
  axis 1, x along the world axis most perpendicular to axis 1 (projected);
- sign of each common normal: the one that makes ``theta_i`` (the joint value at q = 0) lie in
  (-90, 90] degrees (so ``a`` may be negative, as in Universal Robots' tables); at exactly 90
  degrees, the one with ``a >= 0``;
- consecutive axes within ``parallel_tol`` rad of parallel: the common normal is not unique (or,
  when the axes are only nearly parallel, lies far away), so it is taken through the previous
  frame's origin (``d = 0`` for that row, Craig's and Corke's convention). When such axes are
  not exactly parallel (a calibrated arm), the part of the tilt that DH cannot express is lost:
  the table then turns that joint about a slightly different axis, and :func:`to_dh` reports it;
- last frame: standard DH puts frame n's origin at the end point and its z axis along the hand's
  z axis where DH allows; modified DH puts frame n on axis n at the foot of the perpendicular
  from the end point. ``tool`` holds the rest of the hand pose.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga import kinematics
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]
CONVENTIONS = ("dh", "mdh")
_EPS_M = 1e-12  # lengths below this are zero (m)


@dataclasses.dataclass(frozen=True, eq=False)
class DHTable:
    """A DH (``convention="dh"``) or modified-DH (``"mdh"``) table, SI units.

    ``a``, ``alpha``, ``d``, ``theta``: (n,) m, rad, m, rad (row i as in the module docstring;
    ``theta`` is the joint angle at q = 0 of a revolute joint and the fixed angle of a
    prismatic one); ``base``, ``tool``: (4, 4); ``limits``: (n, 2) or None (defaults).

    >>> t = DHTable("dh", a=[1.0], alpha=[0.0], d=[0.0], theta=[0.0], joint_types="R")
    >>> np.round(t.forward([np.pi / 2])[:3, 3], 12)
    array([0., 1., 0.])
    """

    convention: str
    a: Array
    alpha: Array
    d: Array
    theta: Array
    joint_types: str
    base: Array = dataclasses.field(default_factory=lambda: np.eye(4))
    tool: Array = dataclasses.field(default_factory=lambda: np.eye(4))
    name: str = "robot"
    joint_names: tuple[str, ...] | None = None
    limits: Array | None = None

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise ValueError(f"convention: {self.convention!r}, expected one of {', '.join(CONVENTIONS)}")
        n = len(self.joint_types)
        for field in ("a", "alpha", "d", "theta"):
            value = np.array(getattr(self, field), dtype=float)
            if value.shape != (n,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{field}: expected {n} finite numbers, got {getattr(self, field)!r}")
            object.__setattr__(self, field, value)
        robot = self.to_robot()  # validates types, names, limits, base and tool the ZRP way
        object.__setattr__(self, "joint_names", robot.joint_names)
        for field in ("a", "alpha", "d", "theta", "base", "tool", "limits"):
            value = getattr(robot, field) if field == "limits" else np.array(getattr(self, field), dtype=float)
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, field, value)

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_types)

    def to_robot(self) -> ZRPRobot:
        """The ZRP description (exact: docs/model.md, section 1)."""
        make = ZRPRobot.from_dh if self.convention == "dh" else ZRPRobot.from_mdh
        return make(
            d=self.d, a=self.a, alpha=self.alpha, offset=self.theta, joint_types=self.joint_types,
            tool=self.tool, base=self.base, name=self.name, joint_names=self.joint_names, limits=self.limits,
        )

    def forward(self, q: ArrayLike) -> Array:
        """Hand pose ``base A_1 ... A_n tool`` at joint values q (n,) or (M, n): (4, 4) or (M, 4, 4)."""
        q = kinematics.check_q(q, self.n)
        Q = np.atleast_2d(q)
        revolute = np.array([t == "R" for t in self.joint_types])
        T = np.broadcast_to(self.base, (len(Q), 4, 4))
        for i in range(self.n):
            theta = self.theta[i] + np.where(revolute[i], Q[:, i], 0.0)
            d = self.d[i] + np.where(revolute[i], 0.0, Q[:, i])
            T = T @ _link(self.convention, theta, d, self.a[i], self.alpha[i])
        T = T @ self.tool
        return T[0] if q.ndim == 1 else T


@dataclasses.dataclass(frozen=True)
class DHMismatch:
    """How far a table found by :func:`to_dh` is from the ZRP arm.

    ``position_m`` and ``orientation_rad``: largest hand position and orientation difference
    between the table's and the arm's forward kinematics over ``samples`` joint values (q = 0
    and uniform within the joint limits); ``notes``: one line per joint whose axis the table
    cannot place exactly.
    """

    position_m: float
    orientation_rad: float
    samples: int
    notes: tuple[str, ...] = ()

    def __str__(self) -> str:
        return (
            f"largest difference to the ZRP model over {self.samples} joint samples: "
            f"position {self.position_m:.3g} m, orientation {self.orientation_rad:.3g} rad"
        )


def to_dh(
    robot: ZRPRobot, convention: str = "dh", parallel_tol: float = 1e-3, samples: int = 200, seed: int = 0
) -> tuple[DHTable, DHMismatch]:
    """The DH (``"dh"``) or modified-DH (``"mdh"``) table of a ZRP arm and what it misses.

    Choices are those of the module docstring; ``parallel_tol`` (rad) decides which consecutive
    axes count as parallel. The mismatch is measured at q = 0 and ``samples - 1`` joint values
    drawn uniformly within ``robot.joint_limits`` (``numpy.random.default_rng(seed)``).

    >>> from zrp_ga import robots
    >>> table, mismatch = to_dh(robots.get("puma560"))
    >>> np.round(np.degrees(table.alpha)).tolist(), mismatch.position_m < 1e-15
    ([90.0, 0.0, -90.0, 90.0, -90.0, 0.0], True)
    """
    if convention not in CONVENTIONS:
        raise ValueError(f"convention: {convention!r}, expected one of {', '.join(CONVENTIONS)}")
    points = np.cumsum(robot.b0, axis=0)  # points[i]: on axis i+1; points[n]: the end point
    hand = np.eye(4)
    hand[:3, :3], hand[:3, 3] = robot.R_h0, points[-1]
    walk = _walk_dh if convention == "dh" else _walk_mdh
    base, rows, axis_frames = walk(points, robot.u0, hand, parallel_tol)
    a, alpha, d, theta = _tidy(np.array(rows).T)
    table = DHTable(
        convention, a, alpha, d, theta, robot.joint_types, base=_tidy(base), name=robot.name,
        joint_names=robot.joint_names, limits=robot.limits,
    )
    last = table.forward(np.zeros(robot.n))  # frame n of the tidied table
    table = dataclasses.replace(table, tool=_tidy(np.linalg.inv(last) @ hand))
    notes = _axis_notes(robot, axis_frames[:-1], parallel_tol)
    return table, _mismatch(robot, table, samples, seed, notes)


def _tidy(x: Array) -> Array:
    """Round-off below 1e-14 set to zero (and -0.0 to 0.0), so that files read 0.0 rather than
    -1.2e-17. The mismatch is measured after this."""
    return np.where(np.abs(x) < 1e-14, 0.0, x) + 0.0


# --- the walk along the axes at q = 0 ------------------------------------------------------------
def _walk_dh(points: Array, u0: Array, hand: Array, tol: float) -> tuple[Array, list, list[Array]]:
    """Standard DH: frame i-1 has z along axis i; frame i sits on axis i+1 where the common
    normal from axis i meets it. Each row is read off against the table's own previous frame,
    so that a row that is not exact does not shift the later ones. Returns the base frame, the
    rows (a, alpha, d, theta) and the table's frames 0..n (world, q = 0)."""
    n = len(u0)
    T = _base_frame(points[0], u0[0])
    frames, rows = [T], []
    for i in range(n):
        if i < n - 1:
            o, z, x = T[:3, 3], T[:3, 2], T[:3, 0]
            _, foot, normal = _common_normal(o, z, points[i + 1], u0[i + 1], o, x, tol)
            target = _frame(foot, normal, u0[i + 1])
        else:
            target = _dh_end_frame(T, hand)
        rows.append(_dh_row(np.linalg.inv(T) @ target))
        T = T @ _row_link("dh", rows[-1])
        frames.append(T)
    return frames[0], rows, frames


def _walk_mdh(points: Array, u0: Array, hand: Array, tol: float) -> tuple[Array, list, list[Array]]:
    """Modified DH: frame i sits on axis i where the common normal to axis i+1 leaves it. Row i
    first reaches axis i from frame i-1 (``Rx(alpha_{i-1}) Tx(a_{i-1})``, as well as that can when
    the previous pair was only nearly parallel), and frame i is placed on the axis so reached.
    Returns the base frame, the rows (a_{i-1}, alpha_{i-1}, d_i, theta_i) and the table's frames
    1..n followed by frame n again (the one the tool hangs on), world, q = 0."""
    n = len(u0)
    T = _base_frame(points[0], u0[0])
    base, frames, rows = T, [], []
    for i in range(n):
        p, z = _mdh_reach(T, points[i], u0[i])  # p: where the previous normal meets axis i
        if i < n - 1:
            foot, _, normal = _common_normal(p, z, points[i + 1], u0[i + 1], p, T[:3, 0], tol)
        else:
            foot = p + np.dot(hand[:3, 3] - p, z) * z
            normal = _end_normal(hand[:3, 3] - foot, z, T[:3, 0], hand)
        rows.append(_mdh_row(np.linalg.inv(T) @ _frame(foot, normal, z)))
        T = T @ _row_link("mdh", rows[-1])
        frames.append(T)
    return base, rows, frames + [T]


def _mdh_reach(T: Array, point: Array, axis: Array) -> tuple[Array, Array]:
    """The line ``T Rx(alpha) Tx(a)`` puts its z axis on, with alpha and a chosen to reach the
    line (point, axis) (exactly when that line is perpendicular to T's x axis): origin, direction."""
    z = T[:3, :3].T @ axis
    o, x = T[:3, 3], T[:3, 0]
    a = np.dot(_closest_point(o, x, point, axis) - o, x)
    M = T @ _row_link("mdh", (a, np.arctan2(-z[1], z[2]), 0.0, 0.0))
    return M[:3, 3], M[:3, 2]


def _base_frame(point: Array, axis: Array) -> Array:
    """Frame 0: z along axis 1, origin at the foot of the perpendicular from the world origin,
    x along the world axis most perpendicular to axis 1."""
    origin = point - np.dot(point, axis) * axis
    return _frame(origin, np.eye(3)[np.argmin(np.abs(axis))], axis)


def _dh_end_frame(T: Array, hand: Array) -> Array:
    """Standard DH frame n: origin at the end point, x perpendicular to axis n (towards the end
    point, or along the hand's x axis when the end point is on axis n), z as close to the
    hand's z axis as DH allows."""
    o, z = T[:3, 3], T[:3, 2]
    r = hand[:3, 3] - o
    x = _end_normal(r - np.dot(r, z) * z, z, T[:3, 0], hand)
    z_n = hand[:3, 2] - np.dot(hand[:3, 2], x) * x
    z_n = z_n if np.linalg.norm(z_n) > 1e-9 else z
    return _frame(hand[:3, 3], x, z_n, keep="x")


def _end_normal(r: Array, z: Array, x_prev: Array, hand: Array) -> Array:
    """Unit x perpendicular to z: along r (sign as for common normals) or, when r is zero,
    along the hand's x axis (its y axis when x is along z)."""
    if np.linalg.norm(r) > _EPS_M:
        return _signed(r / np.linalg.norm(r), x_prev, r)
    for e in (hand[:3, 0], hand[:3, 1]):
        x = e - np.dot(e, z) * z
        if np.linalg.norm(x) > 1e-6:
            return x / np.linalg.norm(x)
    raise AssertionError("the hand's x and y axes cannot both be along z")  # pragma: no cover


def _common_normal(
    p1: Array, u1: Array, p2: Array, u2: Array, anchor: Array, x_prev: Array, tol: float
) -> tuple[Array, Array, Array]:
    """Feet on line 1 (p1, u1) and line 2 (p2, u2) of their common normal and its unit
    direction. Lines within ``tol`` rad of parallel: the normal through the foot of ``anchor``
    on line 1 (x along the offset, or ``x_prev`` when the lines coincide)."""
    c = np.cross(u1, u2)
    if np.linalg.norm(c) > np.sin(tol):
        foot1, foot2 = _closest_point(p1, u1, p2, u2), _closest_point(p2, u2, p1, u1)
        normal = c / np.linalg.norm(c)
    else:
        foot1 = p1 + np.dot(anchor - p1, u1) * u1
        foot2 = p2 + np.dot(foot1 - p2, u2) * u2
        r = foot2 - foot1
        normal = r / np.linalg.norm(r) if np.linalg.norm(r) > _EPS_M else x_prev
    return foot1, foot2, _signed(normal, x_prev, foot2 - foot1)


def _closest_point(p1: Array, u1: Array, p2: Array, u2: Array) -> Array:
    """The point of line 1 (p1, unit u1) closest to line 2 (p2, unit u2); for parallel lines,
    the foot of p2 on line 1."""
    c = np.cross(u1, u2)
    if np.dot(c, c) < 1e-24:
        return p1 + np.dot(p2 - p1, u1) * u1
    return p1 + np.dot(np.cross(p2 - p1, u2), c) / np.dot(c, c) * u1


def _signed(x: Array, x_prev: Array, r: Array) -> Array:
    """x or -x: the one along x_prev (theta in (-90, 90] deg); if x is perpendicular to x_prev,
    the one along the offset r (a >= 0)."""
    along = np.dot(x, x_prev)
    if abs(along) < 1e-9:
        along = np.dot(x, r) if abs(np.dot(x, r)) > _EPS_M else 1.0
    return x if along > 0 else -x


def _frame(origin: Array, x: Array, z: Array, keep: str = "z") -> Array:
    """4x4 frame with that origin, z axis and x axis (x made perpendicular to z, or z to x with
    ``keep="x"``), y = z cross x."""
    z = z / np.linalg.norm(z)
    if keep == "z":
        x = x - np.dot(x, z) * z
    else:
        z = z - np.dot(z, x) * x
        z = z / np.linalg.norm(z)
    x = x / np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, origin
    return T


# --- rows and links -----------------------------------------------------------------------------
def _dh_row(rel: Array) -> tuple[float, float, float, float]:
    """(a, alpha, d, theta) of ``rel = Rz(theta) Tz(d) Tx(a) Rx(alpha)``; where rel is not of that
    form, the x axis and the z axis of the target decide theta and alpha."""
    x, z, t = rel[:3, 0], rel[:3, 2], rel[:3, 3]
    theta = np.arctan2(x[1], x[0])
    c, s = np.cos(theta), np.sin(theta)
    alpha = np.arctan2(-(-s * z[0] + c * z[1]), z[2])
    return c * t[0] + s * t[1], alpha, t[2], theta


def _mdh_row(rel: Array) -> tuple[float, float, float, float]:
    """(a, alpha, d, theta) of ``rel = Rx(alpha) Tx(a) Rz(theta) Tz(d)``; where rel is not of that
    form, the target's z axis decides alpha and its x axis theta."""
    x, z, t = rel[:3, 0], rel[:3, 2], rel[:3, 3]
    alpha = np.arctan2(-z[1], z[2])
    c, s = np.cos(alpha), np.sin(alpha)
    theta = np.arctan2(c * x[1] + s * x[2], x[0])
    return t[0], alpha, -s * t[1] + c * t[2], theta


def _row_link(convention: str, row: tuple[float, float, float, float]) -> Array:
    """(4, 4) transform of one row (a, alpha, d, theta) at q = 0."""
    a, alpha, d, theta = row
    return _link(convention, np.array([theta]), np.array([d]), a, alpha)[0]


def _link(convention: str, theta: Array, d: Array, a: float, alpha: float) -> Array:
    """(M, 4, 4) link transforms for M values of theta and d (arrays of shape (M,))."""
    if convention == "dh":
        return _rot(2, theta) @ _shift(2, d) @ _shift(0, np.full_like(d, a)) @ _rot(0, np.full_like(d, alpha))
    return _rot(0, np.full_like(d, alpha)) @ _shift(0, np.full_like(d, a)) @ _rot(2, theta) @ _shift(2, d)


def _rot(axis: int, angle: Array) -> Array:
    """(M, 4, 4) rotations by ``angle`` (M,) rad about coordinate axis 0 (x) or 2 (z)."""
    j, k = [(1, 2), None, (0, 1)][axis]
    T = np.tile(np.eye(4), (len(angle), 1, 1))
    T[:, j, j] = T[:, k, k] = np.cos(angle)
    T[:, k, j], T[:, j, k] = np.sin(angle), -np.sin(angle)
    return T


def _shift(axis: int, length: Array) -> Array:
    """(M, 4, 4) translations by ``length`` (M,) m along coordinate axis ``axis``."""
    T = np.tile(np.eye(4), (len(length), 1, 1))
    T[:, axis, 3] = length
    return T


# --- what the table misses ----------------------------------------------------------------------
def _axis_notes(robot: ZRPRobot, axis_frames: Sequence[Array], tol: float) -> tuple[str, ...]:
    """One line per joint whose table axis (z of ``axis_frames[i]`` at q = 0) differs from the
    robot's by more than 1e-12 rad or (revolute joints) 1e-12 m."""
    points = np.cumsum(robot.b0, axis=0)
    names = robot.joint_names or [f"joint_{i + 1}" for i in range(robot.n)]
    notes = []
    for i, F in enumerate(axis_frames):
        angle = np.arctan2(np.linalg.norm(np.cross(F[:3, 2], robot.u0[i])), np.dot(F[:3, 2], robot.u0[i]))
        r = F[:3, 3] - points[i]
        dist = 0.0 if robot.joint_types[i] == "P" else np.linalg.norm(r - np.dot(r, robot.u0[i]) * robot.u0[i])
        if angle > 1e-12 or dist > 1e-12:
            notes.append(
                f"joint {i + 1} ({names[i]}): axes {i} and {i + 1} are parallel within {tol:g} rad but not "
                f"exactly, which DH cannot express: the table's axis {i + 1} is off by {angle:.3g} rad, {dist:.3g} m"
            )
    return tuple(notes)


def _mismatch(robot: ZRPRobot, table: DHTable, samples: int, seed: int, notes: tuple[str, ...]) -> DHMismatch:
    """Largest hand pose difference between ``table`` and ``robot`` at q = 0 and random joint values."""
    limits = robot.joint_limits
    q = np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], size=(max(samples, 1), robot.n))
    q[0] = 0.0
    R, p = kinematics.forward(robot, q)
    T = table.forward(q)
    # |R1 - R2|_F = 2 sqrt(2) sin(angle / 2): accurate for small angles, unlike arccos of the trace
    chord = np.linalg.norm(R - T[:, :3, :3], axis=(1, 2)) / (2 * np.sqrt(2))
    angle = 2 * np.arcsin(np.minimum(chord, 1.0))
    return DHMismatch(
        float(np.max(np.linalg.norm(p - T[:, :3, 3], axis=1))), float(np.max(angle)), len(q), notes
    )
