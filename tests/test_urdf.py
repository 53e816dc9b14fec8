"""URDF in and out: written URDFs against yourdfpy's forward kinematics, hand-written URDFs
against transforms computed here with scipy, and DH chains against tests/dh_reference.py."""

import numpy as np
import pytest
import yourdfpy
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

from zrp_ga import kinematics, robots
from zrp_ga.robot import ZRPRobot
from zrp_ga.robot_files import read_robot, to_urdf


def random_dh_arm(rng, types):
    """A random standard-DH table with random base and tool (lengths m, angles rad)."""
    n = len(types)
    table = dict(
        a=rng.uniform(-0.5, 0.5, n), alpha=rng.uniform(-np.pi, np.pi, n), d=rng.uniform(-0.5, 0.5, n),
        offset=rng.uniform(-np.pi, np.pi, n), joint_types=types,
    )
    base, tool = (pose(rng.uniform(-1, 1, 3), Rotation.random(random_state=int(rng.integers(1000)))) for _ in "bt")
    return table, base, tool


def pose(xyz, rotation):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation.as_matrix(), xyz
    return T


def arms(rng):
    """The presets and random arms with prismatic joints."""
    out = [robots.get(name) for name in robots.names()]
    for types in ("RPRRPR", "PPR", "RRRRRRR"):
        table, base, tool = random_dh_arm(rng, types)
        names = [f"j{i}" for i in range(len(types))]
        out.append(ZRPRobot.from_dh(**table, base=base, tool=tool, name=f"random_{types}", joint_names=names))
    return out


def random_q(robot, rng, M):
    limits = robot.joint_limits
    return rng.uniform(limits[:, 0], limits[:, 1], size=(M, robot.n))


def test_written_urdf_reads_back_to_the_same_zrp_model(tmp_path, rng):
    for robot in arms(rng):
        path = tmp_path / f"{robot.name}.urdf"
        to_urdf(robot, path)
        back = read_robot(path)
        for field in ("u0", "b0", "R_h0"):
            np.testing.assert_allclose(getattr(back, field), getattr(robot, field), atol=1e-12, rtol=0, err_msg=field)
        assert back.joint_types == robot.joint_types and back.name == robot.name
        assert back.joint_names == (robot.joint_names or tuple(f"joint_{i + 1}" for i in range(robot.n)))
        np.testing.assert_allclose(back.limits, robot.joint_limits, rtol=1e-15)


def test_yourdfpy_forward_kinematics_of_the_written_urdf_equal_forward(tmp_path, rng):
    for robot in arms(rng):
        base = pose([0.1, -0.2, 0.3], Rotation.from_euler("xyz", [0.2, -0.4, 1.0]))
        tool = pose([0.0, 0.01, 0.12], Rotation.from_euler("xyz", [np.pi / 2, 0.0, 0.3]))
        path = tmp_path / f"{robot.name}.urdf"
        to_urdf(robot, path, base=base, tool=tool)
        model = yourdfpy.URDF.load(str(path), load_meshes=False)
        names = [j.name for j in model.actuated_joints]
        Q = random_q(robot, rng, 10)
        R, p = kinematics.forward(robot, Q)
        for q, Rm, pm in zip(Q, R, p):
            model.update_cfg(dict(zip(names, q)))
            hand = model.get_transform("hand", "base_link")
            np.testing.assert_allclose(hand[:3, :3], Rm, atol=1e-12)
            np.testing.assert_allclose(hand[:3, 3], pm, atol=1e-12)
            np.testing.assert_allclose(model.get_transform("tool", "world"), base @ hand @ tool, atol=1e-12)


def test_urdf_of_a_dh_table_reads_as_the_dh_chain(tmp_path, rng):
    """Joint i of this URDF sits on DH frame i-1: origin = the fixed part Rz(theta) Tz(d) Tx(a)
    Rx(alpha) of the previous link, axis z; the fixed end joint carries the last link's."""
    for types in ("RRRRRR", "RRPRRR", "PRPR"):
        table, _, _ = random_dh_arm(rng, types)
        fixed = [dh_fk(dict(table, joint_types="R" * (i + 1)), np.zeros(i + 1)) for i in range(len(types))]
        links = [np.eye(4)] + [np.linalg.inv(fixed[i - 1]) @ fixed[i] if i else fixed[0] for i in range(len(types))]
        xyz_rpy = [(T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_euler("xyz")) for T in links]
        joints = [(f"q{i}", {"R": "revolute", "P": "prismatic"}[t], *xyz_rpy[i], "0 0 1") for i, t in enumerate(types)]
        path = tmp_path / "dh.urdf"
        path.write_text(urdf_text(joints + [("end", "fixed", *xyz_rpy[-1], None)]))
        robot = read_robot(path)
        for q in rng.uniform(-1, 1, size=(10, len(types))):
            R, p = kinematics.forward(robot, q)
            T = dh_fk(table, q)
            np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
            np.testing.assert_allclose(p, T[:3, 3], atol=1e-12)


