"""DH and modified-DH tables: the table, its forward kinematics, and the table of a ZRP arm.

Conventions (lengths m, angles rad); a revolute joint adds q_i to theta_i, a prismatic one to d_i:

- ``"dh"`` (standard, distal): ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)``; joint
  i turns about the z axis of frame i-1.
- ``"mdh"`` (modified, proximal, Craig): ``A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Ry(beta_{i-1}) Rz(theta_i) Tz(d_i)``;
  row i holds ``a_{i-1}, alpha_{i-1}, beta_{i-1}, d_i, theta_i`` and joint i turns about the z
  axis of frame i.

``beta`` is Hayati's rotation about y (Hayati and Mirmirani, 1985) for nearly parallel
consecutive axes; it is 0 in a plain DH table, and a row with ``beta != 0`` is a Hayati row.

The hand pose is ``base A_1(q_1) ... A_n(q_n) tool`` (``base``, ``tool``: 4x4 transforms).

:func:`to_dh` finds the table of a ZRP arm by walking its axes at q = 0 (docs/model.md, section 5):
frame x axes lie along the common normals of consecutive axes, z axes along the joint axes (the
ZRP direction, so that q turns the same way). Choices where the geometry leaves freedom:

- base frame: z along axis 1, origin at the foot of the perpendicular from the world origin to
  axis 1, x along the world axis most perpendicular to axis 1 (projected);
- sign of each common normal: the one that makes ``theta_i`` (the joint value at q = 0) lie in
  (-90, 90] degrees (so ``a`` may be negative, as in Universal Robots' tables); at exactly 90
  degrees, the one with ``a >= 0``;
- consecutive axes within ``parallel_tol`` (default 1 degree) of parallel, or whose common
  normal would lie farther along the axis than the arm's size (the sum of its body vectors'
  lengths): the common normal is not unique, or lies metres away on a calibrated arm whose
  parallel axes are tilted by a fraction of a degree. Such a pair gets Hayati's
  parameterisation: the next frame's origin is where the second axis crosses the plane through
  the previous frame's origin perpendicular to the first (``d = 0``, Craig's and Corke's
  convention for parallel axes), and ``beta`` tilts z onto the second axis. Exactly parallel
  axes get ``beta = 0``, a plain DH row; every row with ``beta != 0`` is named in
  :attr:`DHMismatch.notes`. The table stays exact and its lengths those of the arm;
- last frame: standard DH puts frame n's origin at the end point and its z axis along the hand's
  z axis where DH allows; modified DH puts frame n on axis n at the foot of the perpendicular
  from the end point. ``tool`` holds the rest of the hand pose.

With a nominal table (``to_dh(robot, like=nominal)``, :func:`nominal_tables`) these choices are
the nominal's instead (:func:`_walk_like`): each row reads as the nominal row plus a small
correction (:func:`corrections`), which a controller's DH data and a reviewer can take.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model import kinematics
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
CONVENTIONS = ("dh", "mdh")
PARALLEL_TOL = np.radians(1.0)  # consecutive axes closer to parallel get Hayati rows (rad)
_EPS_M = 1e-12  # lengths below this are zero (m)


@dataclasses.dataclass(frozen=True, eq=False)
class DHTable:
    """A DH (``convention="dh"``) or modified-DH (``"mdh"``) table, SI units.

    ``a``, ``alpha``, ``d``, ``theta``: (n,) m, rad, m, rad (row i as in the module docstring;
    ``theta`` is the joint angle at q = 0 of a revolute joint and the fixed angle of a
    prismatic one); ``base``, ``tool``: (4, 4); ``limits``: (n, 2) or None (defaults);
    ``beta``: (n,) rad, Hayati's tilts (None: all 0).

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
    beta: Array | None = None

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise ValueError(f"convention: {self.convention!r}, expected one of {', '.join(CONVENTIONS)}")
        n = len(self.joint_types)
        if self.beta is None:
            object.__setattr__(self, "beta", np.zeros(n))
        for field in ("a", "alpha", "d", "theta", "beta"):
            value = np.array(getattr(self, field), dtype=float)
            if value.shape != (n,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{field}: expected {n} finite numbers, got {getattr(self, field)!r}")
            object.__setattr__(self, field, value)
        robot = self.to_robot()  # validates types, names, limits, base and tool the ZRP way
        object.__setattr__(self, "joint_names", robot.joint_names)
        for field in ("a", "alpha", "d", "theta", "beta", "base", "tool", "limits"):
            value = getattr(robot, field) if field == "limits" else np.array(getattr(self, field), dtype=float)
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, field, value)

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_types)

    @property
    def betas(self) -> Array:
        """``beta`` (n,) rad as the table holds it: zeros for a table given none."""
        assert self.beta is not None  # __post_init__ (and _table) set it
        return self.beta

    def to_robot(self) -> ZRPRobot:
        """The ZRP description (exact: docs/model.md, section 1): the joint axes are the z axes
        of the frames at q = 0 (frames 0..n-1 for DH, 1..n for modified DH), through their origins."""
        if not self.betas.any():  # a plain table: the robot's own DH reading
            make = ZRPRobot.from_dh if self.convention == "dh" else ZRPRobot.from_mdh
            return make(d=self.d, a=self.a, alpha=self.alpha, offset=self.theta, joint_types=self.joint_types,
                        tool=self.tool, base=self.base, name=self.name, joint_names=self.joint_names, limits=self.limits)  # fmt: skip
        frames = [self.base]
        for i in range(self.n):
            frames.append(frames[-1] @ _row_link(self.convention, self.row(i)))
        axis_frames = frames[:-1] if self.convention == "dh" else frames[1:]
        end = frames[-1] @ self.tool
        points = np.array([F[:3, 3] for F in axis_frames] + [end[:3, 3]])
        b0 = np.diff(np.vstack([np.zeros(3), points]), axis=0)
        u0 = np.array([F[:3, 2] for F in axis_frames])
        return ZRPRobot(u0=u0, b0=b0, R_h0=end[:3, :3], joint_types=self.joint_types, normalize=True, name=self.name,
                        joint_names=self.joint_names, limits=self.limits)  # fmt: skip

    def row(self, i: int) -> tuple[float, float, float, float, float]:
        """Row i (from 0): (a, alpha, d, theta, beta)."""
        return self.a[i], self.alpha[i], self.d[i], self.theta[i], self.betas[i]

    def link(self, i: int) -> Array:
        """(4, 4) transform of row i (from 0) at q = 0, frame i-1 to frame i (module docstring)."""
        return _row_link(self.convention, self.row(i))

    def forward(self, q: ArrayLike) -> Array:
        """Hand pose ``base A_1 ... A_n tool`` at joint values q (n,) or (M, n): (4, 4) or (M, 4, 4)."""
        q = kinematics.check_q(q, self.n)
        Q = np.atleast_2d(q)
        revolute = np.array([t == "R" for t in self.joint_types])
        T = np.broadcast_to(self.base, (len(Q), 4, 4))
        for i in range(self.n):  # the fixed one of theta and d a number, its link factor one matrix
            theta = self.theta[i] + Q[:, i] if revolute[i] else self.theta[i] + 0.0
            d = self.d[i] + 0.0 if revolute[i] else self.d[i] + Q[:, i]
            if self.betas[i]:
                T = T @ _link(self.convention, theta, d, self.a[i], self.alpha[i], self.betas[i])
            else:
                T = T @ _plain_link(self.convention, theta, d, self.a[i], self.alpha[i], len(Q))
        T = T @ self.tool
        return T[0] if q.ndim == 1 else T


