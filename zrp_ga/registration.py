"""Rigid registration of a nominal arm to points measured in an instrument's frame.

Measured points ``P_i`` (a laser tracker several metres away) of a tool point on the hand are
modelled as ``P_i = R (f_i + F_i d) + t``: the nominal flange position ``f_i`` and orientation
``F_i`` at the measured joint values, an unknown tool offset ``d`` in the hand frame and an
unknown rigid transform ``(R, t)`` from the robot's base to the instrument. A start comes from
Kabsch's algorithm (``scipy.spatial.transform.Rotation.align_vectors``, the weighted Kabsch /
Umeyama solution without scale); ``scipy.optimize.least_squares`` then fits all nine numbers.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from zrp_ga import kinematics
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class Registration:
    """Base-to-instrument rotation R (3, 3) and translation t (3,) m; tool offset (3,) m in the
    hand frame; the RMS and max distance (m) of the measured points after registration; with
    measured orientations, the tool's rotation in the hand frame (3, 3) and the RMS angle (rad)."""

    R: Array
    t: Array
    tool: Array
    rms: float
    max: float
    tool_rotation: Array | None = None
    rms_angle: float | None = None

    def apply(self, robot: ZRPRobot) -> ZRPRobot:
        """The nominal robot with its tool, in the instrument's frame."""
        robot = robot.with_tool(self.tool)
        if self.tool_rotation is not None:
            robot = robot.replace(R_h0=robot.R_h0 @ self.tool_rotation)
        return robot.transformed(self.R, self.t)

    def to_dict(self) -> dict:
        out = {"R": self.R.tolist(), "t_m": self.t.tolist(), "tool_m": self.tool.tolist(),
               "rms_mm": self.rms * 1e3, "max_mm": self.max * 1e3}  # fmt: skip
        if self.tool_rotation is not None:
            out.update(tool_rotation=self.tool_rotation.tolist(), rms_angle_deg=np.degrees(self.rms_angle))
        return out


def register(
    robot: ZRPRobot, q: ArrayLike, points: ArrayLike, tool0: ArrayLike | None = None, rotations: ArrayLike | None = None
) -> Registration:
    """Fit base transform and tool offset so that ``robot`` best predicts ``points`` (M, 3), m.
    With measured ``rotations`` (M, 3, 3) of the tool, its rotation in the hand frame too: the
    mean rotation (``scipy``'s ``Rotation.mean``) of ``(R F_i)^T R_meas_i``."""
    F, f = kinematics.forward(robot, np.atleast_2d(q))
    P = np.asarray(points, dtype=float)
    d = np.zeros(3) if tool0 is None else np.asarray(tool0, dtype=float)
    X = f + F @ d
    rot, _ = Rotation.align_vectors(P - P.mean(axis=0), X - X.mean(axis=0))
    t = P.mean(axis=0) - rot.apply(X.mean(axis=0))

    def residual(x: Array) -> Array:
        return (Rotation.from_rotvec(x[:3]).apply(f + F @ x[6:]) + x[3:6] - P).ravel()

    fit = least_squares(residual, np.concatenate([rot.as_rotvec(), t, d]), method="lm")
    err = np.linalg.norm(fit.fun.reshape(-1, 3), axis=1)
    R = Rotation.from_rotvec(fit.x[:3]).as_matrix()
    reg = Registration(R, fit.x[3:6], fit.x[6:], float(np.sqrt(np.mean(err**2))), float(err.max()))
    if rotations is None:
        return reg
    hand = Rotation.from_matrix(R @ F)  # nominal hand orientations in the instrument frame
    tool = (hand.inv() * Rotation.from_matrix(np.asarray(rotations, dtype=float))).mean()
    angles = (hand * tool).inv() * Rotation.from_matrix(np.asarray(rotations, dtype=float))
    rms_angle = float(np.sqrt(np.mean(angles.magnitude() ** 2)))
    return dataclasses.replace(reg, tool_rotation=tool.as_matrix(), rms_angle=rms_angle)
