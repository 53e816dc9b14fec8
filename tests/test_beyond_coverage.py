"""A calibration whose poses leave joints still says how far off it may be away from them: the
predicted error across the joint limits (``summary.json``'s uncertainty.across_joint_limits_mm)
and a warning when it exceeds the nominal arm's error where the calibration measured, naming
the joints that barely moved; none for a calibration whose poses move every joint."""

from __future__ import annotations

import numpy as np
import pytest

import zrp_ga
from zrp_ga import kinematics
from zrp_ga.model import simulation
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot

NOISE_M = 3e-5


def _arm() -> ZRPRobot:
    """A made-up 6R arm (not one of the experiments'), a tool 40, -30, 80 mm off the flange."""
    tool = np.eye(4)
    tool[:3, 3] = [0.04, -0.03, 0.08]
    return ZRPRobot.from_dh(d=[0.40, 0.0, 0.0, 0.55, 0.0, 0.09], a=[0.12, 0.50, 0.10, 0.0, 0.0, 0.0],
                            alpha=[-np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0],
                            offset=[0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0], tool=tool, name="test arm")  # fmt: skip


def _data(held: tuple[int, ...], seed: int):
    rng = np.random.default_rng(seed)
    robot = _arm()
    truth = simulation.true_robot(robot, Layout(robot.n, base=True), rng, axis_error=0.002, body_error=0.001)

    def poses(M: int, still: tuple[int, ...]) -> np.ndarray:
        q = rng.uniform(-np.pi, np.pi, (M, robot.n))
        q[:, list(still)] = [-0.4, 0.8][: len(still)]
        return q

    measure = lambda q: simulation.measure(truth, q, rng, joint_noise=0.0, position_noise=NOISE_M, position_only=True)
    return robot, truth, measure(poses(60, held)), measure(poses(100, held)), poses(300, ())


@pytest.mark.parametrize("seed", [5, 9])
def test_held_joints_warn_that_the_model_holds_only_where_it_was_measured(seed):
    robot, truth, cal, same, anywhere = _data((1, 4), seed)  # joints 2 and 5 held
    c = zrp_ga.calibrate(robot, cal, validation=same, algorithm="lm", seed=seed)
    s = c.summary
    across, nominal = s["uncertainty"]["across_joint_limits_mm"], s["uncertainty"]["predicted_model_rms_mm"]["nominal"]
    assert across["narrow_joints"] == [2, 5]
    assert s["validation_rms_mm"]["calibrated"] < 2 * np.sqrt(3) * NOISE_M * 1e3  # at the noise where it was measured
    assert across["total_rms"] > nominal
    warned = [w for w in s["warnings"] if w.startswith("away from its calibration poses")]
    assert len(warned) == 1 and "joints 2, 5 barely moved" in warned[0] and f"{across['total_rms']:.3g} mm" in warned[0]
    # not an empty alarm: the model's distance to the simulation's true arm (forward kinematics,
    # written here) across the joint limits is many times its error where it was measured, and
    # of the predicted size or less
    _, p_true = kinematics.forward(truth, anywhere)
    actual = float(np.sqrt(np.mean(np.sum((c.predict(anywhere).p - p_true) ** 2, axis=1)))) * 1e3
    assert actual > 10 * s["validation_rms_mm"]["calibrated"]
    assert actual < 1.5 * across["total_rms"]

def test_a_calibration_that_moves_every_joint_does_not_warn():
    robot, _, cal, same, _ = _data((), 5)
    s = zrp_ga.calibrate(robot, cal, validation=same, algorithm="lm", seed=5).summary
    across, nominal = s["uncertainty"]["across_joint_limits_mm"], s["uncertainty"]["predicted_model_rms_mm"]["nominal"]
    assert across["narrow_joints"] == [] and across["total_rms"] < 0.1 * nominal
    assert not [w for w in s["warnings"] if w.startswith("away from its calibration poses")]


@pytest.mark.parametrize("algorithm", ["lm", "ga"])
def test_a_perfect_arm_is_not_predicted_worse_than_itself_from_round_off(algorithm):
    """Data of the nominal arm itself: the nominal's model error and cost are 0 to round-off, and
    so are the fit's (about 1e-14 mm, costs 5.7e-16 against 3.7e-16 with the GA); no "worse"
    warning and no nominal arm returned for it."""
    robot = _arm()
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (40, 6))
    _, p = kinematics.forward(robot, q)
    deg, mm = np.degrees(q), 1e3 * p  # a tuple of arrays reads as degrees and millimetres
    s = zrp_ga.calibrate(robot, (deg[:30], mm[:30]), validation=(deg[30:], mm[30:]), algorithm=algorithm, seed=1).summary
    assert s["returned"] == "optimiser"
    assert not [w for w in s["warnings"] if "worse" in w or "away from its calibration" in w], s["warnings"]


def test_the_warning_beyond_the_coverage_is_about_a_returned_model():
    """CMA-ES on the perfect arm's data ends off the floor (its model worse than the nominal on
    validation): the nominal arm is returned, and no warning describes the model not returned."""
    robot = _arm()
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (40, 6))
    _, p = kinematics.forward(robot, q)
    deg, mm = np.degrees(q), 1e3 * p
    s = zrp_ga.calibrate(robot, (deg[:30], mm[:30]), validation=(deg[30:], mm[30:]), algorithm="cmaes", seed=1).summary
    assert s["returned"] == "nominal"
    assert not [w for w in s["warnings"] if "away from its calibration" in w], s["warnings"]