@dataclasses.dataclass(frozen=True)
class DHMismatch:
    """How far a table found by :func:`to_dh` is from the ZRP arm.

    ``position_m`` and ``orientation_rad``: largest hand position and orientation difference
    between the table's and the arm's forward kinematics over ``samples`` joint values (q = 0
    and uniform within the joint limits); ``notes``: one line per Hayati row (nearly parallel
    axes, module docstring) and per joint whose axis the table cannot place exactly.
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
    robot: ZRPRobot, convention: str = "dh", parallel_tol: float = PARALLEL_TOL, samples: int = 200, seed: int = 0,
    max_offset: float | None = None, base_x: ArrayLike | None = None, like: DHTable | None = None,
) -> tuple[DHTable, DHMismatch]:
    """The DH (``"dh"``) or modified-DH (``"mdh"``) table of a ZRP arm and what it misses.

    Choices are those of the module docstring; consecutive axes within ``parallel_tol`` (rad) of
    parallel, or whose common normal lies farther than ``max_offset`` (m; default: the arm's
    size, the sum of its body vectors' lengths) along the axis, get Hayati rows. The
    mismatch is measured at q = 0 and ``samples - 1`` joint values drawn uniformly within
    ``robot.joint_limits`` (``numpy.random.default_rng(seed)``). ``base_x`` (3,): the base
    frame's x axis is this direction made perpendicular to axis 1 (default: the world axis most
    perpendicular to axis 1, which jumps where two tie).

    ``like`` (a table of an arm near ``robot``, typically its nominal table): the table in that
    table's conventions instead (its convention; ``max_offset`` and ``base_x`` unused), row by
    row the nominal's plus a small correction (:func:`_walk_like`).

    >>> from zrp_ga.io import presets
    >>> table, mismatch = to_dh(presets.get("puma560"))
    >>> np.round(np.degrees(table.alpha)).tolist(), mismatch.position_m < 1e-15
    ([90.0, 0.0, -90.0, 90.0, -90.0, 0.0], True)
    """
    return _to_dh(robot, convention, parallel_tol, samples, seed, max_offset, base_x, like=like)


def tables(
    robot: ZRPRobot, samples: int = 200, seed: int = 0, like: dict[str, DHTable] | None = None
) -> dict[str, tuple[DHTable, DHMismatch]]:
    """``{convention: to_dh(robot, convention, samples=samples, seed=seed, like=like[convention])}``
    for both conventions (``like``: None, or a table by convention, as in :func:`nominal_tables`),
    the arm's own hand poses at the joint samples computed once for both.

    >>> from zrp_ga.io import presets
    >>> sorted(tables(presets.get("puma560"), samples=5))
    ['dh', 'mdh']
    """
    reference = _reference(robot, samples, seed)
    like = like or {}
    return {c: _to_dh(robot, c, PARALLEL_TOL, samples, seed, None, None, reference, like.get(c)) for c in CONVENTIONS}


def nominal_tables(nominal: ZRPRobot) -> dict[str, DHTable]:
    """The tables of the nominal arm by convention, as a calibrated arm's are to follow
    (``tables(calibrated, like=nominal_tables(nominal))``): the table the arm was read from
    (``nominal.source``, a :class:`DHTable`) for its convention, :func:`to_dh`'s own for the other.

    >>> from zrp_ga.io import presets
    >>> nominal_tables(presets.get("ur10"))["dh"] is presets.get("ur10").source
    True
    """
    source = nominal.source if isinstance(nominal.source, DHTable) else None
    return {c: source if source is not None and source.convention == c else to_dh(nominal, c, samples=1)[0]
            for c in CONVENTIONS}  # fmt: skip


def _to_dh(
    robot: ZRPRobot, convention: str, parallel_tol: float, samples: int, seed: int, max_offset: float | None,
    base_x: ArrayLike | None, reference: tuple[Array, Array, Array] | None = None, like: DHTable | None = None,
) -> tuple[DHTable, DHMismatch]:
    """:func:`to_dh`; ``reference``: ``_reference(robot, samples, seed)`` if already computed."""
    if convention not in CONVENTIONS:
        raise ValueError(f"convention: {convention!r}, expected one of {', '.join(CONVENTIONS)}")
    points = np.cumsum(robot.b0, axis=0)  # points[i]: on axis i+1; points[n]: the end point
    hand = np.eye(4)
    hand[:3, :3], hand[:3, 3] = robot.R_h0, points[-1]
    if like is not None:
        _check_like(robot, like)
        convention = like.convention
        base, rows, axis_frames, far = _walk_like(points, robot.u0, hand, like, parallel_tol)
    else:
        walk = _walk_dh if convention == "dh" else _walk_mdh
        size = float(np.linalg.norm(robot.b0, axis=1).sum()) if max_offset is None else max_offset
        base, rows, axis_frames, far = walk(points, robot.u0, hand, parallel_tol, size, base_x)
    a, alpha, d, theta, beta = _tidy(np.array(rows).T)
    table = _table(convention, a, alpha, d, theta, robot, _tidy(base), beta)
    last = table.forward(np.zeros(robot.n))  # frame n of the tidied table
    table = _with_tool(table, _tidy(np.linalg.inv(last) @ hand))
    notes = _hayati_notes(robot, table, far) + _axis_notes(robot, axis_frames[:-1])
    return table, _mismatch(robot, table, _reference(robot, samples, seed) if reference is None else reference, notes)


def _table(convention: str, a: Array, alpha: Array, d: Array, theta: Array, robot: ZRPRobot, base: Array,
           beta: Array) -> DHTable:  # fmt: skip
    """``DHTable(convention, a, alpha, d, theta, robot.joint_types, base=base, name=robot.name,
    joint_names=robot.joint_names, limits=robot.limits, beta=beta)`` for the rows :func:`to_dh`
    read off the checked arm ``robot``: the fields as DHTable makes them (float arrays, read-only),
    without checking them again through a ZRP robot of their own (a third of to_dh's time).
    Rows that are not finite are refused all the same."""
    values: dict[str, Array | None] = {"a": a, "alpha": alpha, "d": d, "theta": theta, "beta": beta, "base": base,
                                       "tool": np.eye(4)}  # fmt: skip
    values["limits"] = None if robot.limits is None else robot.limits
    table = object.__new__(DHTable)
    for field, value in values.items():
        if value is not None:
            value = np.array(value, dtype=float)
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{field}: expected finite numbers, got {value!r}")
            value.setflags(write=False)
        object.__setattr__(table, field, value)
    for field, setting in (("convention", convention), ("joint_types", robot.joint_types), ("name", robot.name),
                           ("joint_names", robot.joint_names)):  # fmt: skip
        object.__setattr__(table, field, setting)
    return table


def _with_tool(table: DHTable, tool: Array) -> DHTable:
    """``dataclasses.replace(table, tool=tool)`` without checking the table again: the rows were
    checked when it was built, and the tool, computed from its own frame n, is a transform."""
    tool = np.array(tool, dtype=float)
    tool.setflags(write=False)
    out = copy.copy(table)
    object.__setattr__(out, "tool", tool)
    return out


DH_KINDS = ("a", "alpha", "d", "theta", "beta")  # the columns of a table row, as named by parameters()


def parameters(robot: ZRPRobot, convention: str = "dh", base_x: ArrayLike | None = None) -> dict[str, float]:
    """The DH (``"dh"``) or modified-DH (``"mdh"``) parameters of ``robot`` as :func:`to_dh`
    reads them, by name ``dh_<kind>_<i>``: ``kind`` one of ``a, alpha, d, theta, beta`` (m, rad),
    ``i`` the table's row (joint i, from 1; in a modified-DH table row i holds ``a_{i-1}``,
    ``alpha_{i-1}``, ``beta_{i-1}``, ``d_i``, ``theta_i``). ``base_x``: as in :func:`to_dh`
    (give the nominal table's, ``table.base[:3, 0]``, to read nearby arms smoothly).

    >>> from zrp_ga.io import presets
    >>> round(parameters(presets.get("puma560"))["dh_a_2"], 4)
    0.4318
    """
    table, _ = to_dh(robot, convention, samples=1, base_x=base_x)
    return {f"dh_{k}_{i + 1}": float(getattr(table, k)[i]) for k in DH_KINDS for i in range(robot.n)}


def _tidy(x: Array) -> Array:
    """Round-off below 1e-14 set to zero (and -0.0 to 0.0), so that files read 0.0 rather than
    -1.2e-17. The mismatch is measured after this."""
    return np.where(np.abs(x) < 1e-14, 0.0, x) + 0.0


# --- the walk along the axes at q = 0 ------------------------------------------------------------
def _walk_dh(
    points: Array, u0: Array, hand: Array, tol: float, size: float, base_x: ArrayLike | None = None
) -> tuple[Array, list, list[Array], dict[int, float]]:
    """Standard DH: frame i-1 has z along axis i; frame i sits on axis i+1 where the common
    normal from axis i meets it, or (Hayati row, nearly parallel axes) where axis i+1 crosses
    the plane through frame i-1's origin perpendicular to axis i. Each row is read off against
    the table's own previous frame, so that a row that is not exact does not shift the later
    ones. Returns the base frame, the rows (a, alpha, d, theta, beta), the table's frames 0..n
    (world, q = 0) and, for each Hayati row (index from 0), how far away the common normal was."""
    n = len(u0)
    T = _base_frame(points[0], u0[0], base_x)
    frames, rows, far = [T], [], {}
    for i in range(n):
        if i == n - 1:
            rows.append((*_dh_row(np.linalg.inv(T) @ _dh_end_frame(T, hand)), 0.0))
        else:
            o, z, x = T[:3, 3], T[:3, 2], T[:3, 0]
            away = _normal_distance(o, z, points[i + 1], u0[i + 1])
            if _line_angle(z, u0[i + 1]) < tol or away > size:
                cross = _crossing(o, z, points[i + 1], u0[i + 1])
                normal = _normal_towards(cross - o, x)
                theta = np.arctan2(np.dot(normal, T[:3, 1]), np.dot(normal, x))
                M = T @ _row_link("dh", (np.dot(cross - o, normal), 0.0, 0.0, theta, 0.0))
                alpha, beta = _tilt(M, u0[i + 1])
                rows.append((np.dot(cross - o, normal), alpha, 0.0, theta, beta))
                far[i] = away
            else:
                _, foot, normal = _common_normal(o, z, points[i + 1], u0[i + 1], o, x, 0.0)
                rows.append((*_dh_row(np.linalg.inv(T) @ _frame(foot, normal, u0[i + 1])), 0.0))
        T = T @ _row_link("dh", rows[-1])
        frames.append(T)
    return frames[0], rows, frames, far


def _walk_mdh(
    points: Array, u0: Array, hand: Array, tol: float, size: float, base_x: ArrayLike | None = None
) -> tuple[Array, list, list[Array], dict[int, float]]:
    """Modified DH: frame i sits on axis i where the common normal to axis i+1 leaves it, or
    (nearly parallel axes i, i+1: a Hayati row i+1) where the previous row reached axis i, with
    x towards where axis i+1 crosses the plane through it perpendicular to axis i. Row i first
    reaches axis i from frame i-1 (``Rx(alpha_{i-1}) Tx(a_{i-1}) Ry(beta_{i-1})``, beta only in a
    Hayati row, as well as that can when the previous pair was only nearly parallel), and frame
    i is placed on the axis so reached. Returns the base frame, the rows (a_{i-1}, alpha_{i-1},
    d_i, theta_i, beta_{i-1}), the table's frames 1..n followed by frame n again (the one the
    tool hangs on), world, q = 0, and, for each Hayati row (index from 0), how far away the
    common normal was."""
    n = len(u0)
    T = _base_frame(points[0], u0[0], base_x)
    base, frames, rows, far = T, [], [], {}
    for i in range(n):
        reach = _mdh_reach(T, points[i], u0[i], hayati=i - 1 in far)  # (a, alpha, 0, 0, beta)
        M = T @ _row_link("mdh", reach)
        p, z = M[:3, 3], M[:3, 2]  # where the previous row meets axis i
        if i == n - 1:
            foot = p + np.dot(hand[:3, 3] - p, z) * z
            normal = _end_normal(hand[:3, 3] - foot, z, T[:3, 0], hand)
        else:
            away = _normal_distance(p, z, points[i + 1], u0[i + 1])
            if _line_angle(z, u0[i + 1]) < tol or away > size:
                foot, normal = p, _normal_towards(_crossing(p, z, points[i + 1], u0[i + 1]) - p, T[:3, 0])
                far[i] = away
            else:
                foot, _, normal = _common_normal(p, z, points[i + 1], u0[i + 1], p, T[:3, 0], 0.0)
        rel = np.linalg.inv(M) @ _frame(foot, normal, z)  # Rz(theta) Tz(d)
        if i - 1 in far:
            rows.append((reach[0], reach[1], rel[2, 3], np.arctan2(rel[1, 0], rel[0, 0]), reach[4]))
        else:
            rows.append((*_mdh_row(np.linalg.inv(T) @ _frame(foot, normal, z)), 0.0))
        T = T @ _row_link("mdh", rows[-1])
        frames.append(T)
    return base, rows, frames + [T], {i + 1: away for i, away in far.items()}


# --- the walk in a nominal table's conventions ------------------------------------------------
def _check_like(robot: ZRPRobot, like: DHTable) -> None:
    if not isinstance(like, DHTable) or like.joint_types != robot.joint_types:
        got = like.joint_types if isinstance(like, DHTable) else type(like).__name__
        raise ValueError(f"like: expected the table of an arm with joints {robot.joint_types}, got {got}")


def _frames_at_zero(table: DHTable) -> list[Array]:
    """The table's frames 0..n (world, q = 0): base, then each row's link after the other."""
    frames = [np.array(table.base)]
    for i in range(table.n):
        frames.append(frames[-1] @ _row_link(table.convention, table.row(i)))
    return frames


def _like_parallel(like: DHTable, frames: list[Array], i: int, tol: float) -> bool:
    """Whether the nominal's row for the pair of axes i, i+1 (from 0) is a parallel-axes row: a
    Hayati row, or axes within ``tol`` of parallel (DH: the z axes of frames i and i+1; modified
    DH: of frames i+1 and i+2)."""
    k = i if like.convention == "dh" else i + 1
    return bool(like.betas[k] != 0.0) or _line_angle(frames[k][:3, 2], frames[k + 1][:3, 2]) < tol


def onto_axis(F: Array, point: Array, u: Array) -> Array:
    """Frame F turned by the smallest rotation that takes its z axis onto u, its origin moved to
    the foot of the perpendicular from it onto the line (point, u)."""
    out = F.copy()
    z = F[:3, 2]
    c = _cross(z, u)
    angle = np.arctan2(_norm(c), np.dot(z, u))
    if _norm(c) > 0.0:
        k = c / _norm(c)
        K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        out[:3, :3] = (np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K) @ F[:3, :3]  # Rodrigues
    out[:3, 3] = point + np.dot(F[:3, 3] - point, u) * u
    return out


def _near_row(row: tuple[float, ...], nominal: tuple[float, ...]) -> tuple[float, ...]:
    """(a, alpha, d, theta, beta) with each angle the one of its turns nearest the nominal's."""
    a, alpha, d, theta, beta = row
    near = lambda x, x0: x0 + float(np.angle(np.exp(1j * (x - x0))))
    return a, near(alpha, nominal[1]), d, near(theta, nominal[3]), near(beta, nominal[4])


