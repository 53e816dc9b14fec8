"""Tables of calibrated arms in the nominal table's conventions (to_dh(..., like=nominal)).

Each table is checked against the independent chain of tests/dh_reference.py (Hayati's beta
included) and the calibrated arm's forward kinematics; each row's change from the nominal row
against the size of the errors made."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

from zrp_ga import robots
from zrp_ga.io.robot_files import read_dh, read_robot, write_robot_files
from zrp_ga.model import kinematics
from zrp_ga.model.dh import DHTable, corrections, nominal_tables, to_dh
from zrp_ga.model.robot import ZRPRobot

IRB140 = Path(__file__).parents[1] / "experiments" / "own_arm" / "irb140.yaml"
D = np.pi / 180
KR6 = DHTable("dh", a=[0.025, 0.455, 0.035, 0, 0, 0], alpha=np.array([-90, 0, 90, -90, 90, 0]) * D,
              d=[0.4, 0, 0, 0.42, 0, 0.08], theta=np.array([0, -90, 0, 0, 0, 180]) * D, joint_types="RRRRRR")  # fmt: skip
def pose(rpy_deg, xyz):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_matrix(), xyz
    return T


TURNED = DHTable(  # a base turned by 90 deg about z and lifted, a tool off the flange turned by 30 deg
    "mdh", a=[0, 0.26, 0.68, 0.035, 0, 0], alpha=np.array([0, -90, 0, -90, 90, -90]) * D, d=[0.45, 0, 0, 0.67, 0, 0.1],
    theta=np.array([0, -90, 0, 0, 0, 0]) * D, joint_types="RRRRRR", base=pose([0, 0, 90], [0.1, 0.2, 0.3]),
    tool=pose([0, 0, 30], [0.0, 0.05, 0.12]),
)  # fmt: skip


def nominal(name: str) -> DHTable:
    return {"kr6": KR6, "turned": TURNED, "irb140": read_dh(IRB140)}.get(name) or robots.get(name).source


def calibrated(table: DHTable, rng, scale: float) -> ZRPRobot:
    """The arm of the table, its axes tilted, its body vectors moved and its hand turned by about ``scale``."""
    arm = table.to_robot()
    turn = Rotation.from_rotvec(rng.normal(scale=scale, size=3)).as_matrix()
    return arm.replace(u0=arm.u0 + rng.normal(scale=scale, size=arm.u0.shape), b0=arm.b0 + rng.normal(scale=scale, size=arm.b0.shape),
                       R_h0=turn @ arm.R_h0, normalize=True)  # fmt: skip


def reference_fk(table: DHTable, q):
    rows = dict(d=table.d, a=table.a, alpha=table.alpha, offset=table.theta, beta=table.beta, joint_types=table.joint_types)
    return table.base @ dh_fk(rows, q, modified=table.convention == "mdh") @ table.tool


def wrapped(x):
    return np.angle(np.exp(1j * np.asarray(x)))


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("name", ["puma560", "ur10", "kr6", "irb140", "turned"])
def test_each_row_is_the_nominal_plus_a_small_correction_and_the_table_is_the_arm(name, convention, rng):
    table = nominal(name)
    like = nominal_tables(table.to_robot().replace(source=table))[convention]
    for scale in (1e-5, 1e-4, 1e-3):  # errors of 0.01 to 1 mm and mrad
        arm = calibrated(table, rng, scale)
        out, mismatch = to_dh(arm, like=like)
        q = rng.uniform(-np.pi, np.pi, size=(30, arm.n))
        R, p = kinematics.forward(arm, q)
        for m in range(len(q)):  # the independent chain of the written rows is the arm
            T = reference_fk(out, q[m])
            np.testing.assert_allclose(T[:3, 3], p[m], atol=1e-12)
            np.testing.assert_allclose(T[:3, :3], R[m], atol=1e-12)
        assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12
        # every row reads as the nominal's plus changes of the size of the errors (not 90 or 180 deg)
        for field in ("a", "d"):
            assert np.abs(getattr(out, field) - getattr(like, field)).max() < 30 * scale, field
        for field in ("alpha", "theta", "beta"):
            assert np.abs(getattr(out, field) - getattr(like, field)).max() < 30 * scale, field
        for key in ("base", "tool"):
            T, N = getattr(out, key), getattr(like, key)
            assert np.abs(T - N).max() < 30 * scale, key  # the base turn stays in the base, the tool's in the tool
        # the nominal's parallel pairs are Hayati rows with the nominal's d, the others plain rows
        parallel = {"puma560": [2], "ur10": [2, 3], "kr6": [2], "irb140": [2], "turned": [2]}[name]
        rows = [r if convention == "dh" else r + 1 for r in parallel]
        assert list(np.flatnonzero(out.beta) + 1) == rows
        held = np.array(parallel) - 1  # the row placing the frame along the first axis of the pair (both conventions)
        assert np.array_equal(out.d[held], like.d[held])


def test_the_old_rules_turned_the_base_by_90_degrees_and_joint_6_against_the_tool(rng):
    """The issue's case: a calibrated IRB 140 read by to_dh's own rules (base x along the world
    axis most perpendicular to axis 1, the last x towards a micrometre offset of the end point)
    moves a quarter turn into the base and joint 6's theta against the tool's yaw; read like
    the nominal table, neither moves."""
    table = read_dh(IRB140)
    for _ in range(20):
        arm = calibrated(table, rng, 1e-4)
        if abs(arm.u0[0, 0]) > abs(arm.u0[0, 1]):  # the world's y the most perpendicular to axis 1
            break
    own, _ = to_dh(arm)
    assert abs(abs(own.theta[0]) - np.pi / 2) < 1e-2 and abs(abs(wrapped(Rotation.from_matrix(own.base[:3, :3]).as_euler("xyz")[2])) - np.pi / 2) < 1e-2
    assert np.degrees(abs(own.theta[5])) > 1.0  # joint 6's x along a micrometre offset: any angle
    like, _ = to_dh(arm, like=table)
    assert np.abs(like.theta).max() < 1e-3 and np.abs(like.base - np.eye(4)).max() < 1e-3 and np.abs(like.tool - np.eye(4)).max() < 1e-3


def test_angles_keep_the_nominal_turn(rng):
    """A nominal theta of 180 degrees stays 180 (not -180) and -90 stays -90 (not 270)."""
    arm = calibrated(KR6, rng, 1e-4)
    out, _ = to_dh(arm, like=KR6)
    assert abs(out.theta[5] - np.pi) < 1e-2 and abs(out.theta[1] + np.pi / 2) < 1e-2


def test_the_corrections_file_is_the_difference_of_the_two_tables_files(tmp_path, rng):
    """Written for an arm read from a DH file (the nominal: its source): the CSV's corrections
    are the calibrated file's numbers minus the nominal file's, read back by read_dh."""
    path = tmp_path / "kr6.yaml"
    from zrp_ga.io.robot_files import dh_to_yaml

    dh_to_yaml(KR6, path, length="mm", angle="deg")
    arm = calibrated(read_dh(path), rng, 1e-4).replace(source=read_robot(path).source)
    paths = write_robot_files(arm, tmp_path / "out")
    import pandas as pd

    rows = pd.read_csv(paths["dh_corrections"])
    back, nominal_back = read_dh(paths["dh"]), read_dh(path)
    for _, row in rows[rows["row"].str.isdigit()].iterrows():
        i, kind = int(row["row"]) - 1, row["parameter"]
        f = 1e3 if row["unit"] == "mm" else 180 / np.pi
        assert abs(row["correction"] - (getattr(back, kind)[i] - getattr(nominal_back, kind)[i]) * f) < 1e-9, (i, kind)
        assert abs(row["nominal"] - getattr(nominal_back, kind)[i] * f) < 1e-9
    turn = rows[(rows["row"] == "tool") & (rows["parameter"] == "turn")]["correction"].item()
    angle = np.degrees(np.linalg.norm(Rotation.from_matrix(back.tool[:3, :3]).as_rotvec()))
    assert abs(turn - angle) < 1e-9 and 0 < turn < 0.5
    text = paths["dh"].read_text()
    assert "# In the nominal table's conventions (row = nominal + correction; calibrated_robot_dh_corrections.csv)" in text
    assert yaml.safe_load(text)["joints"][1]["theta"] == pytest.approx(-90, abs=0.1)


def test_corrections_of_a_turned_copy(rng):
    """corrections(): the rotation vector of the base's change, in the nominal base's frame."""
    turn = rng.normal(scale=1e-3, size=3)
    base = KR6.base.copy()
    base[:3, :3] = base[:3, :3] @ Rotation.from_rotvec(turn).as_matrix()
    base[:3, 3] += [1e-3, -2e-3, 0.0]
    moved = DHTable("dh", KR6.a, KR6.alpha + 1e-3, KR6.d, KR6.theta - 2 * np.pi + 1e-3, KR6.joint_types, base=base)
    c = corrections(moved, KR6)
    np.testing.assert_allclose(c["base_rotvec"], turn, atol=1e-15)
    np.testing.assert_allclose(c["base_xyz"], [1e-3, -2e-3, 0.0], atol=1e-18)
    np.testing.assert_allclose(c["theta"], 1e-3, atol=1e-12)  # the smallest turn, not 2 pi
    np.testing.assert_allclose(c["alpha"], 1e-3, atol=1e-12)
