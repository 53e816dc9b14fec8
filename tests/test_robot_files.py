"""Robot files: DH table files written here by hand (mm, deg) against tests/dh_reference.py,
round trips DH file -> ZRP -> URDF -> ZRP, write_robot_files, and one-line errors."""

import os
import re

import numpy as np
import pytest
import yaml
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

from zrp_ga import robots
from zrp_ga.io.robot_files import dh_to_yaml, read_dh, read_robot, to_dh, to_urdf, write_robot_files
from zrp_ga.model import kinematics
from zrp_ga.model.robot import ZRPRobot


def random_table(rng, types):
    """Random DH rows, lengths m and angles rad."""
    n = len(types)
    return dict(
        a=rng.uniform(-0.5, 0.5, n), alpha=rng.uniform(-np.pi, np.pi, n), d=rng.uniform(-0.5, 0.5, n),
        offset=rng.uniform(-np.pi, np.pi, n), joint_types=types,
    )


def dh_file_text(table, convention="dh", base=None, tool=None):
    """A DH table file in mm and deg, written here without zrp_ga (yaml.safe_dump floats are exact)."""
    rows = [
        dict(name=f"j{i + 1}", type=t, a=table["a"][i] * 1000, alpha=np.degrees(table["alpha"][i]),
             d=table["d"][i] * 1000, theta=np.degrees(table["offset"][i]))
        for i, t in enumerate(table["joint_types"])
    ]
    data = dict(name="arm", convention=convention, units=dict(length="mm", angle="deg"), joints=rows)
    for key, T in (("base", base), ("tool", tool)):
        if T is not None:
            xyzw = Rotation.from_matrix(T[:3, :3]).as_quat()
            data[key] = dict(xyz=(T[:3, 3] * 1000).tolist(), quaternion_xyzw=xyzw.tolist())
    return yaml.safe_dump(_plain(data), sort_keys=False)


def _plain(x):
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_plain(v) for v in x]
    return float(x) if isinstance(x, np.floating) else x


def random_pose(rng):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.random(random_state=int(rng.integers(1000))).as_matrix(), rng.uniform(-1, 1, 3)
    return T


def names(robot: ZRPRobot) -> tuple[str, ...]:
    """The joint names, joint_<i> where the robot has none (as files get them)."""
    return robot.joint_names or tuple(f"joint_{i + 1}" for i in range(robot.n))


def assert_same_robot(a: ZRPRobot, b: ZRPRobot, atol=1e-12):
    for field in ("u0", "b0", "R_h0"):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), atol=atol, rtol=0, err_msg=field)
    assert a.joint_types == b.joint_types and names(a) == names(b)
    np.testing.assert_allclose(a.joint_limits, b.joint_limits, rtol=1e-14)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("types", ["RRRRRR", "RRPRRR", "PRPP"])
def test_dh_file_in_mm_and_deg_reads_as_the_dh_chain(tmp_path, rng, types, convention):
    table, base, tool = random_table(rng, types), random_pose(rng), random_pose(rng)
    path = tmp_path / "arm.yaml"
    path.write_text(dh_file_text(table, convention, base, tool))
    robot = read_robot(path)
    assert robot.joint_names == tuple(f"j{i + 1}" for i in range(len(types))) and robot.limits is None
    for q in rng.uniform(-1, 1, size=(10, len(types))):
        T = base @ dh_fk(table, q, modified=convention == "mdh") @ tool
        R, p = kinematics.forward(robot, q)
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p, T[:3, 3], atol=1e-12)


def test_round_trip_dh_file_zrp_urdf_zrp(tmp_path, rng):
    files = [robots.path(name) for name in robots.names()]
    for k, types in enumerate(("RPRRPR", "PPRR", "RRRRRRP")):
        files.append(tmp_path / f"random_{k}.yaml")
        files[-1].write_text(dh_file_text(random_table(rng, types), "dh", random_pose(rng), random_pose(rng)))
    for path in files:
        robot = read_robot(path)
        urdf = tmp_path / f"{path.stem}.urdf"
        to_urdf(robot, urdf)
        assert_same_robot(read_robot(urdf), robot)