def _walk_like(
    points: Array, u0: Array, hand: Array, like: DHTable, tol: float
) -> tuple[Array, list, list[Array], dict[int, float]]:
    """The walk of :func:`_walk_dh` or :func:`_walk_mdh` with the nominal table ``like``'s
    choices, so that each row reads as the nominal's plus a small correction:

    - the base frame is the nominal's, turned by the smallest rotation that puts joint 1's
      axis where the arm has it and moved onto that axis (modified DH: row 1's
      ``Rx(alpha_0) Tx(a_0) Ry(beta_0)`` stays the nominal's and the base carries the rest);
      a base turn of the nominal stays in the base, not in row 1;
    - each common normal's sign (hence the signs of ``a``, ``alpha``, ``theta``) is the one
      nearest the nominal frame's x axis (world, q = 0), and every angle is the turn of itself
      nearest the nominal's (270 degrees stays 270, not -90);
    - the nominal's parallel-axes rows (Hayati, or axes within ``tol`` of parallel) are Hayati
      rows with the nominal's ``d`` held (so ``d`` reads as the nominal's exactly);
    - the last frame is the DH frame nearest the arm's hand with the nominal tool taken off, so
      that the tool too is the nominal's plus a correction.

    Returns what the walks return (base, rows, axis frames, Hayati rows' common-normal distances)."""
    n, dh = len(u0), like.convention == "dh"
    nominal = _frames_at_zero(like)
    target = hand @ np.linalg.inv(like.tool)  # where frame n belongs, the nominal tool kept
    if dh:
        T = onto_axis(nominal[0], points[0], u0[0])
    else:  # row 1 reaches axis 1 as the nominal's does: the base carries the correction
        reach = _row_link("mdh", (like.a[0], like.alpha[0], 0.0, 0.0, like.betas[0]))
        T = onto_axis(nominal[0] @ reach, points[0], u0[0]) @ np.linalg.inv(reach)
    base, frames, rows = T, [T], []
    far: dict[int, float] = {}
    for i in range(n):
        nom = like.row(i)
        row = (_like_dh_row if dh else _like_mdh_row)(T, i, points, u0, target, like, nominal, tol, far)
        rows.append(_near_row(row, nom))
        T = T @ _row_link(like.convention, rows[-1])
        frames.append(T)
    return base, rows, frames if dh else frames[1:] + [T], far


