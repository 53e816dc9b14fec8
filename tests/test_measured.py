"""Measured data: file import, registration in a foreign frame, calibration there, model export."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from zrp_ga import app, config, kinematics, measurements, registration, robots
from zrp_ga.layout import Layout
from zrp_ga.problems.measured import data_path
from zrp_ga.robot import ZRPRobot
from zrp_ga.simulation import random_joints, simulate

NOISE = 5e-5  # m, standard deviation per axis of the simulated tracker
TOOL = np.array([0.012, -0.02, 0.105])


def _foreign(rng, kinematic_errors=True):
    """A UR10 with small errors, 3 m away from the instrument and turned, with a probe."""
    arm = robots.get("ur10")
    truth = arm
    if kinematic_errors:
        truth = simulate(arm, Layout(6, base=True), rng, axis_error=0.002, body_error=5e-4).truth
    R = Rotation.from_rotvec([0.3, -1.2, 2.0]).as_matrix()
    t = np.array([0.4, -3.2, -0.9])
    return arm, truth.with_tool(TOOL).transformed(R, t), R, t


def _write(path, q, p, rng, extra=None):
    p = p + rng.normal(scale=NOISE, size=p.shape)
    df = pd.DataFrame(q, columns=[f"q{i}" for i in range(1, 7)])
    df[["x", "y", "z"]] = p * 1e3  # mm
    for k, v in (extra or {}).items():
        df[k] = v
    df.to_csv(path, index=False)
    return p


def test_registration_recovers_base_and_tool_to_the_noise(rng):
    arm, world, R, t = _foreign(rng, kinematic_errors=False)
    q = random_joints(arm, 300, rng)
    _, p = kinematics.forward(world, q)
    reg = registration.register(arm, q, p + rng.normal(scale=NOISE, size=p.shape))
    assert np.degrees(Rotation.from_matrix(reg.R @ R.T).magnitude()) < 1e-3
    assert np.linalg.norm(reg.t - t) < 1e-4 and np.linalg.norm(reg.tool - TOOL) < 1e-4
    assert reg.rms == pytest.approx(NOISE * np.sqrt(3), rel=0.15)  # what is left is the noise


def test_registration_finds_the_tool_rotation_from_measured_orientations(rng):
    arm, world, _, _ = _foreign(rng, kinematic_errors=False)
    turn = Rotation.from_rotvec([0.1, -0.2, np.pi / 2]).as_matrix()  # a probe frame turned on the hand
    q = random_joints(arm, 100, rng)
    R_meas, p = kinematics.forward(world.replace(R_h0=world.R_h0 @ turn), q)
    noisy = Rotation.from_rotvec(rng.normal(scale=1e-4, size=(100, 3))).as_matrix() @ R_meas
    reg = registration.register(arm, q, p, rotations=noisy)
    assert np.degrees(Rotation.from_matrix(reg.tool_rotation @ turn.T).magnitude()) < 0.01
    assert reg.rms_angle < 3e-4
    model = reg.apply(arm)  # the registered model predicts the measured orientations
    R_model, _ = kinematics.forward(model, q)
    assert np.max(Rotation.from_matrix(np.swapaxes(R_model, 1, 2) @ R_meas).magnitude()) < 1e-3


def test_calibration_in_the_instruments_frame_and_the_exported_model(tmp_path, rng):
    arm, world, _, _ = _foreign(rng)
    q_cal, q_val = random_joints(arm, 200, rng), random_joints(arm, 100, rng)
    _write(tmp_path / "cal.csv", q_cal, kinematics.forward(world, q_cal)[1], rng)
    p_val = _write(tmp_path / "val.csv", q_val, kinematics.forward(world, q_val)[1], rng)
    cfg = config.load(["problem=measured", "robot=ur10", "problem.length_unit=mm",
                       f"problem.calibration_file={tmp_path / 'cal.csv'}", f"problem.validation_file={tmp_path / 'val.csv'}",
                       "population.generations=15"])  # fmt: skip
    app.run(cfg, tmp_path / "run")
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    err = s["position_error_mm"]["validation"]
    assert err["nominal"]["rms"] > 1.0  # the kinematic errors show after registration alone
    assert err["calibrated"]["rms"] < 1.5 * NOISE * np.sqrt(3) * 1e3  # calibrated: down to the noise
    model = ZRPRobot.from_yaml(tmp_path / "run" / "calibrated_robot.yaml")  # the export loads back ...
    _, p = kinematics.forward(model, q_val)  # ... and predicts new poses in the instrument's frame
    rms = np.sqrt(np.mean(np.sum((p - p_val) ** 2, axis=1))) * 1e3
    assert rms == pytest.approx(err["calibrated"]["rms"], rel=1e-6)
    assert json.loads((tmp_path / "run" / "registration.json").read_text())["rms_mm"] > 1.0
    poses = pd.read_csv(tmp_path / "run" / "pose_errors.csv")
    assert list(poses.columns) == ["set", "line", "nominal_mm", "calibrated_mm"] and len(poses) == 300
    val = poses[poses["set"] == "validation"]
    assert np.sqrt(np.mean(val["calibrated_mm"] ** 2)) == pytest.approx(err["calibrated"]["rms"], rel=1e-12)
    assert list(val["line"]) == list(range(2, 102))  # the file's lines, header = line 1


def test_validation_split_by_fraction(tmp_path, rng):
    arm, world, _, _ = _foreign(rng)
    q = random_joints(arm, 120, rng)
    _write(tmp_path / "all.csv", q, kinematics.forward(world, q)[1], rng)
    cfg = config.load(["problem=measured", "robot=ur10", "problem.length_unit=mm",
                       f"problem.calibration_file={tmp_path / 'all.csv'}", "problem.validation_fraction=0.25", "algorithm=lm"])  # fmt: skip
    task = app.prepare(cfg, tmp_path / "run").task
    assert task.problem.data.M == 90 and task.judge.validation.M == 30
    assert sorted(np.r_[task.sets["calibration"].lines, task.sets["validation"].lines]) == list(range(2, 122))


def test_the_ur10_files_ship_and_read(tmp_path):
    fmt = measurements.UR10_IPA
    b = measurements.read(data_path("pkg:ur10_ipa/series_b_joint_configurations.csv"), fmt, 6)
    c = measurements.read(data_path("pkg:ur10_ipa/series_c_random_poses.csv"), fmt, 6)
    assert b.q.shape == (1495, 6) and c.q.shape == (2773, 6)
    np.testing.assert_allclose(b.p[0], [0.38376294, -3.2408734, 0.20193157])  # line 2 of the file, mm -> m
    assert b.std is not None and b.R is not None


GOOD = "q1,q2,q3,q4,q5,q6,x,y,z\n0,0,0,0,0,0,1,2,3\n0.1,0.2,0.3,0.4,0.5,0.6,4,5,6\n"


@pytest.mark.parametrize(
    "text, message",
    [
        (GOOD.replace(",z", ",zz"), "missing column 'z'"),
        (GOOD.replace("4,5,6", "4,nan,6"), "line 3, column 'y': 'nan' is not a finite number"),
        (GOOD.replace("4,5,6", "4,five,6"), "line 3, column 'y': 'five' is not a finite number"),
        (GOOD.replace("0,0,0,0,0,0,1", "0,0,0,0,0,,1"), "line 2, column 'q6': empty"),
        ("q1,q2,q3,q4,q5,x,y,z\n0,0,0,0,0,1,2,3\n", "5 joint columns (q1, q2, q3, q4, q5), but the robot has 6 joints"),
    ],
)
def test_bad_files_name_file_line_and_column(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=r"bad\.csv") as info:
        measurements.read(path, measurements.zrp_format(6), 6)
    assert message in str(info.value)


def test_bad_rows_are_dropped_only_when_asked(tmp_path, caplog):
    path = tmp_path / "bad.csv"
    path.write_text(GOOD.replace("4,5,6", "4,five,6"))
    data = measurements.read(path, measurements.zrp_format(6), 6, drop_bad_rows=True)
    assert data.q.shape == (1, 6) and list(data.lines) == [2]
    assert "dropped 1 rows" in caplog.text and "line 3" in caplog.text


def test_bad_file_from_the_command_line_is_one_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text(GOOD.replace("4,5,6", "4,five,6"))
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.app", "problem=measured", "robot=ur10",
                           f"problem.calibration_file={path}", f"hydra.run.dir={tmp_path / 'run'}"],
                          capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 2 and not (tmp_path / "run").exists()
    assert proc.stderr.strip().splitlines() == [
        f"zrp-ga: error: {path}, line 3, column 'y': 'five' is not a finite number; set problem.drop_bad_rows=true to drop such rows"
    ]
