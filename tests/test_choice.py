"""Model choice (zrp_ga.problems.choice): the candidates' fixed order, the fold scheme picked by
the targets' joint ranges (constructed here), the simplest candidate among near-equals, and a
choice that never reads the validation data's measured points (poisoned rows leave it as it was)."""

import dataclasses

import numpy as np
import pytest

from zrp_ga import robots
from zrp_ga.core.schema import MeasuredConf
from zrp_ga.model import kinematics
from zrp_ga.model.poses import Measurements
from zrp_ga.problems import choice, measured

TERMS = {"compliance": [2, 3]}


def test_candidates_come_in_a_fixed_order():
    assert [c.name for c in choice.candidates("auto")] == ["geometric", "geometric+gp"]
    auto = choice.candidates("auto", TERMS)
    assert [(c.name, c.terms, c.residual) for c in auto] == [
        ("geometric", None, False), ("geometric+gp", None, True), ("terms", TERMS, False), ("terms+gp", TERMS, True)]  # fmt: skip
    listed = choice.candidates(["terms+gp", "geometric"], TERMS)
    assert [c.name for c in listed] == ["terms+gp", "geometric"]  # a list: as given
    assert [c.name for c in choice.candidates("geometric", TERMS)] == ["geometric"]


@pytest.mark.parametrize("model, match", [("best", "expected auto"), (["geometric", "gp"], "unknown candidate 'gp'"),
                                          (["terms"], "needs problem.terms"), ([], "empty"),
                                          (["geometric", "geometric"], "named twice")])  # fmt: skip
def test_bad_model_settings_are_one_line(model, match):
    with pytest.raises(ValueError, match=match):
        choice.candidates(model)


def test_a_simpler_candidate_within_the_tolerance_is_chosen():
    rows = lambda *cv: [{"name": f"c{i}", "cv_rms_mm": v} for i, v in enumerate(cv)]
    assert choice.choose(rows(1.00, 0.70, 0.69))[0] == 1  # 0.70 <= 0.69 x 1.02: the earlier one
    assert choice.choose(rows(1.00, 0.80, 0.69))[0] == 2
    assert choice.choose(rows(0.50, 0.50, 0.40))[0] == 2
    assert choice.choose(rows(0.50, float("nan"), 0.52))[0] == 0  # a failed candidate never wins


def test_targets_inside_the_ranges_give_random_folds_covering_every_pose(rng):
    q = rng.uniform(-1, 1, (200, 3))
    f = choice.folds(q, rng.uniform(-0.9, 0.9, (50, 3)), k=5)
    assert f.scheme == "random" and f.warning is None and len(f.held) == 5
    assert sorted(np.concatenate(f.held).tolist()) == list(range(200))  # a partition


def test_targets_beyond_a_joint_range_give_its_extreme_range_folds_and_a_warning(rng):
    q = rng.uniform(-1, 1, (300, 3))
    lo, hi = q.min(axis=0), q.max(axis=0)
    targets = rng.uniform(-0.9, 0.9, (100, 3))
    targets[:40, 1] = rng.uniform(hi[1] + 0.1, hi[1] + 0.5, 40)  # joint 2 beyond its upper end for 40% of them
    targets[40:50, 2] = lo[2] - 0.2  # joint 3 beyond its lower end for 10%
    targets[50:52, 0] = hi[0] + 1.0  # joint 1: 2%, under the 5% that make a fold
    f = choice.folds(q, targets)
    assert f.scheme == "extremes"
    assert "extrapolat" in f.warning and "joint 2 high" in f.warning and "joint 3 low" in f.warning
    assert len(f.held) == 2
    expected_2 = np.flatnonzero(q[:, 1] >= hi[1] - 0.2 * (hi[1] - lo[1]))  # the top 20% of joint 2's range, by hand
    expected_3 = np.flatnonzero(q[:, 2] <= lo[2] + 0.2 * (hi[2] - lo[2]))
    np.testing.assert_array_equal(f.held[0], expected_2)
    np.testing.assert_array_equal(f.held[1], expected_3)