def _like_dh_row(T: Array, i: int, points: Array, u0: Array, target: Array, like: DHTable, nominal: list[Array],
                 tol: float, far: dict[int, float]) -> tuple[float, ...]:  # fmt: skip
    """Standard DH row i (from 0) from frame T (z on axis i) in the nominal's choices (:func:`_walk_like`)."""
    n = len(u0)
    o, z, x_nominal = T[:3, 3], T[:3, 2], nominal[i + 1][:3, 0]
    if i == n - 1:  # the DH frame nearest the target: Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta_nominal)
        return (*_dh_row(np.linalg.inv(T) @ target @ _rot(1, -like.betas[i])), like.betas[i])
    if _like_parallel(like, nominal, i, tol):  # Hayati, d held: the plane through o + d z
        start = o + like.d[i] * z
        cross = _crossing(start, z, points[i + 1], u0[i + 1])
        normal = _normal_towards(cross - start, x_nominal)
        theta = np.arctan2(np.dot(normal, T[:3, 1]), np.dot(normal, T[:3, 0]))
        a = np.dot(cross - start, normal)
        alpha, beta = _tilt(T @ _row_link("dh", (a, 0.0, like.d[i], theta, 0.0)), u0[i + 1])
        far[i] = _normal_distance(o, z, points[i + 1], u0[i + 1])
        return a, alpha, like.d[i], theta, beta
    _, foot, normal = _common_normal(o, z, points[i + 1], u0[i + 1], o, x_nominal, 0.0)
    return (*_dh_row(np.linalg.inv(T) @ _frame(foot, normal, u0[i + 1])), 0.0)