def test_dh_writer_round_trips_through_read_robot(tmp_path, rng):
    arm = ZRPRobot.from_mdh(**random_table(rng, "RPRRR"), base=random_pose(rng), tool=random_pose(rng),
                            limits=[[-1, 1], [0.1, 0.7], [-2, 2], [-3, 3], [-1, 2]])
    for robot in [robots.get(name) for name in robots.names()] + [arm]:
        for convention, length, angle in (("dh", "m", "deg"), ("mdh", "mm", "rad")):
            table, _ = to_dh(robot, convention)
            path = tmp_path / f"{robot.name}_{convention}.yaml"
            dh_to_yaml(table, path, length=length, angle=angle, comment="written by the test\nsecond line")
            assert path.read_text().startswith("# written by the test\n# second line\n")
            assert_same_robot(read_robot(path), table.to_robot())
            np.testing.assert_allclose(kinematics.forward(read_robot(path), np.zeros(robot.n))[1],
                                       kinematics.forward(robot, np.zeros(robot.n))[1], atol=1e-12)


def test_zrp_yaml_reads_as_from_yaml(tmp_path):
    robot = robots.get("stanford")
    path = tmp_path / "stanford.yml"
    robot.to_yaml(path)
    assert_same_robot(read_robot(path), robot, atol=0)  # a preset: unit axes exactly


def test_base_and_tool_forms_agree(tmp_path):
    rotation = Rotation.from_euler("xyz", [10, -20, 30], degrees=True)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation.as_matrix(), [0.1, 0.2, 0.3]
    forms = [
        "{xyz: [100, 200, 300], rpy: [10, -20, 30]}",
        "{xyz: [100, 200, 300], quaternion_xyzw: %s}" % rotation.as_quat().tolist(),
        "{matrix: %s}" % np.vstack([np.hstack([T[:3, :3], 1000 * T[:3, 3:]]), [0, 0, 0, 1]]).tolist(),
    ]
    for k, form in enumerate(forms):
        path = tmp_path / f"form{k}.yaml"
        path.write_text(
            "convention: dh\nunits: {length: mm, angle: deg}\n"
            f"joints:\n  - {{type: R, a: 0, alpha: 0, d: 1e-3}}\nbase: {form}\ntool: {form}\n"
        )
        table = read_dh(path)
        np.testing.assert_allclose(table.base, T, atol=1e-15)
        np.testing.assert_allclose(table.tool, T, atol=1e-15)
        assert table.d[0] == 1e-6 and table.name == f"form{k}" and table.joint_names == ("joint_1",)


def test_write_robot_files(tmp_path, rng):
    robot = robots.get("ur10")
    robot = robot.replace(u0=robot.u0 + rng.normal(scale=1e-5, size=(6, 3)), normalize=True)  # calibrated-like
    base, tool = random_pose(rng), random_pose(rng)
    paths = write_robot_files(robot, tmp_path / "out", base=base, tool=tool)
    # a UR arm read from a DH file: its kinematics for ur_description, corrections beside the tables
    assert set(paths) == {"urdf", "dh", "mdh", "zrp", "frames", "dh_corrections", "mdh_corrections", "ur_kinematics"}
    assert all(p.is_file() for p in paths.values())
    assert_same_robot(read_robot(paths["zrp"]), robot, atol=1e-15)  # ZRPRobot renormalises u0: an ulp
    # the URDF is the robot alone, from its own base frame: base and tool are in the frames file only
    assert "world" not in paths["urdf"].read_text() and 'name="tool"' not in paths["urdf"].read_text()
    assert_same_robot(read_robot(paths["urdf"]), robot)  # base_link .. hand, the only root and leaf
    # on request, base and tool as fixed joints to new links world and tool
    paths = write_robot_files(robot, tmp_path / "out", base=base, tool=tool, frames_in_urdf=True)
    assert_same_robot(read_robot(paths["urdf"], base_link="base_link", tip_link="hand"), robot)
    whole = read_robot(paths["urdf"])  # world .. tool
    q = rng.uniform(-3, 3, size=(5, 6))
    R, p = kinematics.forward(robot, q)
    Rw, pw = kinematics.forward(whole, q)
    for m in range(5):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R[m], p[m]
        np.testing.assert_allclose(pw[m], (base @ T @ tool)[:3, 3], atol=1e-12)
        np.testing.assert_allclose(Rw[m], (base @ T @ tool)[:3, :3], atol=1e-12)
    text = paths["dh"].read_text()
    assert re.search(r"^# .*position [0-9.e-]+ m, orientation [0-9.e-]+ rad$", text, re.M)
    assert "# row 2 (shoulder_lift_joint): Hayati's parameterisation" in text  # the nearly parallel axes 2, 3
    assert "# row 4 (wrist_1_joint): Hayati's parameterisation" in paths["mdh"].read_text()
    for kind in ("dh", "mdh"):  # exact, Hayati rows read back
        assert np.abs(kinematics.forward(read_robot(paths[kind]), q)[1] - p).max() < 1e-12
    frames = yaml.safe_load(paths["frames"].read_text())
    for key, T in (("base", base), ("tool", tool)):
        np.testing.assert_allclose(frames[key]["matrix"], T, atol=1e-15)
        np.testing.assert_allclose(frames[key]["xyz"], T[:3, 3], atol=1e-15)
        q_xyzw = np.array(frames[key]["quaternion_xyzw"])
        np.testing.assert_allclose(Rotation.from_quat(q_xyzw).as_matrix(), T[:3, :3], atol=1e-15)


