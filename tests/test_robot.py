import numpy as np
import pytest

from zrp_ga import robots
from zrp_ga.model.robot import ZRPRobot

GOOD = dict(u0=[[0, 0, 1], [0, 1, 0]], b0=[[0, 0, 0.3], [0.2, 0, 0], [0.1, 0, 0]])


def test_yaml_round_trip_is_exact(tmp_path):
    for name in robots.names():
        robot = robots.get(name)
        path = tmp_path / f"{name}.yaml"
        robot.to_yaml(path)
        back = ZRPRobot.from_yaml(path)
        assert back.name == name and back.joint_types == robot.joint_types
        for field in ("u0", "b0", "R_h0"):
            assert np.array_equal(getattr(back, field), getattr(robot, field)), field


def test_arrays_are_read_only():
    robot = robots.get("puma560")
    with pytest.raises(ValueError):
        robot.b0[0, 0] = 1.0


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(u0=[[0, 0, 1]]), r"b0: expected shape \(2, 3\), got \(3, 3\)"),
        (dict(u0=[[0, 0, 1, 0], [0, 1, 0, 0]]), r"u0: expected shape \(2, 3\), got \(2, 4\)"),
        (dict(u0=[[0, 0, 0], [0, 1, 0]]), "u0: axis of joint 1 has length zero"),
        (dict(u0=[[0, 0, 1.1], [0, 1, 0]]), "u0: axis of joint 1 has length 1.1, not 1"),
        (dict(b0=[[0, 0, 0.3], [0.2, np.inf, 0], [0.1, 0, 0]]), r"b0: NaN or inf at index \(1, 1\)"),
        (dict(u0=[[0, 0, np.nan], [0, 1, 0]]), r"u0: NaN or inf at index \(0, 2\)"),
        (dict(joint_types="RX"), "joint_types: joint 2 is 'X'"),
        (dict(joint_types="R"), "joint_types: expected a string of 2 letters"),
        (dict(R_h0=np.diag([1.0, 1.0, -1.0])), "R_h0: not a rotation matrix"),
        (dict(b0="abc"), "b0: not an array of numbers"),
    ],
)
def test_bad_robot_is_refused_with_the_field_named(change, message):
    with pytest.raises(ValueError, match=message):
        ZRPRobot(**{**GOOD, **change})


def test_non_unit_axis_normalised_only_when_asked():
    robot = ZRPRobot(**{**GOOD, "u0": [[0, 0, 2.0], [0, 3.0, 0]]}, normalize=True)
    np.testing.assert_allclose(robot.u0, [[0, 0, 1], [0, 1, 0]])


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ValueError, match="unknown robot 'puma'; known robots: puma560, stanford, ur10"):
        robots.get("puma")


@pytest.mark.parametrize(
    "text, message",
    [
        ("u0: [[0, 0, 1]\nb0: ]", "malformed YAML"),
        ("- 1\n- 2\n", "expected a mapping"),
        ("u0: [[0, 0, 1]]\n", "missing key"),
        ("u0: [[0, 0, 1]]\nb0: [[0, 0, 0], [1, 0, 0]]\nbody: 1\n", "unknown key.*body"),
        ("u0: [[0, 0, 1]]\nb0: [[0, 0, 0], [1, 0]]\n", "b0: "),
    ],
)
def test_malformed_yaml_names_file_and_problem(tmp_path, text, message):
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        ZRPRobot.from_yaml(path)
    assert str(path) in str(info.value)


NAMED = dict(GOOD, joint_types="RP", joint_names=["shoulder", "slide"], limits=[[-2.0, 2.5], [0.1, 0.9]])


def test_names_and_limits_survive_yaml_replace_transform_and_tool(tmp_path):
    robot = ZRPRobot(**NAMED)
    path = tmp_path / "arm.yaml"
    robot.to_yaml(path)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for other in (
        ZRPRobot.from_yaml(path),
        robot.replace(name="other"),
        robot.transformed(R, [1.0, 2.0, 3.0]),
        robot.with_tool([0.0, 0.0, 0.1]),
    ):
        assert other.joint_names == ("shoulder", "slide")
        assert np.array_equal(other.limits, [[-2.0, 2.5], [0.1, 0.9]])


def test_default_limits_follow_the_joint_types():
    robot = ZRPRobot(**{**GOOD, "joint_types": "RP"})
    assert robot.limits is None and robot.joint_names is None
    np.testing.assert_array_equal(robot.joint_limits, [[-np.pi, np.pi], [0.0, 0.5]])
    assert "limits" not in robot.to_dict() and "joint_names" not in robot.to_dict()


def test_limits_are_read_only():
    with pytest.raises(ValueError):
        ZRPRobot(**NAMED).limits[0, 0] = 0.0


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(limits=[[-1.0, 1.0]]), r"limits: expected shape \(2, 2\), got \(1, 2\)"),
        (dict(limits=[[1.0, -1.0], [0.0, 0.5]]), "limits: joint 1 has lower 1 >= upper -1"),
        (dict(limits=[[0.0, 0.0], [0.0, 0.5]]), "limits: joint 1 has lower 0 >= upper 0"),
        (dict(limits=[[-1.0, np.inf], [0.0, 0.5]]), r"limits: NaN or inf at index \(0, 1\)"),
        (dict(joint_names=["a"]), "joint_names: expected a list of 2 names"),
        (dict(joint_names="ab"), "joint_names: expected a list of 2 names"),
        (dict(joint_names=["a", ""]), "joint_names: joint 2 has no name"),
        (dict(joint_names=["a", 3]), "joint_names: joint 2 has no name"),
        (dict(joint_names=["a", "a"]), "joint_names: 'a' names joints 1 and 2"),
    ],
)
def test_bad_names_or_limits_are_refused(change, message):
    with pytest.raises(ValueError, match=message):
        ZRPRobot(**{**GOOD, **change})