def _like_mdh_row(T: Array, i: int, points: Array, u0: Array, target: Array, like: DHTable, nominal: list[Array],
                  tol: float, far: dict[int, float]) -> tuple[float, ...]:  # fmt: skip
    """Modified DH row i (from 0) from frame T (frame i) in the nominal's choices
    (:func:`_walk_like`): reach axis i, then place frame i+1 on it."""
    n = len(u0)
    if i == 0:
        reach = (like.a[0], like.alpha[0], 0.0, 0.0, like.betas[0])
    else:
        reach = _mdh_reach(T, points[i], u0[i], hayati=_like_parallel(like, nominal, i - 1, tol))
    M = T @ _row_link("mdh", reach)
    p, z, x_nominal = M[:3, 3], M[:3, 2], nominal[i + 1][:3, 0]
    if i == n - 1:
        F = target
    elif _like_parallel(like, nominal, i, tol):  # frame i+1 at the nominal d, x towards axis i+1's crossing
        foot = p + like.d[i] * z
        F = _frame(foot, _normal_towards(_crossing(foot, z, points[i + 1], u0[i + 1]) - foot, x_nominal), z)
        far[i + 1] = _normal_distance(p, z, points[i + 1], u0[i + 1])
    else:
        foot, _, normal = _common_normal(p, z, points[i + 1], u0[i + 1], p, x_nominal, 0.0)
        F = _frame(foot, normal, z)
    rel = np.linalg.inv(M) @ F  # Rz(theta) Tz(d), up to what a target off the axis leaves to the tool
    return reach[0], reach[1], rel[2, 3], np.arctan2(rel[1, 0] - rel[0, 1], rel[0, 0] + rel[1, 1]), reach[4]


