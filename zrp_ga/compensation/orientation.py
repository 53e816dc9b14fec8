"""Orientation conventions of robot programs, and the names their columns carry.

A controller writes a Cartesian target's orientation in its own convention and under its own
names; a program is read and written under the same ones, so that a corrected table pastes back:

| convention | columns | whose |
| --- | --- | --- |
| ``ZYX`` (intrinsic z-y'-x'') | ``A, B, C`` | KUKA (A about z, B about the new y, C about the newest x) |
| ``xyz`` (extrinsic, fixed axes) | ``W, P, R`` | Fanuc (W about x, P about y, R about z, fixed axes) |
| ``rotvec`` (axis times angle) | ``rx, ry, rz`` | Universal Robots |
| ``quaternion`` (w, x, y, z) | ``q1, q2, q3, q4`` | ABB (``q1`` the scalar part) |
| any other Euler sequence, e.g. ``XYZ`` | ``X1, Y2, Z3`` (the axis and its place) | Staubli's Rx, Ry, Rz are ``XYZ`` |

Euler sequences are scipy's (:meth:`scipy.spatial.transform.Rotation.from_euler`: upper case
intrinsic, lower case extrinsic). Columns named ``rx, ry, rz`` are read in any stated
convention (what many programs call them); ``A, B, C`` and ``W, P, R`` name their convention
themselves. Angles carry the program's angle unit; a quaternion has none.

>>> columns("ZYX"), columns("quaternion"), columns("XYZ")
(('A', 'B', 'C'), ('q1', 'q2', 'q3', 'q4'), ('X1', 'Y2', 'Z3'))
>>> R = to_matrices(np.array([[1.0, 0.0, 0.0, 0.0]]), "quaternion")
>>> bool(np.allclose(R[0], np.eye(3)))
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from zrp_ga.core.checks import ROTVEC, check_convention

Array = NDArray[np.float64]
QUATERNION = "quaternion"
NAMED = {"ZYX": ("A", "B", "C"), "xyz": ("W", "P", "R"), ROTVEC: ("rx", "ry", "rz"), QUATERNION: ("q1", "q2", "q3", "q4")}
WHOSE = {"ZYX": "KUKA's A, B, C", "xyz": "Fanuc's W, P, R", ROTVEC: "Universal Robots' rotation vector rx, ry, rz",
         QUATERNION: "ABB's quaternion q1..q4 (w, x, y, z)"}  # fmt: skip
GENERIC = ("rx", "ry", "rz")  # read in any stated convention of three angles
UNIT_QUATERNION_TOL = 1e-3  # a quaternion whose norm is farther from 1 is refused


def check(convention: str | None, what: str) -> None:
    """ValueError naming ``what`` unless ``convention`` is None, ``quaternion``, ``rotvec`` or
    an Euler sequence."""
    if convention == QUATERNION:
        return
    try:
        check_convention(convention, what)
    except ValueError as exc:
        raise ValueError(f"{exc}, nor {QUATERNION}") from None


def columns(convention: str) -> tuple[str, ...]:
    """The column names of ``convention`` (module docstring)."""
    if convention in NAMED:
        return NAMED[convention]
    return tuple(f"{axis}{k + 1}" for k, axis in enumerate(convention))


def implied(names: set[str]) -> str | None:
    """The convention that column names state by themselves (``A, B, C``: ZYX; ``W, P, R``:
    xyz), or None."""
    for convention in ("ZYX", "xyz"):
        if set(NAMED[convention]) <= names:
            return convention
    return None


def is_angle(convention: str) -> bool:
    """Whether the convention's numbers are angles (a quaternion's are not)."""
    return convention != QUATERNION


def to_matrices(values: Array, convention: str) -> Array:
    """Rotation matrices (M, 3, 3) of ``values`` (M, 3) rad, or (M, 4) unit quaternions
    (w, x, y, z)."""
    if convention == QUATERNION:
        return Rotation.from_quat(values[:, [1, 2, 3, 0]]).as_matrix()
    if convention == ROTVEC:
        return Rotation.from_rotvec(values).as_matrix()
    return Rotation.from_euler(convention, values).as_matrix()


def from_matrices(R: Array, convention: str, near: Array | None = None) -> Array:
    """``values`` (M, 3) rad or (M, 4) quaternions (w >= 0) of rotations ``R`` (M, 3, 3); with
    ``near`` (M, 3) rad (the program's own angles), each angle is the one of its turns (+-2 pi)
    nearest the program's: 180 deg stays 180, not -180."""
    rot = Rotation.from_matrix(R)
    if convention == QUATERNION:
        x, y, z, w = rot.as_quat(canonical=True).T
        return np.column_stack([w, x, y, z])
    angles = rot.as_rotvec() if convention == ROTVEC else rot.as_euler(convention)
    if near is None or convention == ROTVEC:
        return angles
    return near + np.angle(np.exp(1j * (angles - near)))


def quaternion_norms(values: Array) -> Array:
    """How far each quaternion's norm is from 1 (M,)."""
    return np.abs(np.linalg.norm(values, axis=1) - 1.0)
