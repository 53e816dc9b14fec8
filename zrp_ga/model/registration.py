"""Rigid registration of a nominal arm to points measured in an instrument's frame.

Measured points ``P_i`` (a laser tracker several metres away) of tool points on the hand are
modelled as ``P_i = R (f_i + F_i d_k(i)) + t``: the nominal flange position ``f_i`` and
orientation ``F_i`` at the measured joint values, an unknown offset ``d_k`` in the hand frame
of each tool point k (several reflectors on one flange) and an unknown rigid transform
``(R, t)`` from the robot's base to the instrument. A start comes from Kabsch's algorithm
(``scipy.spatial.transform.Rotation.align_vectors``, the weighted Kabsch / Umeyama solution
without scale); ``scipy.optimize.least_squares`` then fits all 6 + 3T numbers.

:func:`align` is the same rigid fit for point sets alone: a validation in another instrument
frame (the tracker moved) re-registers the predictions to the measurements before scoring.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from zrp_ga.model import kinematics
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class Registration:
    """Base-to-instrument rotation R (3, 3) and translation t (3,) m; the tool offsets ``tools``
    (T, 3) m in the hand frame (``tool``: the first), named ``tool_names``; the distance (m) of
    every measured point after registration ``errors`` (M,) and their RMS and max; with measured
    orientations, the tool's rotation in the hand frame (3, 3) and the RMS and max angle (rad)."""

    R: Array
    t: Array
    tools: Array
    errors: Array
    tool_names: tuple[str, ...] = ("tool",)
    tool_rotation: Array | None = None
    rms_angle: float | None = None
    max_angle: float | None = None

    @property
    def tool(self) -> Array:
        return self.tools[0]

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.errors**2)))

    @property
    def max(self) -> float:
        return float(self.errors.max())

    def apply(self, robot: ZRPRobot, tool: int = 0) -> ZRPRobot:
        """The nominal robot with tool ``tool``, in the instrument's frame."""
        robot = robot.with_tool(self.tools[tool])
        if self.tool_rotation is not None:
            robot = robot.replace(R_h0=robot.R_h0 @ self.tool_rotation)
        return robot.transformed(self.R, self.t)

    def base(self) -> Array:
        """The base-to-instrument transform (4, 4)."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R, self.t
        return T

    def to_dict(self) -> dict:
        out = {"R": self.R.tolist(), "t_m": self.t.tolist(), "tool_m": self.tool.tolist(),
               "rms_mm": self.rms * 1e3, "max_mm": self.max * 1e3}  # fmt: skip
        if len(self.tools) > 1:
            out["tools_m"] = dict(zip(self.tool_names, self.tools.tolist()))
        if self.tool_rotation is not None:
            assert self.rms_angle is not None  # estimated with the tool's rotation (register(rotations=...))
            out.update(tool_rotation=self.tool_rotation.tolist(), rms_angle_deg=np.degrees(self.rms_angle))
        return out


def register(
    robot: ZRPRobot,
    q: ArrayLike,
    points: ArrayLike,
    tool0: ArrayLike | None = None,
    rotations: ArrayLike | None = None,
    tools: ArrayLike | None = None,
    tool_names: tuple[str, ...] | None = None,
) -> Registration:
    """Fit base transform and tool offsets so that ``robot`` best predicts ``points`` (M, 3), m.
    ``tools`` (M,): the tool index of each point (None: one tool), ``tool0`` (3,) or (T, 3) the
    offsets to start from (default zero). With measured ``rotations`` (M, 3, 3) of the tool, its
    rotation in the hand frame too: the mean rotation (``scipy``'s ``Rotation.mean``) of
    ``(R F_i)^T R_meas_i``."""
    F, f = kinematics.forward(robot, np.atleast_2d(q))
    P = np.asarray(points, dtype=float)
    k = np.zeros(len(P), dtype=int) if tools is None else np.asarray(tools, dtype=int)
    T = int(k.max()) + 1
    d = np.zeros((T, 3)) if tool0 is None else np.broadcast_to(np.asarray(tool0, dtype=float), (T, 3)).copy()
    X = f + np.einsum("mij,mj->mi", F, d[k])
    rot, _ = Rotation.align_vectors(P - P.mean(axis=0), X - X.mean(axis=0))
    t = P.mean(axis=0) - rot.apply(X.mean(axis=0))

    def residual(x: Array) -> Array:
        offsets = x[6:].reshape(T, 3)[k]
        return (Rotation.from_rotvec(x[:3]).apply(f + np.einsum("mij,mj->mi", F, offsets)) + x[3:6] - P).ravel()

    fit = least_squares(residual, np.concatenate([rot.as_rotvec(), t, d.ravel()]), method="lm")
    err = np.linalg.norm(fit.fun.reshape(-1, 3), axis=1)
    R = Rotation.from_rotvec(fit.x[:3]).as_matrix()
    names = tuple(tool_names) if tool_names is not None else tuple(f"tool{i + 1}" for i in range(T)) if T > 1 else ("tool",)
    reg = Registration(R, fit.x[3:6], fit.x[6:].reshape(T, 3), err, names)
    if rotations is None:
        return reg
    hand = Rotation.from_matrix(R @ F)  # nominal hand orientations in the instrument frame
    tool = (hand.inv() * Rotation.from_matrix(np.asarray(rotations, dtype=float))).mean()
    angles = ((hand * tool).inv() * Rotation.from_matrix(np.asarray(rotations, dtype=float))).magnitude()
    rms_angle = float(np.sqrt(np.mean(angles**2)))
    return dataclasses.replace(reg, tool_rotation=tool.as_matrix(), rms_angle=rms_angle, max_angle=float(angles.max()))


def align(predicted: ArrayLike, measured: ArrayLike) -> Array:
    """``predicted`` points (M, 3) moved rigidly onto ``measured`` (M, 3) in the least-squares
    sense (Kabsch, by ``Rotation.align_vectors`` about the centroids); needs three points not
    on one line."""
    A, B = np.asarray(predicted, dtype=float), np.asarray(measured, dtype=float)
    a, b = A.mean(axis=0), B.mean(axis=0)
    rot, _ = Rotation.align_vectors(B - b, A - a)
    return rot.apply(A - a) + b