def corrections(table: DHTable, nominal: DHTable) -> dict[str, Array]:
    """What ``table`` changes in the table ``nominal`` (same convention and joints): ``a``,
    ``alpha``, ``d``, ``theta``, ``beta`` (n,), m and rad, each angle's the smallest turn; for
    ``base`` and ``tool``, ``<key>_xyz`` (3,), m, the change of the translation, and
    ``<key>_rotvec`` (3,), rad, the rotation vector of ``R_nominal^T R``: the correction turn in
    the nominal frame (``R = R_nominal exp([rotvec]x)``).

    >>> from zrp_ga.io import presets
    >>> table = presets.get("ur10").source
    >>> float(np.abs(corrections(table, table)["theta"]).max())
    0.0
    """
    if table.convention != nominal.convention or table.joint_types != nominal.joint_types:
        raise ValueError("corrections: the tables differ in convention or joints")
    out = {}
    for k in DH_KINDS:
        change = getattr(table, k) - getattr(nominal, k)
        out[k] = np.angle(np.exp(1j * change)) if k in ("alpha", "theta", "beta") else change
    for key in ("base", "tool"):
        T, N = getattr(table, key), getattr(nominal, key)
        out[f"{key}_xyz"] = T[:3, 3] - N[:3, 3]
        out[f"{key}_rotvec"] = _rotvec(N[:3, :3].T @ T[:3, :3])
    return out


def _rotvec(R: Array) -> Array:
    """Rotation vector (3,), rad, of a rotation matrix (scipy's, for its accuracy at every angle)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


def _mdh_reach(T: Array, point: Array, axis: Array, hayati: bool) -> tuple[float, float, float, float, float]:
    """The row (a, alpha, 0, 0, beta) whose ``T Rx(alpha) Tx(a) Ry(beta)`` puts its z axis on the
    line (point, axis): exactly when that line meets T's x axis (beta: a Hayati row) or, with
    beta = 0, when it is also perpendicular to it."""
    o, x = T[:3, 3], T[:3, 0]
    a = np.dot(_closest_point(o, x, point, axis) - o, x)
    z = T[:3, :3].T @ axis
    if not hayati:
        return a, np.arctan2(-z[1], z[2]), 0.0, 0.0, 0.0
    alpha, beta = _tilt(T, axis)
    return a, alpha, 0.0, 0.0, beta


def _tilt(M: Array, axis: Array) -> tuple[float, float]:
    """(alpha, beta) with ``Rx(alpha) Ry(beta)`` turning M's z axis onto ``axis``."""
    z = M[:3, :3].T @ axis
    return np.arctan2(-z[1], z[2]), np.arcsin(np.clip(z[0], -1.0, 1.0))


def _line_angle(u1: Array, u2: Array) -> float:
    """Angle between two lines (rad, 0 to pi/2): parallel and anti-parallel axes alike."""
    return float(np.arctan2(_norm(_cross(u1, u2)), abs(np.dot(u1, u2))))


def _normal_distance(o: Array, z: Array, point: Array, axis: Array) -> float:
    """How far along line (o, z) from o its common normal with line (point, axis) leaves it
    (inf for exactly parallel lines)."""
    c = _cross(z, axis)
    if np.dot(c, c) == 0.0:
        return np.inf
    return abs(np.dot(_closest_point(o, z, point, axis) - o, z))


def _crossing(o: Array, z: Array, point: Array, axis: Array) -> Array:
    """Where line (point, axis) crosses the plane through o perpendicular to z."""
    return point + np.dot(o - point, z) / np.dot(axis, z) * axis


def _normal_towards(r: Array, x_prev: Array) -> Array:
    """Unit x along r (sign as for common normals), or x_prev when r is zero."""
    return _signed(r / _norm(r), x_prev, r) if _norm(r) > _EPS_M else x_prev


def _base_frame(point: Array, axis: Array, base_x: ArrayLike | None = None) -> Array:
    """Frame 0: z along axis 1, origin at the foot of the perpendicular from the world origin,
    x along ``base_x`` (default: the world axis most perpendicular to axis 1), projected."""
    origin = point - np.dot(point, axis) * axis
    x = np.eye(3)[np.argmin(np.abs(axis))] if base_x is None else np.asarray(base_x, dtype=float)
    return _frame(origin, x, axis)


def _dh_end_frame(T: Array, hand: Array) -> Array:
    """Standard DH frame n: origin at the end point, x perpendicular to axis n (towards the end
    point, or along the hand's x axis when the end point is on axis n), z as close to the
    hand's z axis as DH allows."""
    o, z = T[:3, 3], T[:3, 2]
    r = hand[:3, 3] - o
    x = _end_normal(r - np.dot(r, z) * z, z, T[:3, 0], hand)
    z_n = hand[:3, 2] - np.dot(hand[:3, 2], x) * x
    z_n = z_n if _norm(z_n) > 1e-9 else z
    return _frame(hand[:3, 3], x, z_n, keep="x")


