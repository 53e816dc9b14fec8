"""Simulated calibration cases: the paper's case study (Section 7) for any arm and any number
of poses. A true robot is drawn around the nominal one; measurements are its poses at joint
values the model only knows up to joint noise, with optional measurement noise."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.model import kinematics
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class Simulation:
    """A simulated case: the true robot, its genome relative to the nominal one, and its poses."""

    truth: ZRPRobot
    true_x: Array
    calibration: Measurements
    validation: Measurements


def random_joints(robot: ZRPRobot, M: int, rng: np.random.Generator) -> Array:
    """M random configurations (M, n): revolute joints uniform in [-pi, pi] rad, prismatic in [0, 0.5] m."""
    q = rng.uniform(-np.pi, np.pi, size=(M, robot.n))
    q[:, robot.prismatic] = rng.uniform(0.0, 0.5, size=(M, int(robot.prismatic.sum())))
    return q


def true_robot(nominal: ZRPRobot, layout: Layout, rng: np.random.Generator, axis_error: float, body_error: float) -> ZRPRobot:
    """Axes ``u0 + U(+-axis_error)`` renormalised, the identified body vectors ``b0 + U(+-body_error)``
    (m; the base point too with ``layout.base``), the hand turned by ``U(+-axis_error)`` rad per
    axis with ``layout.hand``."""
    from scipy.spatial.transform import Rotation

    n = nominal.n
    u0 = nominal.u0 + rng.uniform(-axis_error, axis_error, size=(n, 3))
    u0 /= np.linalg.norm(u0, axis=1, keepdims=True)
    b0 = nominal.b0.copy()
    first = 0 if layout.base else 1
    b0[first:] += rng.uniform(-body_error, body_error, size=(n + 1 - first, 3))
    R_h0 = nominal.R_h0
    if layout.hand:
        R_h0 = Rotation.from_rotvec(rng.uniform(-axis_error, axis_error, size=3)).as_matrix() @ R_h0
    return nominal.replace(u0=u0, b0=b0, R_h0=R_h0, name=f"{nominal.name} (true)")


def measure(
    truth: ZRPRobot,
    q: Array,
    rng: np.random.Generator,
    joint_noise: float = 0.0,
    position_noise: float = 0.0,
    orientation_noise: float = 0.0,
    position_only: bool = False,
) -> Measurements:
    """Poses of ``truth`` at ``q + U(+-joint_noise)`` with Gaussian measurement noise (standard
    deviations ``position_noise`` m, ``orientation_noise`` rad); the measurements record ``q``."""
    from scipy.spatial.transform import Rotation

    M = q.shape[0]
    q_actual = q + rng.uniform(-joint_noise, joint_noise, size=q.shape)
    R, p = kinematics.forward(truth, q_actual)
    p = p + rng.normal(scale=position_noise, size=p.shape) if position_noise > 0 else p
    if orientation_noise > 0:
        R = Rotation.from_rotvec(rng.normal(scale=orientation_noise, size=(M, 3))).as_matrix() @ R
    return Measurements(q=q, p=p, R=None if position_only else R, source="simulation")


def simulate(
    nominal: ZRPRobot,
    layout: Layout,
    rng: np.random.Generator,
    n_poses: int = 1,
    n_validation: int = 100,
    axis_error: float = 0.01,
    body_error: float = 5e-4,
    joint_noise: float = 1e-3,
    position_noise: float = 0.0,
    orientation_noise: float = 0.0,
    position_only: bool = False,
) -> Simulation:
    """The paper's case study: a true robot (:func:`true_robot`), ``n_poses`` calibration poses
    and ``n_validation`` validation poses at random configurations (:func:`measure`), drawn in
    that order from ``rng``. The validation poses never enter the cost."""
    truth = true_robot(nominal, layout, rng, axis_error, body_error)
    noise: dict[str, Any] = dict(joint_noise=joint_noise, position_noise=position_noise, orientation_noise=orientation_noise,
                                 position_only=position_only)  # fmt: skip
    calibration = measure(truth, random_joints(nominal, n_poses, rng), rng, **noise)
    validation = measure(truth, random_joints(nominal, n_validation, rng), rng, **noise)
    return Simulation(truth, layout.pack(nominal, truth), calibration, validation)