def test_presets_ship_names_and_limits_in_si_units():
    ur10, stanford = robots.get("ur10"), robots.get("stanford")
    assert ur10.joint_names[0] == "shoulder_pan_joint"
    np.testing.assert_allclose(ur10.joint_limits, [[-2 * np.pi, 2 * np.pi]] * 6)
    np.testing.assert_allclose(stanford.joint_limits[2], [12 * 0.0254, 50 * 0.0254])  # inches, in m


# --- bad inputs: one line naming the file and where ------------------------------------------
GOOD_DH = """name: arm
convention: dh
units: {length: mm, angle: deg}
joints:
  - {name: j1, type: R, a: 0, alpha: 90, d: 400, limits: [-170, 170]}
  - {name: j2, type: P, a: 25, alpha: 0, d: 0, theta: -90, limits: [0, 500]}
"""

BAD_YAML = [  # (change to GOOD_DH, or a whole text), text found at the line and column named, message
    (("{length: mm,", "{length: inch,"), "inch", "units: length: 'inch', expected one of m, mm$"),
    (("convention: dh", "convention: craig"), "craig", "convention: 'craig', expected one of dh, mdh$"),
    (("d: 400", "d: .nan"), ".nan", r"joint 1 \(j1\): d: \.nan is not a finite number$"),
    (("a: 25", "a: -.inf"), "-.inf", r"joint 2 \(j2\): a: -\.inf is not a finite number$"),
    (("d: 400", "d: 1e300"), "1e300", r"joint 1 \(j1\): d: 1e300 is absurd"),
    (("d: 400", "d: abc"), "abc", r"joint 1 \(j1\): d: expected a number, got 'abc'$"),
    (("d: 400", "d: yes"), "yes", r"joint 1 \(j1\): d: expected a number$"),
    (("[0, 500]", "[500, 0]"), "[500, 0]", r"joint 2 \(j2\): limits: lower must be below upper$"),
    (("[-170, 170]", "[-170, 170, 3]"), "[-170, 170, 3]", r"joint 1 \(j1\): limits: expected a list of 2 numbers, got 3"),
    (("type: P", "type: X"), "X, a:", r"joint 2 \(j2\): type: 'X', expected one of R, P$"),
    ((", alpha: 90", ""), "{name: j1", r"joint 1 \(j1\): missing key 'alpha'$"),
    (("alpha: 90", "alpah: 90"), "alpah", r"joint 1: unknown key 'alpah'"),
    (("name: j2", "name: j1"), "{name: j1, type: P", r"joint 2: name 'j1' is joint 1's already$"),
    (("units: {length: mm, angle: deg}\n", ""), "name: arm", r"the file \(e\.g\. units: .*\): missing key 'units'$"),
    (("joints:", "old: 1\njoints:"), "old", r"the file: unknown key 'old'"),
    ("convention: dh\nunits: {length: m, angle: rad}\njoints: []\n", "[]", "joints: expected a list of joint rows"),
    ("units: {length: m, angle: deg}}\n", "}", "malformed YAML: expected <block end>, but found '}'$"),
    ("joints: [\n  {a: 1]\n", "]", "malformed YAML: expected ',' or '}', but got ']'$"),
    ("u0: [[0, 0, 1]]\nb0: [[0, 0, 0], [1, 0]]\n", "[[0, 0, 0], [1, 0]]", "b0: not an array of numbers"),
    ("u0: [[0, 0, 1]]\nb0: [[0, 0, 0]]\n", "[[0, 0, 0]]", r"b0: expected shape \(2, 3\), got \(1, 3\)$"),
    ("u0: [[0, 0, 1]]\nb0: [[0, 0, 0], [1e300, 0, 0]]\n", "[[0, 0, 0], [1e300", r"b0: a length of 1e\+300 m is absurd$"),
    ("robot: {}\n", "robot", r"neither a DH table \(key 'joints'\) nor a ZRP robot"),
    ("", None, "empty file$"),
    (GOOD_DH + "base: {xyz: [0, 0], rpy: [0, 0, 0]}\n", "[0, 0], rpy", "base: xyz: expected a list of 3 numbers, got 2 entries$"),
    (GOOD_DH + "tool: {quaternion_xyzw: [0, 0, 0, 0]}\n", "[0, 0, 0, 0]", "tool: quaternion_xyzw has length 0, not 1$"),
    (GOOD_DH + "tool: {rpy: [0, 0, 0], quaternion_xyzw: [0, 0, 0, 1]}\n", "{rpy", "tool: give either rpy or quaternion_xyzw$"),
    (GOOD_DH + "base: {matrix: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]}\n", "[[1, 0", "base: matrix: not a rotation"),
]


