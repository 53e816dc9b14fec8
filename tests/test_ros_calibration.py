"""Universal Robots' default_kinematics.yaml, read back as ur_description reads it
(tests/ur_description_reference.py: the xacro package and yourdfpy)."""

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from zrp_ga import robots
from zrp_ga.io import ros_calibration
from zrp_ga.io.robot_files import read_robot, to_urdf, write_robot_files
from zrp_ga.model import kinematics
from zrp_ga.model.robot import ZRPRobot

yourdfpy = pytest.importorskip("yourdfpy")
pytest.importorskip("xacro")
from ur_description_reference import ur_description_urdf  # noqa: E402 (after the skips)


def pose(R, p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def calibrated(robot: ZRPRobot, rng, scale=1e-3) -> ZRPRobot:
    """The arm with every axis tilted, every body vector moved (about ``scale``) and the hand turned."""
    turn = Rotation.from_rotvec(rng.normal(scale=scale, size=3)).as_matrix()
    return robot.replace(u0=robot.u0 + rng.normal(scale=scale, size=robot.u0.shape),
                         b0=robot.b0 + rng.normal(scale=scale, size=robot.b0.shape), R_h0=turn @ robot.R_h0, normalize=True)  # fmt: skip


def test_the_ur10_presets_file_is_ur_descriptions_own(tmp_path):
    """ur_description's config/ur10/default_kinematics.yaml (its numbers typed in here): the
    preset's file has the same joint origins (UR's rounded pi/2 to 1e-9)."""
    published = {"shoulder": [0, 0, 0.1273, 0, 0, 0], "upper_arm": [0, 0, 0, 1.570796327, 0, 0],
                 "forearm": [-0.612, 0, 0, 0, 0, 0], "wrist_1": [-0.5723, 0, 0.163941, 0, 0, 0],
                 "wrist_2": [0, -0.1157, -2.373046667922381e-11, 1.570796327, 0, 0],
                 "wrist_3": [0, 0.0922, -1.891053610911353e-11, 1.570796326589793, np.pi, np.pi]}  # fmt: skip
    paths = write_robot_files(robots.get("ur10"), tmp_path)
    ours = yaml.safe_load(paths["ur_kinematics"].read_text())["kinematics"]
    assert ours["hash"].startswith("calib_zrp_ga_")
    for section, numbers in published.items():
        mine = [ours[section][k] for k in ros_calibration.KEYS]
        np.testing.assert_allclose(mine[:3], numbers[:3], atol=1e-9, err_msg=section)
        R = Rotation.from_euler("xyz", mine[3:]).as_matrix()
        np.testing.assert_allclose(R, Rotation.from_euler("xyz", numbers[3:]).as_matrix(), atol=1e-9, err_msg=section)


@pytest.mark.parametrize("source", ["dh", "urdf"])
def test_a_calibrated_ur10_read_back_by_ur_descriptions_xacro_has_its_forward_kinematics(tmp_path, rng, source):
    """The file expanded by xacro into ur_description's chain, forward kinematics by yourdfpy:
    ``base_link_inertia`` (the arm's world: UR's DH base; from a URDF, ``base_link``) to
    ``tool0``, times the TCP offset the file's header states, is the calibrated model's hand
    pose, to round-off."""
    nominal, frm = robots.get("ur10"), "base_link_inertia"
    if source == "urdf":  # the arm as read from ur_description's own URDF (from base_link), nominal numbers
        nominal_file = tmp_path / "nominal_kinematics.yaml"
        ros_calibration.write_ur_kinematics(nominal, nominal_file)
        urdf = ur_description_urdf(tmp_path, nominal_file)
        urdf.write_xml_file(str(tmp_path / "ur10.urdf"))
        nominal, frm = read_robot(tmp_path / "ur10.urdf", base_link="base_link", tip_link="tool0"), "base_link"
    arm = calibrated(nominal, rng)
    paths = write_robot_files(arm, tmp_path / "out")
    urdf = ur_description_urdf(tmp_path, paths["ur_kinematics"])
    k = ros_calibration.ur_kinematics(arm, world="base_link" if source == "urdf" else "base")
    q = rng.uniform(-np.pi, np.pi, size=(20, 6))
    R, p = kinematics.forward(arm, q)
    worst = 0.0
    for m in range(len(q)):
        urdf.update_cfg(dict(zip(ros_calibration.UR_JOINTS, q[m])))
        T = urdf.get_transform(frame_to="tool0", frame_from=frm) @ k.tcp
        worst = max(worst, np.abs(T[:3, 3] - p[m]).max(), np.abs(T[:3, :3] - R[m]).max())
    assert worst < 1e-12
    # the TCP offset: the calibrated hand is off the flange by about the errors made (mm, mrad), stated in the header
    assert 1e-5 < np.linalg.norm(k.tcp[:3, 3]) < 1e-2
    assert "The calibrated hand in tool0 (a TCP offset, not in this file): xyz " in paths["ur_kinematics"].read_text()


def test_each_joints_numbers_read_as_the_nominal_ones_plus_a_small_correction(tmp_path, rng):
    arm = calibrated(robots.get("ur10"), rng, scale=1e-4)
    nominal = ros_calibration.ur_kinematics(robots.get("ur10")).kinematics
    ours = ros_calibration.ur_kinematics(arm).kinematics
    for section in ros_calibration.UR_SECTIONS:
        change = np.array([ours[section][k] - nominal[section][k] for k in ros_calibration.KEYS])
        assert np.abs(change).max() < 2e-3, (section, change)


def test_only_ur_arms_get_the_file(tmp_path):
    assert "ur_kinematics" not in write_robot_files(robots.get("puma560"), tmp_path)
    renamed = robots.get("ur10").replace(joint_names=[f"ur_{j}" for j in ros_calibration.UR_JOINTS])
    assert ros_calibration.is_ur(renamed) and not ros_calibration.is_ur(renamed.replace(joint_names=[f"j{i}" for i in range(6)]))


def test_the_urdf_read_back_by_yourdfpy_has_the_models_forward_kinematics(tmp_path, rng):
    """The calibrated URDF (a new one, and the user's own written back) in yourdfpy."""
    arm = calibrated(robots.get("puma560"), rng)
    to_urdf(arm, tmp_path / "new.urdf")
    urdf = yourdfpy.URDF.load(str(tmp_path / "new.urdf"), build_scene_graph=True, load_meshes=False)
    names = [f"joint_{i + 1}" for i in range(6)] if arm.joint_names is None else list(arm.joint_names)
    q = rng.uniform(-2, 2, size=(10, 6))
    R, p = kinematics.forward(arm, q)
    for m in range(len(q)):
        urdf.update_cfg(dict(zip(names, q[m])))
        np.testing.assert_allclose(urdf.get_transform("hand", "base_link"), pose(R[m], p[m]), atol=1e-12)
