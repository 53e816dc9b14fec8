"""Compensation on the full model (issue 30 item 4): a calibration with a residual model (a
Gaussian process on joint space) solves its inverse kinematics on the parametric model plus the
process's correction, and predicts with it.

The true arm is written here: a UR10 with geometric errors, seen in a tracker's frame, plus a
smooth position error of joints 1 and 2 that no geometric parameter can represent. Calibrated
with ``problem.model=[geometric+gp]``, the program compensated in the tracker's frame is judged
on that true arm (forward kinematics of the arm written here, plus the error written here): the
compensation with the residual model must leave far less error than the same calibration's
parametric model alone (its residual.json removed).
"""

import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import robots
from zrp_ga.compensation import ik
from zrp_ga.model import kinematics
from zrp_ga.model.poses import Measurements
from zrp_ga.model.residual import FILE

ROT = Rotation.from_rotvec([0.05, -0.1, 0.7]).as_matrix()  # the tracker's frame: the arm's base seen from it
SHIFT = np.array([1.5, -0.4, 0.2])
NOISE_M = 1e-5


def bump(q):
    """The non-geometric error (M, 3) m in the tracker's frame: smooth in joints 1 and 2, 0.3-0.4 mm."""
    q1, q2 = q[:, 0], q[:, 1]
    return np.column_stack([3e-4 * np.sin(2 * q1 + 0.5), 2.5e-4 * np.cos(3 * q2), 2e-4 * np.sin(q1) * np.cos(2 * q2)])


@pytest.fixture(scope="module")
def truth():
    rng = np.random.default_rng(30)
    arm = robots.get("ur10").with_tool([0.02, -0.01, 0.12])
    arm = arm.replace(b0=arm.b0 + rng.normal(scale=1e-3, size=arm.b0.shape))  # geometric errors

    def seen(q):  # the true measured point in the tracker's frame
        return kinematics.forward(arm, np.atleast_2d(q))[1] @ ROT.T + SHIFT + bump(np.atleast_2d(q))

    return seen


@pytest.fixture(scope="module")
def runs(truth, tmp_path_factory):
    """One calibration with the residual model, and the same without its residual.json."""
    rng = np.random.default_rng(31)
    d = tmp_path_factory.mktemp("gp")
    q = rng.uniform(-1.2, 1.2, (150, 6))
    data = Measurements(q=q, p=truth(q) + rng.normal(scale=NOISE_M, size=(len(q), 3)), source="tracker")
    cal = zrp_ga.calibrate("ur10", data, algorithm="lm", out=d / "gp", problem={"model": ["geometric+gp"], "length_unit": "m",
                                                                               "use_orientation": False})  # fmt: skip
    shutil.copytree(d / "gp", d / "parametric")
    (d / "parametric" / FILE).unlink()
    return d / "gp", d / "parametric", cal


def test_compensation_with_the_residual_model_brings_the_true_arm_to_the_targets(truth, runs):
    with_gp, parametric, _ = runs
    rng = np.random.default_rng(32)
    q_goal = rng.uniform(-1.0, 1.0, (12, 6))  # inside the calibration poses' ranges
    targets = truth(q_goal)  # where the true arm can go, in the tracker's frame
    program = {"x": targets[:, 0], "y": targets[:, 1], "z": targets[:, 2], **{f"q{i + 1}": q_goal[:, i] + 0.05 for i in range(6)}}
    errors = {}
    for name, run in (("gp", with_gp), ("parametric", parametric)):
        c = zrp_ga.compensate(run, program, kind="cartesian", frame="instrument", tool="calibration", length_unit="m",
                              angle_unit="rad")  # fmt: skip
        assert c.reached.all()
        assert any("residual model" in note for note in c.arms.notes) == (name == "gp")
        errors[name] = np.linalg.norm(truth(c.q) - targets, axis=1) * 1e3  # judged on the true arm, mm
        if name == "gp":  # its predicted sigma: the parametric one and the process's spread in quadrature
            std = zrp_ga.load(with_gp).residual.predict(c.q, std=True)[1]
            parametric_sigma = zrp_ga.load(parametric).predict(c.q).position_mm
            np.testing.assert_allclose(c.predicted["sigma_mm"], np.hypot(parametric_sigma, np.sqrt(3) * std * 1e3), rtol=1e-6)
    bump_mm = np.linalg.norm(bump(q_goal), axis=1)
    rms = {k: float(np.sqrt(np.mean(e**2))) for k, e in errors.items()}
    print(f"compensated error on the true arm, RMS mm: {rms}; the non-geometric error itself: "
          f"{np.sqrt(np.mean(bump_mm**2)) * 1e3:.3f} mm")  # fmt: skip
    assert rms["parametric"] > 0.15  # what the geometric model cannot represent stays
    assert rms["gp"] < 0.3 * rms["parametric"] and rms["gp"] < 0.05


