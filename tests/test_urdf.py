"""URDF in and out: written URDFs against the independent forward kinematics of
tests/urdf_reference.py, hand-written URDFs against transforms computed here with scipy, DH
chains against tests/dh_reference.py, and calibrated URDFs diffed against the user's input."""

from pathlib import Path

import numpy as np
import pytest
from dh_reference import dh_fk
from lxml import etree
from scipy.spatial.transform import Rotation
from urdf_reference import urdf_fk

from zrp_ga import robots
from zrp_ga.io.robot_files import read_robot, to_urdf, write_robot_files
from zrp_ga.model import kinematics
from zrp_ga.model.robot import ZRPRobot

KR6 = Path(__file__).parent / "data" / "kr6_meshes.urdf"  # meshes, inertias, flange, tool0, a gripper
KR6_JOINTS = [f"joint_a{i}" for i in range(1, 7)]


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


def test_independent_forward_kinematics_of_the_written_urdf_equal_forward(tmp_path, rng):
    for robot in arms(rng):
        base = pose([0.1, -0.2, 0.3], Rotation.from_euler("xyz", [0.2, -0.4, 1.0]))
        tool = pose([0.0, 0.01, 0.12], Rotation.from_euler("xyz", [np.pi / 2, 0.0, 0.3]))
        path = tmp_path / f"{robot.name}.urdf"
        to_urdf(robot, path, base=base, tool=tool)
        names = robot.joint_names or [f"joint_{i + 1}" for i in range(robot.n)]
        Q = random_q(robot, rng, 10)
        R, p = kinematics.forward(robot, Q)
        for q, Rm, pm in zip(Q, R, p):
            hand = urdf_fk(path, dict(zip(names, q)), "base_link", "hand")
            np.testing.assert_allclose(hand[:3, :3], Rm, atol=1e-12)
            np.testing.assert_allclose(hand[:3, 3], pm, atol=1e-12)
            np.testing.assert_allclose(urdf_fk(path, dict(zip(names, q)), "world", "tool"), base @ hand @ tool, atol=1e-12)


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


# --- a URDF with meshes in, the same URDF calibrated out ---------------------------------------------
def calibrated(robot, rng, scale=1e-3):
    """The arm with its axes, body vectors and hand turned and moved by about ``scale`` (rad, m);
    ``replace`` keeps the URDF it was read from."""
    turn = Rotation.from_rotvec(rng.normal(scale=scale, size=3)).as_matrix()
    return robot.replace(u0=robot.u0 + rng.normal(scale=scale, size=robot.u0.shape),
                         b0=robot.b0 + rng.normal(scale=scale, size=robot.b0.shape), R_h0=turn @ robot.R_h0, normalize=True)  # fmt: skip


def assert_urdf_is_the_arm(path, robot, rng, frm, to, joints, before=None, after=None):
    """FK of the URDF at ``path`` (tests/urdf_reference.py) from link ``frm`` to ``to`` is
    ``before @ robot(q) @ after`` (default identities) to 1e-12 m and rad."""
    before, after = (np.eye(4) if T is None else T for T in (before, after))
    Q = random_q(robot, rng, 10)
    R, p = kinematics.forward(robot, Q)
    for q, Rm, pm in zip(Q, R, p):
        np.testing.assert_allclose(urdf_fk(path, dict(zip(joints, q)), frm, to), before @ pose(pm, Rotation.from_matrix(Rm)) @ after, atol=1e-12)


def differences(a, b):
    """(parent's name, tag, attribute) of every attribute that differs between two XML files
    with the same elements and comments in the same order (asserted)."""
    A, B = (list(etree.parse(str(path)).getroot().getroottree().iter()) for path in (a, b))
    assert [(x.tag, (x.text or "").strip()) for x in A] == [(y.tag, (y.text or "").strip()) for y in B]
    out = []
    for x, y in zip(A, B):
        for key in sorted(set(x.attrib) | set(y.attrib)):
            if x.get(key) != y.get(key):
                out.append((x.getparent().get("name"), x.tag, key))
    return out


def test_a_urdf_with_meshes_reads_without_them(rng):
    robot = read_robot(KR6, tip_link="tool0")  # the gripper's fingers are leaves too
    assert robot.joint_names == tuple(KR6_JOINTS) and robot.joint_types == "RRRRRR"
    np.testing.assert_allclose(robot.limits[2], [-2.094, 2.722])
    assert_urdf_is_the_arm(KR6, robot, rng, "world", "tool0", KR6_JOINTS)
    assert read_robot(KR6, base_link="base_link", tip_link="link_6").n == 6


