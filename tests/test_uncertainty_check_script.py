"""experiments/uncertainty_check.py's measured cases run as the command line runs them
(``measured``): its call into the run layer broke when ``execute`` took a sweep as its third
argument. The own_arm case (about a second) is checked against the file itself: the measured
validation RMS is the one the run reports, the prediction within a factor of 1.5 of it."""

from __future__ import annotations

import logging
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "experiments"))
import uncertainty_check


def test_the_measured_cases_run_and_predict_their_validation_error():
    robot, calibration, settings = uncertainty_check.MEASURED["own_arm, same tracker position"]
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = uncertainty_check.measured(robot, calibration, settings)
    finally:
        logging.disable(logging.NOTSET)
    predicted, measured, ratio, outside, noise = uncertainty_check.row(s)
    assert np.isclose(measured, s["validation_rms_mm"]["calibrated"]) and np.isclose(ratio, measured / predicted)
    assert 1 / 1.5 < ratio < 1.5 and 0.0 <= outside <= 1.0 and noise > 0