def _measured(rng, M, arm):
    """Positions of a UR10 with a smooth error no geometric parameter explains (0.3 mm, joint 2)."""
    q = rng.uniform(-1.2, 1.2, (M, 6))
    p = kinematics.forward(arm, q)[1]
    p = p + np.column_stack([3e-4 * np.sin(3 * q[:, 1]), 2e-4 * np.cos(2 * q[:, 2]), np.zeros(M)])
    return Measurements(q, p + rng.normal(scale=2e-5, size=p.shape), source="synthetic")


def test_the_choice_never_reads_the_validation_points(rng, monkeypatch):
    arm = robots.get("ur10").with_tool([0.0, 0.0, 0.1])
    calib, val = _measured(rng, 60, arm), _measured(rng, 30, arm)
    poisoned = dataclasses.replace(val, p=val.p + rng.normal(scale=0.5, size=val.p.shape))  # every row off by ~0.5 m
    c = MeasuredConf(calibration_file="synthetic", model=["geometric", "geometric+gp"], use_orientation=False)
    seen = []
    real = measured.refit

    def recording(robot, conf):
        fit = real(robot, conf)

        def wrapped(data, terms):
            seen.append(data.p.copy())
            return fit(data, terms)

        return wrapped

    monkeypatch.setattr(measured, "refit", recording)
    clean = measured.chosen(robots.get("ur10"), calib, val, c).info["model"]
    dirty = measured.chosen(robots.get("ur10"), calib, poisoned, c).info["model"]
    assert clean == dirty  # the same folds, table, choice and reason
    assert clean["chosen"] == "geometric+gp"  # the smooth error is what the residual model is for
    for p in seen:  # every fold fitted calibration rows only
        assert len(p) < calib.M and all(np.any(np.all(np.isclose(calib.p, row), axis=1)) for row in p)


def test_a_run_with_a_residual_model_writes_it_and_validates_with_it(rng, tmp_path):
    """The run's validation RMS is that of the instrument-frame model it writes plus the residual
    model read back from residual.json, recomputed here from the files."""
    import json

    import pandas as pd

    from zrp_ga import config
    from zrp_ga.io.robot_files import read_robot
    from zrp_ga.model.residual import Residual
    from zrp_ga.run import execute

    arm = robots.get("ur10").with_tool([0.0, 0.0, 0.1])
    arm = arm.replace(b0=arm.b0 + rng.normal(scale=1e-3, size=arm.b0.shape))  # geometric errors as well
    for name, M in (("cal", 80), ("val", 40)):
        m = _measured(rng, M, arm)
        df = pd.DataFrame(m.q, columns=[f"q{i}" for i in range(1, 7)])
        df[["x", "y", "z"]] = m.p
        df.to_csv(tmp_path / f"{name}.csv", index=False)
    over = ["problem=measured", "robot=ur10", f"problem.calibration_file={tmp_path / 'cal.csv'}", "problem.length_unit=m",
            f"problem.validation_file={tmp_path / 'val.csv'}", "algorithm=lm", "progress=false",
            "problem.model=[geometric,geometric+gp]"]  # fmt: skip
    execute.run(config.load(over), tmp_path / "run")
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["problem"]["model"]["chosen"] == "geometric+gp" and len(s["problem"]["model"]["cross_validation"]) == 2
    gp = Residual.read(tmp_path / "run")
    val = pd.read_csv(tmp_path / "val.csv")
    q, p = val[[f"q{i}" for i in range(1, 7)]].to_numpy(), val[["x", "y", "z"]].to_numpy()
    model = read_robot(tmp_path / "run" / measured.INSTRUMENT_MODEL)
    predicted = kinematics.forward(model, q)[1] + gp.predict(q)
    rms_mm = np.sqrt(np.mean(np.sum((p - predicted) ** 2, axis=1))) * 1e3
    assert s["validation_rms_mm"]["calibrated"] == pytest.approx(rms_mm, rel=1e-6)
    geometric = np.sqrt(np.mean(np.sum((p - kinematics.forward(model, q)[1]) ** 2, axis=1))) * 1e3
    assert rms_mm < 0.5 * geometric  # the residual model does the work here