def _end_normal(r: Array, z: Array, x_prev: Array, hand: Array) -> Array:
    """Unit x perpendicular to z: along r (sign as for common normals) or, when r is zero,
    along the hand's x axis (its y axis when x is along z)."""
    if _norm(r) > _EPS_M:
        return _signed(r / _norm(r), x_prev, r)
    for e in (hand[:3, 0], hand[:3, 1]):
        x = e - np.dot(e, z) * z
        if _norm(x) > 1e-6:
            return x / _norm(x)
    raise AssertionError("the hand's x and y axes cannot both be along z")  # pragma: no cover


def _common_normal(
    p1: Array, u1: Array, p2: Array, u2: Array, anchor: Array, x_prev: Array, tol: float
) -> tuple[Array, Array, Array]:
    """Feet on line 1 (p1, u1) and line 2 (p2, u2) of their common normal and its unit
    direction. Lines within ``tol`` rad of parallel: the normal through the foot of ``anchor``
    on line 1 (x along the offset, or ``x_prev`` when the lines coincide)."""
    c = _cross(u1, u2)
    if _norm(c) > np.sin(tol):
        foot1, foot2 = _closest_point(p1, u1, p2, u2), _closest_point(p2, u2, p1, u1)
        normal = c / _norm(c)
    else:
        foot1 = p1 + np.dot(anchor - p1, u1) * u1
        foot2 = p2 + np.dot(foot1 - p2, u2) * u2
        r = foot2 - foot1
        normal = r / _norm(r) if _norm(r) > _EPS_M else x_prev
    return foot1, foot2, _signed(normal, x_prev, foot2 - foot1)


def _closest_point(p1: Array, u1: Array, p2: Array, u2: Array) -> Array:
    """The point of line 1 (p1, unit u1) closest to line 2 (p2, unit u2); for parallel lines,
    the foot of p2 on line 1."""
    c = _cross(u1, u2)
    if np.dot(c, c) < 1e-24:
        return p1 + np.dot(p2 - p1, u1) * u1
    return p1 + np.dot(_cross(p2 - p1, u2), c) / np.dot(c, c) * u1


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
    z = z / _norm(z)
    if keep == "z":
        x = x - np.dot(x, z) * z
    else:
        z = z - np.dot(z, x) * x
        z = z / _norm(z)
    x = x / _norm(x)
    T = _EYE.copy()
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, _cross(z, x), z, origin
    return T


# --- small vectors and matrices ----------------------------------------------------------------
# What np.cross, np.linalg.norm and np.tile(np.eye(4), ...) compute, to the last bit (the same
# products and sums in the same order), without their overhead on 3-vectors: to_dh calls them
# a few hundred times, and a run of a sweep writes two tables.
def _cross(u: Array, v: Array) -> Array:
    """``np.cross(u, v)`` of two 3-vectors."""
    (u0, u1, u2), (v0, v1, v2) = u.tolist(), v.tolist()
    return np.array([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0])


def _norm(v: Array) -> float:
    """``np.linalg.norm(v)`` of a vector (which is ``sqrt(v.dot(v))`` of it raveled)."""
    v = v.ravel(order="K")
    return math.sqrt(v.dot(v))


_EYES = np.eye(4)[None]


def _eyes(m: int) -> Array:
    """(m, 4, 4) identities."""
    return _EYES.repeat(m, axis=0)


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


def _row_link(convention: str, row: tuple[float, ...]) -> Array:
    """(4, 4) transform of one row (a, alpha, d, theta[, beta]) at q = 0."""
    a, alpha, d, theta, *beta = row
    return _link(convention, theta, d, a, alpha, beta[0] if beta else 0.0)


def _link(convention: str, theta: Array | float, d: Array | float, a: float, alpha: float, beta: float = 0.0) -> Array:
    """(M, 4, 4) link transforms for M values of theta and d (arrays of shape (M,)); (4, 4) for
    numbers. Each factor that is the same for all M is one (4, 4) matrix: numpy's matmul takes
    the same products in the same order for a broadcast factor, so the links are the same to
    the last bit as with M copies of it."""
    tilt = _rot(1, beta) if beta else _EYE
    if convention == "dh":
        return _rot(2, theta) @ _shift(2, d) @ _shift(0, a) @ _rot(0, alpha) @ tilt
    return _rot(0, alpha) @ _shift(0, a) @ tilt @ _rot(2, theta) @ _shift(2, d)


_EYE = np.eye(4)
_EYE.setflags(write=False)


def _plain_link(convention: str, theta: Array | float, d: Array | float, a: float, alpha: float, m: int) -> Array:
    """``_link(convention, theta, d, a, alpha)`` (beta = 0) for m samples, written out: each entry
    of the product of its factors is a single product of two of their entries (or one entry),
    rounded once either way, so the link is :func:`_link`'s (up to the signs of its zeros)."""
    c, s, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    L = _eyes(m)
    if convention == "dh":  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        L[:, 0, 0], L[:, 0, 1], L[:, 0, 2], L[:, 0, 3] = c, -(s * ca), s * sa, c * a
        L[:, 1, 0], L[:, 1, 1], L[:, 1, 2], L[:, 1, 3] = s, c * ca, -(c * sa), s * a
        L[:, 2, 1], L[:, 2, 2], L[:, 2, 3] = sa, ca, d
    else:  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
        L[:, 0, 0], L[:, 0, 1], L[:, 0, 3] = c, -s, a
        L[:, 1, 0], L[:, 1, 1], L[:, 1, 2], L[:, 1, 3] = ca * s, ca * c, -sa, -(sa * d)
        L[:, 2, 0], L[:, 2, 1], L[:, 2, 2], L[:, 2, 3] = sa * s, sa * c, ca, ca * d
    return L


