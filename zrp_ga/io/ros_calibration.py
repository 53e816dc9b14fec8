"""Calibration files that ROS packages read: Universal Robots' ``default_kinematics.yaml``.

Which ROS packages read a calibration file (read in their sources):

- **ur_description** (Universal Robots' ROS 2 description, Universal_Robots_ROS2_Description;
  the ROS 1 ur_description of universal_robot ships files of the same form): ``ur.urdf.xacro``
  takes the file as ``kinematics_params:=FILE`` (``ros2 launch ur_robot_driver
  ur_control.launch.py ... kinematics_params_file:=FILE``). Its ``read_model_data`` macro
  (``urdf/inc/ur_common.xacro``) loads it with ``xacro.load_yaml`` and ``ur_macro.xacro`` writes
  each arm joint as ``<origin xyz="${X_x} ${X_y} ${X_z}" rpy="${X_roll} ${X_pitch} ${X_yaw}"/>``
  with ``<axis xyz="0 0 1"/>``, X = ``shoulder`` (shoulder_pan_joint, parent
  ``base_link_inertia``), ``upper_arm``, ``forearm``, ``wrist_1``, ``wrist_2``, ``wrist_3``
  (wrist_3_joint, child ``wrist_3_link``); ``base_link_inertia`` is ``base_link`` turned by pi
  about z (the controller's base frame; ``base_link`` is REP-103's), and ``tool0`` is
  ``wrist_3_link``'s frame (its two fixed joints ``0 -pi/2 -pi/2`` and ``pi/2 0 pi/2`` compose
  to the identity). The key ``hash`` is read too; ur_robot_driver compares it with the
  controller's own calibration and warns when they differ, as they do for a calibration of
  one's own: zrp_ga writes ``calib_zrp_ga_`` and a digest of the numbers.
- The description packages of other arms (ROS-Industrial's ABB, FANUC, KUKA and Motoman support
  packages, KUKA's LBR iiwa, Franka) read no calibration file: their URDF is the model, so the
  calibrated URDF (the package's own with the joint origins changed,
  :mod:`zrp_ga.io.urdf`) goes in its place.

:func:`ur_kinematics` places each joint's frame on the calibrated axis (z along it) as the
standard DH table in the nominal's conventions does (:func:`zrp_ga.model.dh.to_dh` with
``like``: frame i-1 of the table times ``Rz(theta_i) Tz(d_i)``, which for UR's own DH values
is exactly the frame ur_description puts ``X_link`` in), and writes each joint's pose in the
previous one's, rpy nearest the nominal's (:func:`zrp_ga.io.urdf.rpy_near`). What the file
cannot hold, the calibrated hand's pose in ``tool0`` (the calibrated end point off the flange),
is returned and written in the file's header: it is a TCP (tool) offset.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from zrp_ga.io.urdf import rpy_near
from zrp_ga.model.dh import DHTable, onto_axis, to_dh
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
UR_SECTIONS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")  # the file's keys, joint by joint
KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
WORLDS = ("base", "base_link")  # the robot's world frame is the controller's base, or ROS's base_link


def is_ur(robot: ZRPRobot) -> bool:
    """Whether the arm is a Universal Robots arm as ur_description names its joints: six
    revolute joints named ``shoulder_pan_joint`` .. ``wrist_3_joint`` (one prefix allowed).

    >>> from zrp_ga.io import presets
    >>> is_ur(presets.get("ur10")), is_ur(presets.get("puma560"))
    (True, False)
    """
    names = robot.joint_names or ()
    if robot.joint_types != "RRRRRR" or len(names) != 6 or not names[0].endswith(UR_JOINTS[0]):
        return False
    prefix = names[0][: -len(UR_JOINTS[0])]
    return tuple(names) == tuple(prefix + j for j in UR_JOINTS)


class URKinematics(NamedTuple):
    """The file's numbers and what it leaves out.

    ``kinematics``: section -> {x, y, z (m), roll, pitch, yaw (rad)}; ``tcp``: (4, 4) the
    calibrated hand in ``tool0`` (identity when the hand is on the flange; ``tool0`` is the hand
    turned and moved onto axis 6 the least, so that the offset is the smallest the file allows); ``joints``: (6, 4, 4)
    each joint's origin transform (what ur_description's xacro puts into the URDF)."""

    kinematics: dict[str, dict[str, float]]
    tcp: Array
    joints: Array


def ur_kinematics(robot: ZRPRobot, like: DHTable | None = None, world: str = "base",
                  table: DHTable | None = None) -> URKinematics:  # fmt: skip
    """The default_kinematics.yaml numbers of a UR arm (module docstring).

    ``like``: the nominal standard DH table (default: the table ``robot.source`` holds, if a
    standard DH one, else the arm's own :func:`zrp_ga.model.dh.to_dh` table); ``world``: the
    robot's world frame is UR's ``base`` (the controller's base: z up along axis 1, x as in UR's
    DH tables; the presets' and UR's DH tables) or ROS's ``base_link`` (REP-103: ``base``
    turned by pi about z; an arm read from ur_description's URDF from ``base_link``); ``table``:
    ``to_dh(robot, "dh", like=like)``'s table if already computed.

    >>> from zrp_ga.io import presets
    >>> k = ur_kinematics(presets.get("ur10")).kinematics
    >>> k["shoulder"]["z"], k["forearm"]["x"], round(k["upper_arm"]["roll"], 9)
    (0.1273, -0.612, 1.570796327)
    """
    if world not in WORLDS:
        raise ValueError(f"world: {world!r}, expected one of {', '.join(WORLDS)}")
    if like is None and isinstance(robot.source, DHTable) and robot.source.convention == "dh":
        like = robot.source
    table = to_dh(robot, "dh", samples=1, like=like)[0] if table is None else table
    start = np.diag([-1.0, -1.0, 1.0, 1.0]) if world == "base_link" else np.eye(4)  # base_link_inertia in the world
    frames, nominal = _link_frames(table, start), None if like is None else _link_frames(like, start)
    hand = np.linalg.inv(start)
    hand[:3, :3], hand[:3, 3] = hand[:3, :3] @ robot.R_h0, hand[:3, :3] @ robot.b0.sum(axis=0) + hand[:3, 3]
    # wrist_3_link (= tool0): the hand turned and moved onto axis 6 the least, whatever the table
    frames[-1] = onto_axis(hand, frames[-1][:3, 3], frames[-1][:3, 2])
    joints = np.array([np.linalg.inv(frames[i]) @ frames[i + 1] for i in range(6)])
    kinematics = {}
    for i, section in enumerate(UR_SECTIONS):
        near = None if nominal is None else rpy_near((np.linalg.inv(nominal[i]) @ nominal[i + 1])[:3, :3])
        numbers = [*joints[i][:3, 3], *rpy_near(joints[i][:3, :3], near)]
        kinematics[section] = {k: float(v) + 0.0 for k, v in zip(KEYS, numbers)}
    return URKinematics(kinematics, np.asarray(np.linalg.inv(frames[-1]) @ hand, dtype=np.float64), joints)


def _link_frames(table: DHTable, start: Array) -> list[Array]:
    """base_link_inertia (``start``, world) and the frames ur_description gives ``X_link`` at
    q = 0: the table's frame i-1 times ``Rz(theta_i) Tz(d_i)`` (z on axis i, origin on it), in
    ``start``'s frame."""
    out, T = [np.eye(4)], np.linalg.inv(start) @ table.base
    for i in range(table.n):
        d, theta = table.d[i], table.theta[i]
        c, s = np.cos(theta), np.sin(theta)
        turn = np.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, d], [0.0, 0.0, 0.0, 1.0]])
        out.append(T @ turn)
        T = T @ table.link(i)
    return out


