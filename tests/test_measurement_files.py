"""Measurement files: every kind of bad input is one line naming file, line and column; units
(stated or found), joint units by joint type, orientation conventions, tool columns."""

import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from zrp_ga import robots
from zrp_ga.core import checks
from zrp_ga.io import measurements
from zrp_ga.io.measurements import read, zrp_format

UR10 = robots.get("ur10")
HEAD = "q1,q2,q3,q4,q5,q6,x,y,z"
ROWS = ["0,0,0,0,0,0,0.1,0.2,0.3", "0.1,0.2,0.3,0.4,0.5,0.6,0.45,0.55,0.65", "-0.3,0.5,1,0,-1,2,0.9,-0.2,0.15",
        "1,1,1,1,1,1,-0.5,0.35,0.7"]  # fmt: skip
GOOD = "\n".join([HEAD, *ROWS]) + "\n"


def _file(tmp_path, text, name="data.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _error(path, fmt=None, robot=UR10, **kw) -> str:
    with pytest.raises(ValueError) as info:
        read(path, fmt or zrp_format(robot.n), robot, **kw)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    return message


def test_a_good_file_reads_in_si_units(tmp_path):
    data = read(_file(tmp_path, GOOD), zrp_format(6, "m", "rad"), UR10)
    np.testing.assert_allclose(data.p[1], [0.45, 0.55, 0.65])
    np.testing.assert_allclose(data.q[2], [-0.3, 0.5, 1, 0, -1, 2])
    assert list(data.lines) == [2, 3, 4, 5] and data.units == ("m", "rad") and data.tool is None


@pytest.mark.parametrize(
    "change, message",
    [
        (("0.45,0.55", "0.45,nan"), "line 3, column 'y': 'nan' is not a finite number"),
        (("0.45,0.55", "0.45,inf"), "line 3, column 'y': 'inf' is not a finite number"),
        (("0.45,0.55", "0.45,five"), "line 3, column 'y': 'five' is not a finite number"),
        (("0,0,0,0,0,0,0.1", "0,0,0,0,0,,0.1"), "line 2, column 'q6': empty"),
        (("0.45,0.55", "1e300,0.55"), "line 3, column 'x': 1e+300 m is absurd (more than 1e+04 m)"),
        (("0.1,0.2,0.3,0.4", "0.1,1e300,0.3,0.4"), "line 3, column 'q2': 1e+300 rad is beyond any turn of ur10"),
        (("0.1,0.2,0.3,0.4", "0.1,90,0.3,0.4"), "problem.angle_unit=deg"),
        (("-0.2,0.15", "-0.2,40"), "line 4, column 'z': 40 m puts the point"),
    ],
)
def test_bad_cells_name_file_line_and_column(tmp_path, change, message):
    assert message in _error(_file(tmp_path, GOOD.replace(*change)), zrp_format(6, "m", "rad"))


def test_a_bad_cell_that_no_unit_explains_is_named_also_with_units_found_from_the_data(tmp_path):
    path = _file(tmp_path, GOOD.replace("0.45,0.55", "1e300,0.55"))
    assert "line 3, column 'x': 1e+300 m is absurd" in _error(path, zrp_format(6, "auto", "auto"))


@pytest.mark.parametrize(
    "text, message",
    [
        (GOOD.replace(",z", ",zz"), "missing column 'z'"),
        (GOOD.replace(",", ";"), "is the file separated by something else than ','?"),
        ("q1,q2,q3,q4,q5,x,y,z\n0,0,0,0,0,1,2,3\n", "5 joint columns (q1, q2, q3, q4, q5), but the robot has 6 joints"),
        (HEAD + "\n", "no measurement rows"),
        ("", "cannot be read as a ','-separated file"),
        (GOOD + ROWS[0] + "\n" + ROWS[2] + "\n", "2 rows repeat earlier rows exactly (first: line 6 repeats line 2)"),
        (GOOD.replace(HEAD, HEAD + ",sx,sy,sz").replace("0.1,0.2,0.3\n", "0.1,0.2,0.3,0,1,1\n", 1)
         .replace("0.6\n", "0.6,1,1,1\n").replace("0.1\n", "0.1,1,1,1\n").replace("0.7\n", "0.7,1,1,1\n"),
         "line 2, column 'sx': 0: a standard deviation must be > 0"),
        ("\n".join([HEAD + ",tool", ROWS[0] + ",A", ROWS[1] + ",B", ROWS[2] + ",A", ROWS[3] + ","]) + "\n",
         "line 5, column 'tool': empty"),
    ],
)  # fmt: skip
def test_bad_files_are_one_line(tmp_path, text, message):
    assert message in _error(_file(tmp_path, text), zrp_format(6, "m", "rad"))


def test_missing_directory_binary_and_unreadable_paths(tmp_path):
    assert "no such file" in _error(tmp_path / "none.csv")
    assert "is a directory" in _error(tmp_path)
    assert "not a text file" in _error(_file(tmp_path, "q1\0\0\0", "binary.csv"))
    if os.geteuid() != 0:  # root reads any file
        path = _file(tmp_path, GOOD, "locked.csv")
        path.chmod(0)
        assert "cannot read" in _error(path)


def test_blank_lines_keep_the_line_numbers(tmp_path):
    path = _file(tmp_path, GOOD.replace("\n0.1,0.2", "\n\n0.1,0.2").replace("0.45,0.55", "0.45,x"))
    assert "line 4, column 'y'" in _error(path, zrp_format(6, "m", "rad"))
    assert list(read(_file(tmp_path, GOOD.replace("\n0.1,0.2", "\n\n0.1,0.2"), "ok.csv"), zrp_format(6), UR10).lines) == [2, 4, 5, 6]


def test_bad_rows_and_repeats_are_dropped_only_when_asked(tmp_path, caplog):
    path = _file(tmp_path, GOOD.replace("0.45,0.55", "0.45,five") + ROWS[0] + "\n")
    data = read(path, zrp_format(6, "m", "rad"), UR10, drop_bad_rows=True)
    assert list(data.lines) == [2, 4, 5]
    assert "dropped 1 rows with bad cells (lines 3)" in caplog.text and "line 6 repeats line 2" in caplog.text


@pytest.mark.parametrize("unit, scale", [("m", 1.0), ("mm", 1e3)])
def test_units_are_found_from_the_points_and_the_arms_reach(tmp_path, unit, scale):
    rows = [",".join(r.split(",")[:6] + [repr(float(v) * scale) for v in r.split(",")[6:]]) for r in ROWS]
    deg = [",".join([repr(float(v) * 90) for v in r.split(",")[:6]] + r.split(",")[6:]) for r in rows]
    data = read(_file(tmp_path, "\n".join([HEAD, *deg]) + "\n"), zrp_format(6, "auto", "auto"), UR10)
    assert data.units == (unit, "deg")
    np.testing.assert_allclose(data.p[3], [-0.5, 0.35, 0.7])
    np.testing.assert_allclose(data.q[1], np.radians([9, 18, 27, 36, 45, 54]))
    assert read(_file(tmp_path, "\n".join([HEAD, *rows]) + "\n", "rad.csv"), zrp_format(6, "auto", "auto"), UR10).units == (unit, "rad")


def test_a_stated_length_unit_that_cannot_be_right_is_refused_with_the_one_that_fits(tmp_path):
    mm = "\n".join([HEAD] + [",".join(r.split(",")[:6] + [repr(float(v) * 1e3) for v in r.split(",")[6:]]) for r in ROWS])
    message = _error(_file(tmp_path, mm + "\n"), zrp_format(6, "m", "rad"))
    assert "they cannot be in m (problem.length_unit=mm?)" in message


def test_prismatic_joints_are_read_in_length_units(tmp_path):
    stanford = robots.get("stanford")  # joint 3 prismatic
    path = _file(tmp_path, "\n".join([HEAD, "10,20,300,40,50,60,100,200,300", "-10,5,250,0,10,-20,400,500,600",
                                      "0,0,100,0,0,0,-300,200,100"]) + "\n")  # fmt: skip
    data = read(path, zrp_format(6, "mm", "deg"), stanford)
    np.testing.assert_allclose(data.q[0], [np.radians(10), np.radians(20), 0.3, np.radians(40), np.radians(50), np.radians(60)])


def _rx(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _ry(a):
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _rz(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


@pytest.mark.parametrize(
    "convention, expected",
    [
        ("XYZ", lambda a, b, c: _rx(a) @ _ry(b) @ _rz(c)),  # intrinsic: about the moving axes
        ("xyz", lambda a, b, c: _rz(c) @ _ry(b) @ _rx(a)),  # extrinsic: about the fixed axes
        ("ZYX", lambda a, b, c: _rz(a) @ _ry(b) @ _rx(c)),
    ],
)
def test_euler_conventions_against_hand_written_products(tmp_path, convention, expected):
    angles = [20.0, -35.0, 50.0]
    text = GOOD.replace(HEAD, HEAD + ",rx,ry,rz").replace("\n", ",20,-35,50\n").replace(HEAD + ",rx,ry,rz,20,-35,50", HEAD + ",rx,ry,rz")
    data = read(_file(tmp_path, text), zrp_format(6, "m", "deg", convention), UR10)
    np.testing.assert_allclose(data.R[0], expected(*np.radians(angles)), atol=1e-14)
    assert data.q[0, 0] == 0.0  # the angle unit applies to the joints too


def test_rotation_vector_as_ur_controllers_report_it(tmp_path):
    text = "\n".join([HEAD + ",rx,ry,rz", *[r + f",0,0,{np.pi / 2!r}" for r in ROWS[:3]], ROWS[3] + ",0.1,-0.2,0.3"]) + "\n"
    data = read(_file(tmp_path, text), zrp_format(6, "m", "rad", "rotvec"), UR10)
    np.testing.assert_allclose(data.R[0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)  # a quarter turn about z
    v = np.array([0.1, -0.2, 0.3])  # Rodrigues' formula by hand
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / np.linalg.norm(v)
    t = np.linalg.norm(v)
    np.testing.assert_allclose(data.R[3], np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K, atol=1e-15)


def test_orientation_columns_are_not_read_without_a_stated_convention(tmp_path):
    text = "\n".join([HEAD + ",rx,ry,rz", *[r + ",1,2,nonsense" for r in ROWS]]) + "\n"
    assert read(_file(tmp_path, text), zrp_format(6, "m", "rad"), UR10).R is None
    with pytest.raises(ValueError, match="orientation convention: 'XXY' is neither"):
        checks.check_convention("XXY", "orientation convention")
    checks.check_convention("ZYZ", "orientation convention")  # proper Euler angles are fine


def test_tool_names_in_the_order_they_first_appear(tmp_path):
    text = "\n".join([HEAD + ",tool", ROWS[0] + ",B", ROWS[1] + ",A", ROWS[2] + ",B", ROWS[3] + ", C "]) + "\n"
    data = read(_file(tmp_path, text), zrp_format(6, "m", "rad"), UR10)
    assert data.tool_names == ("B", "A", "C") and list(data.tool) == [0, 1, 0, 2]
    moved = data.with_tool_names(("A", "B", "C", "D"))
    assert [moved.tool_names[k] for k in moved.tool] == ["B", "A", "B", "C"]
    with pytest.raises(ValueError, match=r"data\.csv, line 5, column 'tool': tool 'C' is neither"):
        data.with_tool_names(("A", "B"))


def test_the_ur10_files_ship_and_read():
    from zrp_ga.problems.measured import data_path

    b = read(data_path("pkg:ur10_ipa/series_b_joint_configurations.csv"), measurements.UR10_IPA, UR10)
    c = read(data_path("pkg:ur10_ipa/series_c_random_poses.csv"), measurements.UR10_IPA, UR10)
    assert b.q.shape == (1495, 6) and c.q.shape == (2773, 6)
    np.testing.assert_allclose(b.p[0], [0.38376294, -3.2408734, 0.20193157])  # line 2 of the file, mm -> m
    np.testing.assert_allclose(b.R[0], Rotation.from_euler("XYZ", [-90.179302, -20.118749, -90.169308], degrees=True).as_matrix())
    assert b.std is not None


def test_the_ur10_format_refuses_bad_cells_by_line_and_column(tmp_path):
    from zrp_ga.problems.measured import data_path

    lines = data_path("pkg:ur10_ipa/series_b_joint_configurations.csv").read_text().splitlines()[:12]
    cells = lines[3].split(";")
    cells[14] = "1e300"  # measurement_x
    path = _file(tmp_path, "\n".join(lines[:3] + [";".join(cells)] + lines[4:]) + "\n", "ur10.csv")
    assert "line 4, column 'measurement_x': 1e+300 mm is absurd" in _error(path, measurements.UR10_IPA)
    path = _file(tmp_path, "\n".join(lines + lines[5:6]) + "\n", "repeat.csv")
    assert "1 rows repeat earlier rows exactly (first: line 13 repeats line 6)" in _error(path, measurements.UR10_IPA)


def test_points_too_close_together_for_either_unit_ask_for_it(tmp_path):
    rows = [f"{i * 0.1},0,0,0,0,0,{300 + i},{200 - i},{500 + 2 * i}" for i in range(5)]  # 8 mm apart at most: mm or m?
    message = _error(_file(tmp_path, "\n".join([HEAD, *rows]) + "\n"), zrp_format(6, "auto", "auto"))
    assert "cannot tell metres from millimetres; set problem.length_unit=m or mm" in message
    assert read(_file(tmp_path, "\n".join([HEAD, *rows]) + "\n", "mm.csv"), zrp_format(6, "mm", "auto"), UR10).units == ("mm", "rad")


def _small_volume_rows(side_m: float, scale: float, seed: int = 5) -> tuple[str, np.ndarray]:
    """A tracker's points of a UR10 end point moving within a cube of side ``side_m`` about a
    point 0.8 m out (a tool-centre-point calibration near one spot), written in file units
    (``scale`` per metre); the true points in metres."""
    rng = np.random.default_rng(seed)
    p = np.array([0.8, 0.1, 0.4]) + rng.uniform(-side_m / 2, side_m / 2, (30, 3))
    q = rng.uniform(-1, 1, (30, 6))
    rows = [",".join([*(repr(float(v)) for v in qi), *(repr(float(v * scale)) for v in pi)]) for qi, pi in zip(q, p)]
    return "\n".join([HEAD, *rows]) + "\n", p


@pytest.mark.parametrize("side_mm", [40, 100, 400])
@pytest.mark.parametrize("unit, scale", [("m", 1.0), ("mm", 1e3)])
def test_a_small_measured_volume_is_read_in_the_unit_it_was_written_in(tmp_path, side_mm, unit, scale):
    """Points within a 4 cm cube (2.4% of the UR10's 1.68 m reach, the region a tool-point
    calibration may cover) are read in metres from a file in metres and in millimetres from a
    file in millimetres: the truth, known here, comes back in metres either way."""
    text, truth = _small_volume_rows(side_mm * 1e-3, scale)
    data = read(_file(tmp_path, text), zrp_format(6, "auto", "auto"), UR10)
    assert data.units[0] == unit
    np.testing.assert_allclose(data.p, truth, rtol=0, atol=1e-12)


def test_a_volume_below_a_hundredth_of_the_reach_asks_for_the_unit(tmp_path):
    """A 1 cm cube (under 1% of the reach: 1.7 cm): in metres it could be millimetres of
    another calibration's spread, so the unit is asked for, and read as stated."""
    reach = float(np.linalg.norm(UR10.b0[1:], axis=1).sum())  # the arm's reach, by its body vectors
    assert 1.6 < reach < 1.8  # 1.68 m: the body vectors of the shipped UR10, wrist and flange included
    text, truth = _small_volume_rows(0.01, 1.0)
    assert "cannot tell metres from millimetres" in _error(_file(tmp_path, text), zrp_format(6, "auto", "auto"))
    data = read(_file(tmp_path, text, "m.csv"), zrp_format(6, "m", "auto"), UR10)
    np.testing.assert_allclose(data.p, truth, rtol=0, atol=1e-12)