def test_the_calibrated_urdf_is_the_input_with_only_the_chains_origins_changed(tmp_path, rng):
    arm = calibrated(read_robot(KR6, tip_link="tool0"), rng)
    paths = write_robot_files(arm, tmp_path)
    changed = differences(KR6, paths["urdf"])
    # the arm's joints and the hand joint (the first fixed joint after the last arm joint) move;
    # meshes, inertias, limits (velocity 2.5 too), the flange-tool0 joint, the gripper, comments stay
    assert sorted({(name, tag) for name, tag, _ in changed}) == [(j, "origin") for j in ["joint_a1", "joint_a2", "joint_a3", "joint_a4", "joint_a5", "joint_a6", "joint_a6-flange"]]  # fmt: skip
    assert 'velocity="2.5"' in paths["urdf"].read_text() and "package://kuka_kr6_support" in paths["urdf"].read_text()
    assert_urdf_is_the_arm(paths["urdf"], arm, rng, "world", "tool0", KR6_JOINTS)
    back = read_robot(paths["urdf"], tip_link="tool0")  # the same axes and hand (points on the axes may slide)
    for field in ("u0", "R_h0"):
        np.testing.assert_allclose(getattr(back, field), getattr(arm, field), atol=1e-12, rtol=0, err_msg=field)
    # the nominal arm gives the input back, byte for byte, also with the root's start tag over two lines
    assert to_urdf(read_robot(KR6, tip_link="tool0")) == KR6.read_text()
    split = tmp_path / "split.urdf"
    split.write_text(KR6.read_text().replace('<robot name="kr6_meshes" ', '<robot\n    name="kr6_meshes"\n    '))
    assert to_urdf(read_robot(split, tip_link="tool0")) == split.read_text()


def test_base_and_tool_go_into_the_users_urdf_as_new_fixed_joints(tmp_path, rng):
    arm = calibrated(read_robot(KR6, base_link="base_link", tip_link="tool0"), rng)
    base = pose([1.0, 2.0, 0.5], Rotation.from_euler("xyz", [0.1, -0.2, 2.0]))
    tool = pose([0.0, 0.02, 0.15], Rotation.from_euler("xyz", [0.0, 0.3, 0.0]))
    out = tmp_path / "with_frames.urdf"
    to_urdf(arm, out, base=base, tool=tool)
    # base_link has a parent (world_joint): the base stays in the frames file; the tool is added
    assert_urdf_is_the_arm(out, arm, rng, "base_link", "tool", KR6_JOINTS, after=tool)
    arm = calibrated(read_robot(KR6, tip_link="tool0"), rng)  # from the root: world_2 is added above it
    to_urdf(arm, out, base=base, tool=tool)
    assert_urdf_is_the_arm(out, arm, rng, "world_2", "tool", KR6_JOINTS, before=base, after=tool)
    assert "<!-- added by zrp_ga: the calibrated tool frame in the hand frame -->" in out.read_text()


def test_calibrated_hand_written_chain_with_prismatic_and_fixed_joints_between(tmp_path, rng):
    joints = [(name, kind, xyz, rpy, axis[0] if axis else None) for name, kind, xyz, rpy, *axis in HAND_WRITTEN]
    path = tmp_path / "arm.urdf"
    path.write_text(urdf_text(joints))
    arm = calibrated(read_robot(path), rng, scale=1e-2)
    out = tmp_path / "calibrated.urdf"
    to_urdf(arm, out)
    assert {(name, tag) for name, tag, _ in differences(path, out)} <= {(j, "origin") for j in ("turn", "slide", "spin", "flange")}
    assert_urdf_is_the_arm(out, arm, rng, "l0", "l6", ["turn", "slide", "spin"])


def test_a_chain_ending_at_a_movable_joint_gets_the_hand_in_a_new_fixed_joint(tmp_path, rng):
    joints = [(name, kind, xyz, rpy, axis[0] if axis else None) for name, kind, xyz, rpy, *axis in HAND_WRITTEN[:-1]]
    path = tmp_path / "arm.urdf"
    path.write_text(urdf_text(joints))
    arm = calibrated(read_robot(path), rng, scale=1e-2)
    out = tmp_path / "calibrated.urdf"
    to_urdf(arm, out)
    assert ("spin", "axis", "xyz") in differences_but_added(path, out)
    assert_urdf_is_the_arm(out, arm, rng, "l0", "calibrated_hand", ["turn", "slide", "spin"])


def differences_but_added(a, b):
    """Like :func:`differences`, after removing from b what zrp_ga added (after its comment)."""
    tree = etree.parse(str(b))
    root = tree.getroot()
    marks = [k for k, e in enumerate(root) if isinstance(e, etree._Comment) and "added by zrp_ga" in e.text]
    for e in list(root)[marks[0]:] if marks else []:
        root.remove(e)
    list(root)[-1].tail = "\n"
    trimmed = Path(str(b) + ".trimmed")
    tree.write(str(trimmed))
    return differences(a, trimmed)


