"""What a run says about how far it can be trusted (issue 29), through zrp_ga.calibrate and the
files it writes: the predicted errors from a run directory equal the calibration's own, a
model predicted worse than the nominal arm is not returned, measured orientations are fitted
when the file has them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga.io import presets
from zrp_ga.model import coverage, kinematics, simulation, uncertainty
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.run import summary as run_summary


def test_a_run_directory_predicts_what_the_calibration_predicts(tmp_path, rng):
    cal = zrp_ga.calibrate("puma560", algorithm="lm", out=tmp_path / "run",
                           problem={"n_poses": 30, "cost": "nonlinear", "position_noise": 5e-5, "joint_noise": 0.0001})  # fmt: skip
    q = np.vstack([cal.task.problem.data.q[:4], simulation.random_joints(presets.get("puma560"), 4, rng)])
    q[-1, 0] = 9.0  # beyond every calibrated range
    mine = cal.predict_error(q)
    np.testing.assert_allclose(uncertainty.predict_error_mm(tmp_path / "run", q), mine["position_mm"], rtol=1e-12)
    where = coverage.assess_targets(tmp_path / "run", q)
    assert where.outside.tolist() == mine["outside"].tolist() and not where.outside[:4].any() and where.outside[-1]
    assert np.all(mine["position_mm"] >= mine["position_identified_mm"])
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert set(s["uncertainty"]["standard_errors"]) == set(s["best_genome"])
    line = run_summary.uncertainty_line(s)
    v = s["uncertainty"]["validation_rms_mm"]
    assert line.startswith("uncertainty: +-") and f"validation RMS predicted {v['predicted']:.4g} mm, measured {v['measured']:.4g} mm" in line
    assert f"{s['identified']['rank']} of {s['identified']['combinations']} combinations identified" in line


def test_a_model_predicted_worse_than_the_nominal_arm_is_not_returned(rng):
    """The nominal arm is the truth: the data say so (the nominal residual is the noise), and any
    calibration can only add estimation noise; without validation poses, the prediction decides."""
    arm = presets.get("ur10")
    q = simulation.random_joints(arm, 40, rng)
    data = Measurements(q, kinematics.forward(arm, q)[1] + rng.normal(scale=1e-4, size=(40, 3)))
    s = zrp_ga.calibrate(arm, data, algorithm="lm").summary
    pred = s["uncertainty"]["predicted_model_rms_mm"]
    assert pred["calibrated"] > pred["nominal"] and s["returned"] == "nominal"
    assert any("predicted to be worse than the nominal one over its own coverage" in w and "returned instead" in w for w in s["warnings"])
    kept = zrp_ga.calibrate(arm, data, algorithm="lm", problem={"if_worse": "keep"}).summary
    assert kept["returned"] == "optimiser"


def test_measured_orientations_are_fitted_when_the_file_states_them(tmp_path, rng):
    arm = presets.get("ur10")
    truth = simulation.true_robot(arm, Layout(6, base=True, hand=True), rng, axis_error=0.002, body_error=0.001)
    q = simulation.random_joints(arm, 40, rng)
    R, p = kinematics.forward(truth, q)
    angles = Rotation.from_matrix(R).as_euler("XYZ")
    cols = {**{f"q{i + 1}": q[:, i] for i in range(6)}, "x": p[:, 0], "y": p[:, 1], "z": p[:, 2],
            "rx": angles[:, 0], "ry": angles[:, 1], "rz": angles[:, 2]}  # fmt: skip
    import pandas as pd

    pd.DataFrame(cols).to_csv(tmp_path / "cal.csv", index=False)
    with pytest.raises(ValueError, match="problem.orientation_convention: .*cal.csv has orientation columns"):
        zrp_ga.calibrate(arm, tmp_path / "cal.csv", algorithm="lm")
    stated = zrp_ga.calibrate(arm, tmp_path / "cal.csv", algorithm="lm", problem={"orientation_convention": "XYZ"})
    left_out = zrp_ga.calibrate(arm, tmp_path / "cal.csv", algorithm="lm", problem={"use_orientation": False})
    assert stated.task.info["use_orientation"] and not left_out.task.info["use_orientation"]
    assert stated.task.layout.hand and not stated.task.problem.data.position_only and left_out.task.problem.data.position_only