def urdf_text(joints, extra=""):
    """A serial URDF: links l0 .. lk, joint i from l(i) to l(i+1), given as (name, type, origin
    xyz, origin rpy, axis or None)."""
    parts = ['<?xml version="1.0"?>', '<robot name="hand_written">', '  <link name="l0"/>']
    for i, (name, kind, xyz, rpy, axis) in enumerate(joints):
        xyz, rpy = (" ".join(repr(float(v)) for v in values) for values in (xyz, rpy))
        axis = axis if axis is None or isinstance(axis, str) else " ".join(map(str, axis))
        parts += [
            f'  <link name="l{i + 1}"/>',
            f'  <joint name="{name}" type="{kind}">',
            f'    <parent link="l{i}"/> <child link="l{i + 1}"/>',
            f'    <origin xyz="{xyz}" rpy="{rpy}"/>',
            f'    <axis xyz="{axis}"/>' if axis else "",
            '    <limit lower="-1.5" upper="2.0" effort="1" velocity="1"/>' if kind in ("revolute", "prismatic") else "",
            "  </joint>",
        ]
    return "\n".join(parts + [extra, "</robot>"])


HAND_WRITTEN = [  # name, type, origin xyz, origin rpy, axis
    ("mount", "fixed", [0.0, 0.0, 0.1], [0.0, 0.0, 0.5]),
    ("turn", "revolute", [0.05, 0.0, 0.3], [0.1, -0.2, 0.3], [0.6, 0.0, 0.8]),
    ("bracket", "fixed", [0.0, 0.2, 0.0], [np.pi / 2, 0.0, 0.0]),
    ("slide", "prismatic", [0.1, 0.0, 0.0], [0.0, 0.3, 0.0], [1.0, 1.0, 0.0]),
    ("spin", "continuous", [0.0, 0.0, 0.25], [0.4, 0.5, -0.6], [0.0, -1.0, 0.0]),
    ("flange", "fixed", [0.0, 0.0, 0.08], [0.0, np.pi / 2, 0.0]),
]


def hand_written_fk(q):
    """Tip pose of HAND_WRITTEN: product of origin(xyz, rpy) and the joint motion, via scipy."""
    T, k = np.eye(4), 0
    for name, kind, xyz, rpy, *axis in HAND_WRITTEN:
        T = T @ pose(xyz, Rotation.from_euler("xyz", rpy))
        if kind != "fixed":
            u = np.array(axis[0]) / np.linalg.norm(axis[0])
            motion = pose(u * q[k], Rotation.identity()) if kind == "prismatic" else pose([0, 0, 0], Rotation.from_rotvec(u * q[k]))
            T, k = T @ motion, k + 1
    return T


def test_hand_written_urdf_with_fixed_joints_offsets_and_tilted_axes(tmp_path, rng):
    joints = [(name, kind, xyz, rpy, axis[0] if axis else None) for name, kind, xyz, rpy, *axis in HAND_WRITTEN]
    branch = '<link name="camera"/><joint name="cam" type="fixed"><parent link="l2"/><child link="camera"/></joint>'
    path = tmp_path / "arm.urdf"
    path.write_text(urdf_text(joints, extra=branch))
    robot = read_robot(path, tip_link="l6")
    assert robot.joint_types == "RPR" and robot.joint_names == ("turn", "slide", "spin")
    np.testing.assert_allclose(robot.limits, [[-1.5, 2.0], [-1.5, 2.0], [-np.pi, np.pi]])  # continuous: default
    for q in rng.uniform(-1, 1, size=(10, 3)):
        R, p = kinematics.forward(robot, q)
        T = hand_written_fk(q)
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p, T[:3, 3], atol=1e-12)
    # a sub-chain: from l1 to the branch link
    sub = read_robot(path, base_link="l1", tip_link="camera")
    assert sub.joint_names == ("turn",)


def test_reserved_joint_names_are_refused():
    robot = robots.get("puma560")
    with pytest.raises(ValueError, match="joint names hand_joint: reserved"):
        to_urdf(robot.replace(joint_names=["a", "b", "c", "d", "e", "hand_joint"]))


def test_bad_base_transform_is_refused():
    with pytest.raises(ValueError, match="base: not a rigid transform"):
        to_urdf(robots.get("ur10"), base=np.diag([1.0, 1.0, -1.0, 1.0]))
