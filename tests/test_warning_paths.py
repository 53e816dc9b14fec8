"""The warnings users meet on measured data, each produced and its numbers checked, and
``zrp_ga.calibrate`` on measured data judged against errors known before it runs.

- a calibration on exact calibration points of a perturbed arm: the validation error drops from
  the registered nominal arm's (computed here with a registration written in this file) to the
  validation points' own noise (known: it was added here), by the ratio of the two;
- validation worse than nominal: calibration points of the nominal arm itself, few and noisy, so
  that the calibrated model fits their noise and predicts new points worse than the nominal arm;
  the warning gives both RMS values, and the optimiser's result is kept (the nominal arm is
  returned only when the calibration data are fitted worse, ``zrp_ga.run.summary``);
- registration far off: a joint's zero position wrong in the file; the warning names the worst
  line and the 2% of the reach;
- the optimiser diverged: a result without a finite cost gives the warning and the nominal arm.
  A GA or CMA-ES run whose every cost is NaN ends there too.
"""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import robots
from zrp_ga.algorithms import Result
from zrp_ga.model import kinematics
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.simulation import random_joints, true_robot
from zrp_ga.run import summary

FRAME = (Rotation.from_rotvec([-0.5, 0.8, 2.2]).as_matrix(), np.array([2.1, 0.4, -0.7]))
TOOL = np.array([0.015, 0.03, 0.08])
NOISE = 2e-5  # m per axis, on the validation points


def _points(arm, q):
    """Positions (M, 3) of TOOL on ``arm`` at q, in FRAME."""
    return kinematics.forward(arm.with_tool(TOOL).transformed(*FRAME), q)[1]


def _register(arm, q, P):
    """Base transform and tool offset fitting ``arm`` to points P in the least-squares sense,
    written here: x = (rotation vector, translation, tool offset), started from the truth's
    neighbourhood-free guess of a Kabsch fit of the hand's end points."""
    F, f = kinematics.forward(arm, q)
    rot, _ = Rotation.align_vectors(P - P.mean(axis=0), f - f.mean(axis=0))
    x0 = np.concatenate([rot.as_rotvec(), P.mean(axis=0) - rot.apply(f.mean(axis=0)), np.zeros(3)])

    def predict(x, F, f):
        return Rotation.from_rotvec(x[:3]).apply(f + F @ x[6:]) + x[3:6]

    x = least_squares(lambda x: (predict(x, F, f) - P).ravel(), x0, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    return lambda q2: predict(x, *kinematics.forward(arm, q2)), np.linalg.norm(predict(x, F, f) - P, axis=1)


def _rms(e):
    return float(np.sqrt(np.mean(np.sum(np.atleast_2d(e) ** 2, axis=-1))))


@pytest.fixture(scope="module")
def perturbed():
    """A UR10 with 2 mrad axis and 0.5 mm body errors, 60 exact calibration points and 40
    validation points with NOISE, the nominal arm, and the validation noise."""
    rng = np.random.default_rng(19)
    arm = robots.get("ur10")
    truth = true_robot(arm, Layout(6, base=True), rng, axis_error=0.002, body_error=5e-4)
    q, qv = random_joints(arm, 60, rng), random_joints(arm, 40, rng)
    noise = rng.normal(scale=NOISE, size=(40, 3))
    return arm, Measurements(q, _points(truth, q)), Measurements(qv, _points(truth, qv) + noise), noise


def test_calibrate_on_measured_data_brings_the_validation_error_down_to_the_noise(perturbed):
    arm, cal, val, noise = perturbed
    predict, _ = _register(arm, cal.q, cal.p)
    nominal_rms = _rms(predict(val.q) - val.p)  # the registered nominal arm on the validation points
    noise_rms = _rms(noise)  # what an exact model leaves
    assert nominal_rms > 30 * noise_rms  # the kinematic errors show
    c = zrp_ga.calibrate(arm, cal, validation=val, algorithm="lm")
    s = c.summary
    assert s["returned"] == "optimiser" and s["warnings"] == []
    assert s["validation_rms_mm"]["nominal"] == pytest.approx(nominal_rms * 1e3, rel=1e-6)
    assert s["validation_rms_mm"]["calibrated"] == pytest.approx(noise_rms * 1e3, rel=1e-4)
    factor = s["validation_rms_mm"]["nominal"] / s["validation_rms_mm"]["calibrated"]
    assert factor == pytest.approx(nominal_rms / noise_rms, rel=1e-4)
    # the calibrated arm (in the instrument's frame) predicts the validation points up to their noise
    np.testing.assert_allclose(kinematics.forward(c.robot, val.q)[1], val.p - noise, atol=1e-8)
    assert s["final_cost"] < 1e-9 < s["nominal_cost"]


def test_validation_worse_than_nominal_is_warned_with_both_rms(tmp_path):
    rng = np.random.default_rng(5)
    arm = robots.get("ur10")
    q, qv = random_joints(arm, 14, rng), random_joints(arm, 40, rng)  # 14 points: just enough for the model
    cal = Measurements(q, _points(arm, q) + rng.normal(scale=2e-3, size=(14, 3)))  # the nominal arm is the truth
    val = Measurements(qv, _points(arm, qv) + rng.normal(scale=2e-3, size=(40, 3)))
    kept = zrp_ga.calibrate(arm, cal, validation=val, algorithm="lm", problem={"if_worse": "keep"}).summary
    rms = kept["validation_rms_mm"]
    assert kept["final_cost"] < kept["nominal_cost"] and rms["calibrated"] > rms["nominal"]  # the noise fitted
    predict, _ = _register(arm, q, cal.p)
    assert rms["nominal"] == pytest.approx(_rms(predict(qv) - val.p) * 1e3, rel=1e-6)
    expected = (f"the calibrated model predicts the validation poses worse than the nominal one "
                f"(RMS {rms['calibrated']:.4g} mm > {rms['nominal']:.4g} mm)")  # fmt: skip
    assert expected in kept["warnings"] and kept["returned"] == "optimiser"  # problem.if_worse=keep: kept
    s = zrp_ga.calibrate(arm, cal, validation=val, algorithm="lm").summary  # measured data: the nominal arm by default
    assert s["returned"] == "nominal" and s["validation_rms_mm"]["calibrated"] == s["validation_rms_mm"]["nominal"]
    assert expected + "; the nominal arm is returned instead" in s["warnings"]


def _far_off_file(tmp_path):
    """A UR10 file whose joint 2 values are 0.2 rad off the robot file's zero (mm, rad), its
    joint values as written, and the points."""
    rng = np.random.default_rng(7)
    arm = robots.get("ur10")
    q = random_joints(arm, 40, rng)
    wrong = q.copy()
    wrong[:, 1] += 0.2
    df = pd.DataFrame(wrong, columns=[f"q{i}" for i in range(1, 7)])
    df[["x", "y", "z"]] = _points(arm, q) * 1e3
    df.to_csv(tmp_path / "cal.csv", index=False)
    return tmp_path / "cal.csv", wrong, _points(arm, q)


def _far_warning(arm, wrong, P):
    """The far-registration warning's text from a registration written here (line = row + 2)."""
    _, errors = _register(arm, wrong, P)
    reach = float(np.linalg.norm(arm.b0[1:], axis=1).sum())
    rms = _rms(errors[:, None])
    assert rms > 0.02 * reach  # far, by the hand fit
    worst = int(np.argmax(errors))
    return (f"the registered nominal {arm.name} is {rms * 1e3:.4g} mm RMS off the calibration points (more than 2% of its "
            f"{reach:.3g} m reach; worst: line {worst + 2}, {errors[worst] * 1e3:.4g} mm)")  # fmt: skip


def test_registration_far_off_names_the_worst_line_and_the_share_of_the_reach(tmp_path):
    arm = robots.get("ur10")
    path, wrong, P = _far_off_file(tmp_path)
    c = zrp_ga.calibrate(arm, path, algorithm="lm")
    (far,) = [w for w in c.summary["warnings"] if "off the calibration points" in w]
    assert far.startswith(_far_warning(arm, wrong, P)) and far.endswith("(read as mm and rad)")


def test_registration_far_off_on_the_command_line(tmp_path):
    arm = robots.get("ur10")
    path, wrong, P = _far_off_file(tmp_path)
    run = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "problem=measured", "robot=ur10", f"problem.calibration_file={path}",
                           "algorithm=lm", "progress=false", f"hydra.run.dir={run}"], capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    expected = _far_warning(arm, wrong, P)
    assert expected in proc.stdout + proc.stderr  # on the console
    assert any(w.startswith(expected) for w in json.loads((run / "summary.json").read_text())["warnings"])