@pytest.mark.parametrize("change, at, message", BAD_YAML)
def test_bad_yaml_gives_one_line_with_file_line_and_column(tmp_path, change, at, message):
    path = tmp_path / "arm.yaml"
    assert isinstance(change, str) or change[0] in GOOD_DH
    text = GOOD_DH.replace(*change) if isinstance(change, tuple) else change
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        read_robot(path)
    error = str(info.value)
    assert "\n" not in error and error.startswith(str(path)), error
    assert re.search(message, error), error
    if at is not None:  # the line and column named point at the culprit
        line, column = map(int, re.match(r", line (\d+), column (\d+): ", error[len(str(path)):]).groups())
        assert text.splitlines()[line - 1][column - 1:].startswith(at), error


GOOD_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/> <link name="l1"/> <link name="l2"/> <link name="tip"/>
  <joint name="j1" type="revolute">
    <parent link="base"/> <child link="l1"/>
    <origin xyz="0 0 0.4" rpy="0 0 0"/> <axis xyz="0 0 1"/> <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="prismatic">
    <parent link="l1"/> <child link="l2"/>
    <origin xyz="0.1 0 0" rpy="0 0 0"/> <axis xyz="1 0 0"/> <limit lower="0" upper="0.5" effort="1" velocity="1"/>
  </joint>
  <joint name="flange" type="fixed">
    <parent link="l2"/> <child link="tip"/> <origin xyz="0 0 0.1" rpy="0 0 0"/>
  </joint>