def ur_kinematics_text(k: URKinematics, name: str = "robot", comment: str = "") -> str:
    """The text of a default_kinematics.yaml (ur_description's form: ``kinematics:`` with one
    block per section and ``hash``), ``comment`` lines and the TCP offset in its header; floats
    written in full (``repr``), as ``yaml.safe_load`` reads them back."""
    numbers = [v for section in UR_SECTIONS for v in k.kinematics[section].values()]
    digest = int(hashlib.sha256(np.array(numbers).tobytes()).hexdigest()[:16], 16)
    tcp_mm = k.tcp[:3, 3] * 1e3
    tcp_deg = np.degrees(rpy_near(k.tcp[:3, :3], np.zeros(3)))
    lines = [f"# Universal Robots kinematics (ur_description's default_kinematics.yaml form) of {name}, written by zrp_ga.",
             "# ROS 2: ros2 launch ur_robot_driver ur_control.launch.py ... kinematics_params_file:=THIS_FILE",
             "# (xacro ur.urdf.xacro kinematics_params:=THIS_FILE). Lengths m, angles rad; frames: base_link_inertia",
             "# (the controller's base) .. wrist_3_link (= tool0). The hash is zrp_ga's, not the controller's.",
             f"# The calibrated hand in tool0 (a TCP offset, not in this file): xyz {' '.join(f'{v:.4f}' for v in tcp_mm)} mm, "
             f"rpy {' '.join(f'{v:.4f}' for v in tcp_deg)} deg."]  # fmt: skip
    lines += [f"# {line}" if line else "#" for line in comment.splitlines()]
    lines.append("kinematics:")
    for section in UR_SECTIONS:
        lines.append(f"  {section}:")
        lines += [f"    {key}: {value!r}" for key, value in k.kinematics[section].items()]
    lines.append(f"  hash: calib_zrp_ga_{digest}")
    return "\n".join(lines) + "\n"


def write_ur_kinematics(robot: ZRPRobot, path: str | Path, like: DHTable | None = None, world: str = "base",
                        comment: str = "", table: DHTable | None = None) -> URKinematics:  # fmt: skip
    """Write the arm's default_kinematics.yaml to ``path`` (:func:`ur_kinematics`,
    :func:`ur_kinematics_text`); returns the numbers."""
    k = ur_kinematics(robot, like, world, table)
    Path(path).write_text(ur_kinematics_text(k, robot.name, comment))
    return k