def test_a_diverged_result_gives_the_warning_and_the_nominal_arm(perturbed):
    arm, cal, val, _ = perturbed
    task = zrp_ga.calibrate(arm, cal, validation=val, algorithm="lm").task
    nominal = float(task.problem.costs(np.zeros(task.problem.layout.size))[0])
    for x, cost in ((None, np.inf), (np.full(task.problem.layout.size, 0.01), np.nan)):
        result = Result(x, cost, 10, "", np.zeros((1, task.problem.layout.size)), np.array([cost]))
        j, genome = summary.judged(task, result)
        assert f"the optimiser diverged: its best cost is {cost}; the nominal arm is returned instead" in j["warnings"]
        assert j["returned"] == "nominal" and j["final_cost"] == nominal and not genome.any()
        assert j["validation_rms_mm"]["calibrated"] == j["validation_rms_mm"]["nominal"]


def _all_nan(monkeypatch):
    """Every genome but the nominal one breaks the model (NaN cost)."""
    costs = CalibrationProblem.costs

    def broken(self, X):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.where(np.any(X != 0, axis=1), np.nan, costs(self, X))

    monkeypatch.setattr(CalibrationProblem, "costs", broken)


def test_a_ga_whose_every_cost_is_nan_ends_with_the_diverged_warning(perturbed, monkeypatch):
    arm, cal, val, _ = perturbed
    _all_nan(monkeypatch)
    s = zrp_ga.calibrate(arm, cal, validation=val, population={"mu": 6, "lambda_": 6, "generations": 2}, refine="none").summary
    assert s["returned"] == "nominal" and any(w.startswith("the optimiser diverged") for w in s["warnings"])


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # cma, on the NaN costs
def test_cmaes_whose_every_cost_is_nan_ends_with_the_diverged_warning(perturbed, monkeypatch):
    arm, cal, val, _ = perturbed
    _all_nan(monkeypatch)
    s = zrp_ga.calibrate(arm, cal, validation=val, algorithm="cmaes").summary
    assert s["returned"] == "nominal" and any(w.startswith("the optimiser diverged") for w in s["warnings"])
