"""Inverse kinematics of a ZRP arm near a start: damped least squares within the joint limits,
and why a target was not reached.

``q* = IK(T*)`` from ``q0``: Gauss-Newton steps while they lower the residual and stay within
the limits, then ``scipy.optimize.least_squares`` (trust-region reflective, the limits as
bounds) for anything else. Started from the program's joints (or the nominal solution), it stays
on the program's branch (elbow up or down, wrist flipped or not).

A calibration with a residual model (:mod:`zrp_ga.model.residual`: a Gaussian process on joint
space, what no parametric term explains) predicts the hand at ``FK(q) + c(q)``, ``c`` the
process's mean correction. :func:`solve` with ``correction=c`` solves ``FK(q) + c(q) = p`` by a
fixed-point iteration on the parametric solver: ``q_{k+1} = IK(p - c(q_k))`` from ``q_k``, until
``c`` changes by less than a tenth of the tolerance. Why not ``c``'s Jacobian inside the
Gauss-Newton steps: ``c`` varies by fractions of a millimetre over its kernel's length scales
(tenths of a radian and more), so ``dc/dq`` is some 1e-3 of the arm's Jacobian and the iteration
contracts by about that factor per step (two or three steps); it keeps the parametric solver as
it is (its limits, its reasons) and needs no derivative of the process (scikit-learn gives
none; finite differences would cost n extra predictions per step). Orientation targets are left
to the parametric model: the process corrects positions only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from zrp_ga.io.measurements import reach_m
from zrp_ga.model import kinematics, so3, terms
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
TOLERANCE_M = 1e-6  # a target counts as reached within this position residual, m
TOLERANCE_RAD = 1e-6  # and this orientation residual, rad
ORIENTATION_LENGTH_M = 1.0  # 1 rad of orientation residual weighs as this many metres in the fit
NEWTON_STEPS = 20  # Gauss-Newton steps before the bounded solver takes over
NEWTON_DONE = 1e-14  # residual norm (m, rad) at which the steps stop: round-off
CORRECTION_STEPS = 20  # fixed-point steps with a residual model's correction (each contracts ~1e-3: a few suffice)


def chain(robot: ZRPRobot, q: ArrayLike) -> tuple[Array, Array, Array, Array]:
    """The joint axes ``u_i = R_{i-1} u0_i`` (n, 3) and a point ``o_i`` on each (n, 3) m at
    ``q`` (n,), the hand orientation R (3, 3) and the end point p (3,) m (Eq. 1-5 of the ZRP
    paper, written out: the compiled :func:`zrp_ga.model.kinematics.forward` gives no axes)."""
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
    return axes, points, R @ robot.R_h0, p + R @ robot.b0[robot.n]


def forward_jacobian(robot: ZRPRobot, q: ArrayLike) -> tuple[Array, Array, Array]:
    """Hand orientation R (3, 3), position p (3,) m and the geometric Jacobian J (6, n) at ``q``
    (n,): rows 0-2 the hand's angular velocity, rows 3-5 its linear velocity per unit joint
    velocity: revolute ``[u_i; u_i x (p - o_i)]``, prismatic ``[0; u_i]`` (:func:`chain`). The
    full model: an arm carrying non-geometric terms (:mod:`zrp_ga.model.terms`) is evaluated at the
    joint values it takes, ``q_eff(q)``, and J is ``J(q_eff) dq_eff/dq``."""
    if robot.terms is not None:
        geometric, q = robot.geometric, np.asarray(q, dtype=float)
        R, p, J = forward_jacobian(geometric, terms.effective(robot, q))
        return R, p, J @ terms.effective_derivative(robot, q)
    axes, points, R, p = chain(robot, q)
    rev = ~robot.prismatic
    J = np.zeros((6, robot.n))
    J[:3, rev] = axes[rev].T
    J[3:, rev] = np.cross(axes[rev], p - points[rev]).T
    J[3:, ~rev] = axes[~rev].T
    return R, p, J


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
          tolerance_m: float = TOLERANCE_M, tolerance_rad: float = TOLERANCE_RAD,
          correction: Callable[[Array], Array] | None = None) -> Solution:  # fmt: skip
    """Joint values within the limits that put ``robot``'s hand on position ``p`` (3,) m and,
    if given, orientation ``R`` (3, 3), from ``q0`` (n,); with ``correction`` (joint values (n,)
    -> a position offset (3,) m in the robot's frame: a residual model's mean), the hand at
    ``FK(q) + correction(q)`` (module docstring: a fixed-point iteration on this solver). The residual is ``[p(q) - p;
    ORIENTATION_LENGTH_M log(R(q) R^T)]``, its Jacobian the geometric one mapped through the
    inverse left Jacobian of SO(3). Gauss-Newton steps (least-norm ``numpy.linalg.lstsq``, as
    long as each lowers the residual and stays within the limits) reach a nearby solution in a
    few steps; anything else goes on with ``scipy.optimize.least_squares`` (trust-region
    reflective, the limits as bounds), which also says which joints a limit holds."""
    p = np.asarray(p, dtype=float)
    R = None if R is None else np.asarray(R, dtype=float)
    if correction is not None:
        return _solve_corrected(robot, p, R, q0, correction, tolerance_m, tolerance_rad)
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


def _solve_corrected(robot: ZRPRobot, p: Array, R: ArrayLike | None, q0: ArrayLike, correction: Callable[[Array], Array],
                     tolerance_m: float, tolerance_rad: float) -> Solution:  # fmt: skip
    """:func:`solve` of ``FK(q) + correction(q) = p``: ``q_{k+1} = IK(p - c(q_k))`` from ``q_k``
    until ``c`` moves by less than a tenth of ``tolerance_m`` (module docstring); the position
    residual reported (and judged) is that of the corrected model."""
    q = np.asarray(q0, dtype=float)
    c = np.asarray(correction(q), dtype=float)
    s = solve(robot, p - c, R, q, tolerance_m, tolerance_rad)
    for _ in range(CORRECTION_STEPS):
        c_new = np.asarray(correction(s.q), dtype=float)
        moved = float(np.linalg.norm(c_new - c))
        c = c_new
        if moved <= 0.1 * tolerance_m:
            break
        s = solve(robot, p - c, R, s.q, tolerance_m, tolerance_rad)
    pq = kinematics.forward(robot, s.q)[1] + np.asarray(correction(s.q), dtype=float)
    dp = float(np.linalg.norm(pq - p))
    return Solution(s.q, dp <= tolerance_m and s.orientation_rad <= tolerance_rad, dp, s.orientation_rad, s.at_limit)


def _angle(A: Array, B: Array) -> float:
    """The angle (rad) of the rotation between A and B (3, 3)."""
    return float(np.linalg.norm(so3.log(A @ B.T)))


RESTARTS = 8  # random starts of the nominal inverse kinematics when the seeds do not reach a target


def nominal_solution(nom: ZRPRobot, p: Array, R: Array | None, start: Array, first: Array, row: int, tol: dict) -> Solution:
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


def why(robot: ZRPRobot, p: Array, s: Solution, pose: bool) -> str:
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
