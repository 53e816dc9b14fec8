"""The held-joint example of issue 29 (experiments/held_joints.py), judged on the model the
optimiser found (``problem.if_worse=keep``), not on what the run returns: by default a model
worse than nominal on the validation poses is replaced by the nominal arm, so a check of the
returned model's error anywhere against 1.1 x the nominal arm's cannot fail."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import zrp_ga

sys.path.insert(0, str(Path(__file__).parent.parent / "experiments"))
import held_joints


@pytest.mark.parametrize("algorithm", ["lm", "ga", pytest.param("cmaes", marks=pytest.mark.slow)])
def test_the_identified_model_itself_holds_anywhere_and_fits_the_region_to_the_noise(algorithm):
    """Seed 3 of the committed example: the identified model 0.78 x the nominal arm's error
    anywhere (experiments/results/held_joints.md); with every parameter free, 7-25 x. CMA-ES
    (400 generations, as the script runs it) is marked slow."""
    robot = held_joints.arm()
    cal, same, anywhere = held_joints.data(robot, 3)
    keep = {"problem": {"if_worse": "keep"}, **({"population": {"generations": 400}} if algorithm == "cmaes" else {})}
    a = zrp_ga.calibrate(robot, cal, validation=anywhere, algorithm=algorithm, seed=3, **keep).summary
    s = zrp_ga.calibrate(robot, cal, validation=same, algorithm=algorithm, seed=3, **keep).summary
    assert a["returned"] == "optimiser" and s["returned"] == "optimiser"
    v_any, v_same = a["validation_rms_mm"], s["validation_rms_mm"]
    assert v_any["calibrated"] < 1.1 * v_any["nominal"], v_any
    assert v_same["calibrated"] < 1.5 * np.sqrt(3) * held_joints.NOISE_M * 1e3, v_same