</robot>
"""

BAD_URDF = [  # (change to GOOD_URDF), expected message after the path, keyword arguments
    (('<joint name="flange" type="fixed">', '<joint name="flange" type="fixed">\n<oops>'), r", line 15, column \d+: malformed XML: Opening and ending tag mismatch: oops line 13 and joint", {}),
    (('type="prismatic"', 'type="floating"'), r", line 8: joint 'j2': a floating joint; only revolute, continuous, prismatic", {}),
    (('type="prismatic"', 'type="planar"'), r", line 8: joint 'j2': a planar joint", {}),
    (('<axis xyz="1 0 0"/>', '<axis xyz="1 0 0"/><mimic joint="j1"/>'), r", line 8: joint 'j2': mimics 'j1'; mimic joints cannot be read$", {}),
    (('<axis xyz="1 0 0"/>', '<axis xyz="0 0 0"/>'), r", line 8: joint 'j2': axis of length zero$", {}),
    (('xyz="0.1 0 0"', 'xyz="0.1 0"'), r", line 8: joint 'j2': <origin xyz='0.1 0'>: expected 3 number\(s\), got 2$", {}),
    (('xyz="0.1 0 0"', 'xyz="0.1 nan 0"'), r", line 8: joint 'j2': <origin xyz='0.1 nan 0'>: not finite or absurd", {}),
    (('xyz="0.1 0 0"', 'xyz="0.1 1e300 0"'), r", line 8: joint 'j2': <origin xyz='0.1 1e300 0'>: not finite or absurd", {}),
    (('xyz="0.1 0 0"', 'xyz="0.1 x 0"'), r", line 8: joint 'j2': <origin xyz='0.1 x 0'>: not numbers$", {}),
    (('lower="0" upper="0.5"', 'lower="0.5" upper="0"'), r", line 8: joint 'j2': limit lower 0.5 is not below upper 0$", {}),
    (('<parent link="l1"/>', '<parent link="l7"/>'), r", line 8: joint 'j2': unknown link 'l7'$", {}),
    (('<parent link="l1"/>', ""), r", line 8: joint 'j2': missing <parent link=...>$", {}),
    (("", ""), r": tip_link 'hand' is not a link of the file \(links: base, l1, l2, tip\)$", dict(tip_link="hand")),
    (("", ""), r": base_link 'world' is not a link of the file", dict(base_link="world")),
    (("", ""), r": tip_link 'l1' is not below base_link 'l2'$", dict(base_link="l2", tip_link="l1")),
    (("", ""), r": no movable joint between base_link 'l2' and tip_link 'tip'$", dict(base_link="l2")),
    (('<link name="tip"/>', '<link name="tip"/><link name="cam"/><joint name="c" type="fixed"><parent link="l1"/><child link="cam"/></joint>'),
     r": 2 leaf links below 'base' \((tip, cam|cam, tip)\); choose one with tip_link$", {}),
    (('<link name="base"/>', '<link name="base"/><link name="stray"/>'), r": 2 root links \(base, stray\); choose one with base_link$", {}),
    (('xyz="0 0 0.4"', 'xyz="0 0 0.4'), r", line 6, column \d+: malformed XML: ", {}),
    (('<robot name="arm">', '<robot>'), r", line 2: not a URDF: expected <robot name=...> as the root", {}),
    (('type="prismatic"', 'type="slider"'), r", line 8: joint 'j2': unknown type 'slider' \(URDF joint types: revolute, continuous,", {}),
    (('<link name="l2"/>', '<link name="l2"/> <link name="l1"/>'), r", line 3: link 'l1': name already used by the link on line 3$", {}),
    (('<link name="tip"/>', '<link name="tip"/> <link/>'), r", line 3: a <link> without a name$", {}),
]


@pytest.mark.parametrize("change, message, kwargs", BAD_URDF)
def test_bad_urdf_gives_one_line_with_file_and_line_or_joint(tmp_path, change, message, kwargs):
    path = tmp_path / "arm.urdf"
    assert change[0] in GOOD_URDF
    path.write_text(GOOD_URDF.replace(*change) if change[0] else GOOD_URDF)
    with pytest.raises(ValueError) as info:
        read_robot(path, **kwargs)
    text = str(info.value)
    assert "\n" not in text and text.startswith(str(path))
    assert re.search(message, text), text


def test_good_urdf_of_the_error_tests_reads(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(GOOD_URDF)
    robot = read_robot(path)
    np.testing.assert_allclose(robot.b0, [[0, 0, 0.4], [0.1, 0, 0], [0, 0, 0.1]], atol=1e-15)
    assert robot.joint_types == "RP" and robot.joint_names == ("j1", "j2")


def test_bad_paths(tmp_path):
    cases = [
        (tmp_path / "missing.yaml", ": no such file$"),
        (tmp_path, ": is a directory, expected a robot file"),
        (tmp_path / "binary.yaml", r": not a text file \(not UTF-8\)$"),
        (tmp_path / "arm.urdf.xacro", r": a xacro file; expand it to URDF first"),
    ]
    (tmp_path / "binary.yaml").write_bytes(b"\xff\xfe\x00\x81")
    (tmp_path / "arm.urdf.xacro").write_text("<robot/>")
    for path, message in cases:
        with pytest.raises(ValueError) as info:
            read_robot(path)
        assert "\n" not in str(info.value) and str(info.value).startswith(str(path))
        assert re.search(message, str(info.value)), str(info.value)


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root reads any file")
def test_unreadable_file(tmp_path):
    path = tmp_path / "arm.yaml"
    path.write_text(GOOD_DH)
    path.chmod(0)
    with pytest.raises(ValueError, match=r"arm\.yaml: cannot read \(Permission denied\)$"):
        read_robot(path)


def test_base_link_for_a_yaml_file_is_refused(tmp_path):
    path = tmp_path / "arm.yaml"
    path.write_text(GOOD_DH)
    with pytest.raises(ValueError, match=r"arm\.yaml: base_link and tip_link apply to URDF files only$"):
        read_robot(path, base_link="base")


def test_good_dh_of_the_error_tests_reads(tmp_path):
    path = tmp_path / "arm.yaml"
    path.write_text(GOOD_DH)
    table = read_dh(path)
    np.testing.assert_allclose([table.d[0], table.a[1], table.alpha[0], table.theta[1]], [0.4, 0.025, np.pi / 2, -np.pi / 2])
    np.testing.assert_allclose(table.limits, [np.radians([-170, 170]), [0.0, 0.5]])
