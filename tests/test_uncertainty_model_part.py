"""The model's part of the predicted error (zrp_ga.model.uncertainty, ``noise=False``) against
the calibrated model's actual error: the distance to the true arm at validation poses measured
without noise. The end-to-end check (test_identified's predicted against measured validation
RMS) adds the noise (3 sigma^2, most of the total on that problem) to both sides, which hides a
covariance off by a factor of two."""

from __future__ import annotations

import numpy as np
from test_identified import tracker_problem

from zrp_ga.core.schema import SimulatedConf
from zrp_ga.model import metrics, simulation
from zrp_ga.problems import identify
from zrp_ga.problems.least_squares import levenberg_marquardt


def test_the_predicted_model_error_is_the_distance_to_the_true_arm():
    ratios = []
    for seed in range(8):
        robot, sim, problem, prior = tracker_problem(20 + seed, M=40)
        problem, setup = identify.prepare(problem, prior, 2.0, SimulatedConf())
        z = levenberg_marquardt(problem).x
        unc = identify.uncertainty(problem, z, setup)
        q = sim.validation.q
        exact = simulation.measure(sim.truth, q, np.random.default_rng(0))  # no noise: the true arm's points
        actual = np.sqrt(np.mean(metrics.position_errors(problem.layout, robot, z, exact) ** 2))
        ratios.append(actual / unc.predicted_rms_m(q, noise=False))
    assert 0.8 < np.mean(ratios) < 1.25, ratios
