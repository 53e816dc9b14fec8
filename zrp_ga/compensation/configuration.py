"""Which inverse-kinematics branch a joint solution is on, as controllers write it beside a
Cartesian target (so that the controller's own inverse kinematics picks the same one).

- **Quadrants** ``cf1 .. cfn`` (ABB's confdata ``cf1, cf4, cf6``; any revolute joint):
  ``floor(q_j / 90 deg)``; they also count the turns of joints that can turn more than once.
- **Branch signs** of a 6R arm (KUKA's Status bits, Fanuc's configuration string): the signs of
  the three factors whose zeros are its singularities, at the solution's axes ``u_i`` and
  points ``o_i`` and the wrist point ``w`` (the point nearest axes 4, 5 and 6, least squares):
  ``shoulder = sign((w - o_1) . (u_1 x u_2))`` (zero with the wrist point in the plane of
  axis 1 along axis 2: overhead), ``elbow = sign(u_2 . ((o_3 - o_2) x (w - o_3)))`` (zero with
  the arm stretched or folded), ``wrist = sign(u_4 . (u_5 x u_6))`` (zero with axes 4 and 6 in
  line). A solution on the other branch of one of them has that sign flipped; 0 is on the
  singularity. For a spherical wrist they are the usual front/back, up/down and flip/no flip.

>>> quadrants(np.radians([[-10.0, 95.0, 360.0]]), np.array([False, False, False]))[0].tolist()
[-1, 1, 4]
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zrp_ga.compensation.ik import chain
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
SIGNS = ("shoulder", "elbow", "wrist")


def quadrants(q: Array, prismatic: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``floor(q / 90 deg)`` (M, r) of the revolute joints of ``q`` (M, n) rad."""
    return np.floor(q[:, ~prismatic] / (np.pi / 2) + 1e-12).astype(np.int64)


def wrist_point(axes: Array, points: Array) -> Array:
    """The point (3,) nearest the lines (points[k], axes[k]) in the least-squares sense:
    ``sum_k (I - u_k u_k^T) (w - o_k) = 0``."""
    P = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]
    return np.linalg.lstsq(P.sum(axis=0), np.einsum("kij,kj->i", P, points), rcond=None)[0]


def signs(robot: ZRPRobot, q: Array) -> Array:
    """The branch signs (3,) ``shoulder, elbow, wrist`` of a 6R arm at ``q`` (6,) (module docstring)."""
    u, o, _, _ = chain(robot, q)
    w = wrist_point(u[3:6], o[3:6])
    values = [np.dot(w - o[0], np.cross(u[0], u[1])), np.dot(u[1], np.cross(o[2] - o[1], w - o[2])),
              np.dot(u[3], np.cross(u[4], u[5]))]  # fmt: skip
    return np.sign(np.round(values, 12))


def has_signs(robot: ZRPRobot) -> bool:
    """Branch signs are defined for arms of six revolute joints."""
    return robot.n == 6 and not robot.prismatic.any()


def table(robot: ZRPRobot, q: Array) -> dict[str, Array]:
    """Columns ``cf1 ..`` (quadrants, revolute joints numbered as in the arm) and, for a 6R arm,
    ``shoulder, elbow, wrist`` of solutions ``q`` (M, n) (NaN rows stay NaN)."""
    ok = np.all(np.isfinite(q), axis=1)
    out: dict[str, Array] = {}
    cf = np.full((len(q), int((~robot.prismatic).sum())), np.nan)
    cf[ok] = quadrants(q[ok], robot.prismatic)
    for k, j in enumerate(np.flatnonzero(~robot.prismatic)):
        out[f"cf{j + 1}"] = cf[:, k]
    if has_signs(robot):
        s = np.full((len(q), 3), np.nan)
        s[ok] = [signs(robot, qk) for qk in q[ok]]
        out.update({name: s[:, k] for k, name in enumerate(SIGNS)})
    return out