def test_an_arm_whose_joints_are_no_longer_the_files_gets_a_new_urdf(tmp_path, caplog):
    robot = read_robot(KR6, tip_link="tool0").replace(joint_names=[f"j{i}" for i in range(6)])
    text = to_urdf(robot)
    assert "the arm's joints are no longer the file's chain; writing a new URDF instead" in caplog.text
    assert '<link name="link_1" />' in text and "kuka" not in text


# --- angle triples nearest the nominal ones --------------------------------------------------------
OLD_UR = [  # a ROS 1-style UR10 description (its own numbers): two joints' frames pitched by 90 degrees
    ("shoulder_pan_joint", "revolute", [0, 0, 0.1273], [0, 0, 0], "0 0 1"),
    ("shoulder_lift_joint", "revolute", [0, 0.220941, 0], [0.0, 1.570796325, 0.0], "0 1 0"),
    ("elbow_joint", "revolute", [0, -0.1719, 0.612], [0, 0, 0], "0 1 0"),
    ("wrist_1_joint", "revolute", [0, 0, 0.5723], [0.0, 1.570796325, 0.0], "0 1 0"),
    ("wrist_2_joint", "revolute", [0, 0.1149, 0], [np.pi, 0, 0], "0 0 -1"),
    ("wrist_3_joint", "revolute", [0, 0, -0.1157], [0, 0, 0], "0 1 0"),
    ("ee_fixed_joint", "fixed", [0, 0.0922, 0], [0.0, 0.0, 1.570796325], None),
]


def origin_numbers(path, joint, attr):
    element = etree.parse(str(path)).getroot().find(f"joint[@name='{joint}']")
    return element.find("origin").get("rpy") if attr == "rpy" else element.find("axis").get("xyz")


def test_a_small_correction_reads_small_in_every_origins_rpy(tmp_path, rng):
    """Roll pi stays next to pi; where the nominal pitch is 90 degrees (no triple is near: roll
    and yaw would take half a radian each for a 1 mrad turn) the rpy text stays and the axis
    carries the tilt; the URDF is the arm to round-off (tests/urdf_reference.py, yourdfpy)."""
    path = tmp_path / "old_ur.urdf"
    path.write_text(urdf_text(OLD_UR))
    nominal = read_robot(path)
    arm = calibrated(nominal, rng, scale=1e-3)
    out = tmp_path / "calibrated.urdf"
    to_urdf(arm, out)
    names = [j[0] for j in OLD_UR[:-1]]
    assert_urdf_is_the_arm(out, arm, rng, "l0", "l7", names)
    for name, _, _, rpy, axis in OLD_UR:
        written = np.array(origin_numbers(out, name, "rpy").split(), dtype=float)
        if rpy[1] == 1.570796325:  # kept as written; the axis tilts by about the error
            assert origin_numbers(out, name, "rpy") == " ".join(repr(float(v)) for v in rpy)
            tilt = np.array(origin_numbers(out, name, "axis").split(), dtype=float) - np.array(axis.split(), dtype=float)
            assert 1e-5 < np.abs(tilt).max() < 1e-2
        else:
            assert np.abs(written - rpy).max() < 1e-2, (name, written)
            assert axis is None or origin_numbers(out, name, "axis") == axis
    yourdfpy = pytest.importorskip("yourdfpy")
    urdf = yourdfpy.URDF.load(str(out), build_scene_graph=True, load_meshes=False)
    for q in random_q(arm, rng, 5):
        urdf.update_cfg(dict(zip(names, q)))
        R, p = kinematics.forward(arm, q)
        np.testing.assert_allclose(urdf.get_transform("l7", "l0"), pose(p, Rotation.from_matrix(R)), atol=1e-12)


@pytest.mark.parametrize("pitch_deg", [0.0, 45.0, -80.0, 179.0])
def test_rpy_near_is_the_nominal_triple_plus_the_small_turn(pitch_deg, rng):
    from zrp_ga.io.urdf import reads_small, rpy_near

    for _ in range(20):
        nominal = np.array([rng.uniform(-np.pi, np.pi), np.radians(pitch_deg), rng.choice([np.pi, -np.pi, 0.3])])
        turn = rng.normal(scale=1e-3, size=3)
        R = Rotation.from_euler("xyz", nominal).as_matrix() @ Rotation.from_rotvec(turn).as_matrix()
        r = rpy_near(R, nominal)
        np.testing.assert_allclose(Rotation.from_euler("xyz", r).as_matrix(), R, atol=1e-14)
        assert np.abs(r - nominal).max() < 5 * np.linalg.norm(turn) / max(np.cos(nominal[1]) ** 2, 0.03)
        assert reads_small(R, nominal)
    R = Rotation.from_euler("xyz", [0, 1.570796325, 0]).as_matrix() @ Rotation.from_rotvec([0, 0, 1e-3]).as_matrix()
    assert not reads_small(R, [0, 1.570796325, 0])  # the case: roll and yaw of about half a radian