def _rot(axis: int, angle: Array | float) -> Array:
    """(M, 4, 4) rotations by ``angle`` (M,) rad about coordinate axis 0 (x), 1 (y) or 2 (z);
    (4, 4) for a number."""
    j, k = _PLANES[axis]
    c, s = np.cos(angle), np.sin(angle)
    if np.ndim(angle) == 0:
        T = _EYE.copy()
        T[j, j] = T[k, k] = c
        T[k, j], T[j, k] = s, -s
        return T
    T = _eyes(np.shape(angle)[0])
    T[:, j, j] = T[:, k, k] = c
    T[:, k, j], T[:, j, k] = s, -s
    return T


_PLANES = ((1, 2), (2, 0), (0, 1))  # the plane each coordinate axis turns


def _shift(axis: int, length: Array | float) -> Array:
    """(M, 4, 4) translations by ``length`` (M,) m along coordinate axis ``axis``; (4, 4) for a number."""
    if np.ndim(length) == 0:
        T = _EYE.copy()
        T[axis, 3] = length
        return T
    T = _eyes(np.shape(length)[0])
    T[:, axis, 3] = length
    return T


# --- what the table misses ----------------------------------------------------------------------
def _hayati_notes(robot: ZRPRobot, table: DHTable, far: dict[int, float]) -> tuple[str, ...]:
    """One line per Hayati row with beta != 0: which axes, how far from parallel, and why."""
    names = robot.joint_names or [f"joint_{i + 1}" for i in range(robot.n)]
    notes = []
    for i, away in sorted(far.items()):
        if table.betas[i] == 0.0:
            continue  # exactly parallel: a plain DH row
        k = i if table.convention == "dh" else i - 1  # the pair of axes k+1, k+2 (from 1)
        angle = np.degrees(_line_angle(robot.u0[k], robot.u0[k + 1]))
        normal = f"their common normal lies {away:.3g} m along axis {k + 1}" if np.isfinite(away) else "parallel"
        notes.append(
            f"row {i + 1} ({names[i]}): Hayati's parameterisation (beta = {np.degrees(table.betas[i]):.4g} deg about y, "
            f"d{'' if table.convention == 'dh' else f'_{k + 1}'} = 0): axes {k + 1} and {k + 2} are {angle:.3g} deg "
            f"from parallel ({normal})"
        )
    return tuple(notes)


def _axis_notes(robot: ZRPRobot, axis_frames: Sequence[Array]) -> tuple[str, ...]:
    """One line per joint whose table axis (z of ``axis_frames[i]`` at q = 0) differs from the
    robot's by more than 1e-12 rad or (revolute joints) 1e-12 m (not expected: a safeguard)."""
    points = np.cumsum(robot.b0, axis=0)
    names = robot.joint_names or [f"joint_{i + 1}" for i in range(robot.n)]
    notes = []
    for i, F in enumerate(axis_frames):
        angle = np.arctan2(_norm(_cross(F[:3, 2], robot.u0[i])), np.dot(F[:3, 2], robot.u0[i]))
        r = F[:3, 3] - points[i]
        dist = 0.0 if robot.joint_types[i] == "P" else _norm(r - np.dot(r, robot.u0[i]) * robot.u0[i])
        if angle > 1e-12 or dist > 1e-12:
            notes.append(
                f"joint {i + 1} ({names[i]}): the table's axis {i + 1} is off by {angle:.3g} rad, {dist:.3g} m"
            )
    return tuple(notes)


def _reference(robot: ZRPRobot, samples: int, seed: int) -> tuple[Array, Array, Array]:
    """The joint samples of :func:`to_dh`'s mismatch (q = 0, then uniform within the limits) and
    the arm's hand orientations and positions there: (q, R, p)."""
    q = _samples(robot.joint_limits.tobytes(), robot.n, samples, seed)
    R, p = kinematics.forward(robot, q)
    return q, R, p


@functools.lru_cache(maxsize=64)
def _samples(limits: bytes, n: int, samples: int, seed: int) -> Array:
    """The joint samples of :func:`_reference` for the joint limits ``limits`` (the bytes of an
    (n, 2) float array), read-only: the runs of a sweep share their arm's limits."""
    lo_hi = np.frombuffer(limits, dtype=float).reshape(n, 2)
    q = np.random.default_rng(seed).uniform(lo_hi[:, 0], lo_hi[:, 1], size=(max(samples, 1), n))
    q[0] = 0.0
    q.setflags(write=False)
    return q


def _mismatch(robot: ZRPRobot, table: DHTable, reference: tuple[Array, Array, Array], notes: tuple[str, ...]) -> DHMismatch:
    """Largest hand pose difference between ``table`` and ``robot`` at the joint samples of
    ``reference`` (:func:`_reference`)."""
    q, R, p = reference
    T = table.forward(q)
    # |R1 - R2|_F = 2 sqrt(2) sin(angle / 2): accurate for small angles, unlike arccos of the trace
    chord = np.linalg.norm(R - T[:, :3, :3], axis=(1, 2)) / (2 * np.sqrt(2))
    angle = 2 * np.arcsin(np.minimum(chord, 1.0))
    return DHMismatch(
        float(np.max(np.linalg.norm(p - T[:, :3, 3], axis=1))), float(np.max(angle)), len(q), notes
    )