def test_the_corrected_solve_meets_its_own_model_and_the_parametric_one_does_not(runs):
    """The fixed-point iteration ends where parametric model + correction hit the target."""
    cal = zrp_ga.load(runs[0])
    arm, gp = cal.robot, cal.residual  # the instrument-frame model and its process
    assert gp is not None
    q0 = np.array([0.3, -0.5, 0.8, 0.1, 0.6, -0.2])
    target = kinematics.forward(arm, q0[None])[1][0] + gp.predict(q0[None])[0] + np.array([2e-3, -1e-3, 1e-3])
    s = ik.solve(arm, target, None, q0, correction=lambda q: gp.predict(q[None])[0])
    full = kinematics.forward(arm, s.q[None])[1][0] + gp.predict(s.q[None])[0]
    assert s.reached and np.linalg.norm(full - target) < 1e-6
    plain = ik.solve(arm, target, None, q0)
    assert np.linalg.norm(kinematics.forward(arm, plain.q[None])[1][0] + gp.predict(plain.q[None])[0] - target) > 1e-5


def test_prediction_and_its_sigma_carry_the_residual_model(truth, runs):
    cal, plain = zrp_ga.load(runs[0]), zrp_ga.load(runs[1])
    rng = np.random.default_rng(33)
    q = rng.uniform(-1.0, 1.0, (20, 6))
    err = lambda c: np.linalg.norm(c.predict(q, tool=0, frame="measurements").p - truth(q), axis=1)
    assert np.sqrt(np.mean(err(cal) ** 2)) < 0.3 * np.sqrt(np.mean(err(plain) ** 2))
    gp_std = cal.residual.predict(q, std=True)[1]
    s_gp, s_plain = cal.predict(q).position_mm, plain.predict(q).position_mm
    np.testing.assert_allclose(s_gp, np.hypot(s_plain, np.sqrt(3) * gp_std * 1e3), rtol=1e-9)
    far = np.full((1, 6), 3.0)  # beyond every calibration pose: the process's prior spread counts
    assert cal.predict(far).position_mm[0] > plain.predict(far).position_mm[0] + 0.1


def test_the_calibration_in_memory_predicts_as_the_one_read_back(runs):
    q = np.random.default_rng(34).uniform(-1.0, 1.0, (5, 6))
    in_memory, back = runs[2].predict(q), zrp_ga.load(runs[0]).predict(q)
    assert runs[2].residual is not None
    np.testing.assert_allclose(in_memory.p, back.p, rtol=0, atol=1e-9)
    np.testing.assert_allclose(in_memory.position_mm, back.position_mm, rtol=1e-6)


def test_the_run_pose_table_predicts_with_the_residual_model_spread(runs):
    import pandas as pd

    cal, plain = zrp_ga.load(runs[0]), zrp_ga.load(runs[1])
    rows = pd.read_csv(runs[0] / "pose_errors.csv")
    rows = rows[rows["set"] == "calibration"]
    q = cal.residual.q[rows["line"].to_numpy() - rows["line"].min()]  # the calibration poses, in their order
    spread = np.sqrt(3) * cal.residual.predict(q, std=True)[1] * 1e3
    np.testing.assert_allclose(rows["predicted_mm"], np.hypot(plain.predict_error(q)["position_mm"], spread), rtol=1e-6)
