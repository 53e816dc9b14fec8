"""Registration's numbers against hand computations: the RMS and the largest distance of the
points it leaves, on made-up points with a known rigid transform, tool offset and residuals;
the two "far" rules at their boundaries (a measured point farther from the others than the arm
can carry a tool: refused; a registered nominal arm off the points by more than 2% of its reach:
a warning), each just inside and just outside.

The residuals are made orthogonal to every direction the fit can move (rotation, translation,
tool offset, by the Jacobian of the model ``P_i = R (f_i + F_i d) + t`` written here): the true
transform is then an exact stationary point of the least squares, and the distances the
registration leaves are the residuals' lengths, known before it runs.
"""

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import robots
from zrp_ga.io import measurements
from zrp_ga.model import kinematics
from zrp_ga.model.poses import Measurements
from zrp_ga.model.registration import Registration, register
from zrp_ga.model.simulation import random_joints

R_TRUE = Rotation.from_rotvec([0.4, -0.9, 1.7]).as_matrix()
T_TRUE = np.array([1.2, -2.5, 0.3])
TOOL = np.array([0.02, -0.01, 0.09])


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _points_with_residuals(arm, q, scale, rng):
    """Measured points (M, 3) of ``arm`` with TOOL in the frame (R_TRUE, T_TRUE), plus
    residuals (M, 3) that no rotation, translation or tool offset can explain, of RMS length
    ``scale`` and lengths that differ from point to point (so that RMS and mean differ)."""
    F, f = kinematics.forward(arm, q)
    X = (f + F @ TOOL) @ R_TRUE.T  # R (f + F d), before the translation
    J = np.concatenate([np.stack([-_skew(x) for x in X]), np.broadcast_to(np.eye(3), (len(q), 3, 3)), R_TRUE @ F], axis=2)
    J = J.reshape(-1, 9)  # d(point)/d(small rotation, translation, tool offset), 3M x 9
    e0 = rng.normal(size=(len(q), 3)) * (1 + 4 * (np.arange(len(q)) % 5 == 0))[:, None]  # every fifth point 5x
    e = e0.ravel() - J @ np.linalg.lstsq(J, e0.ravel(), rcond=None)[0]  # orthogonal to the fit's moves
    e = e.reshape(-1, 3)
    e *= scale / np.sqrt(np.mean(np.sum(e**2, axis=1)))
    return X + T_TRUE + e, e


def test_rms_and_max_of_given_distances():
    reg = Registration(np.eye(3), np.zeros(3), np.zeros((1, 3)), np.array([3.0, 4.0, 0.0, 12.0]) * 1e-3)
    assert reg.rms == pytest.approx(6.5e-3, rel=1e-15)  # sqrt((9 + 16 + 0 + 144) / 4) = sqrt(42.25) mm; the mean is 4.75
    assert reg.max == 12e-3
    d = reg.to_dict()
    assert d["rms_mm"] == pytest.approx(6.5) and d["max_mm"] == pytest.approx(12.0)


def test_registration_leaves_exactly_the_residuals_it_cannot_explain(rng):
    arm = robots.get("ur10")
    q = random_joints(arm, 40, rng)
    P, e = _points_with_residuals(arm, q, 2e-3, rng)
    lengths = np.linalg.norm(e, axis=1)
    reg = register(arm, q, P)
    np.testing.assert_allclose(reg.errors, lengths, atol=1e-10)
    assert reg.rms == pytest.approx(2e-3, rel=1e-7)  # the RMS of the lengths, by construction
    assert abs(reg.rms - lengths.mean()) > 1e-4  # 0.1 mm apart: the mean distance is not the RMS
    assert reg.max == pytest.approx(lengths.max(), rel=1e-7)
    np.testing.assert_allclose(reg.R, R_TRUE, atol=1e-9)
    np.testing.assert_allclose(reg.t, T_TRUE, atol=1e-9)
    np.testing.assert_allclose(reg.tool, TOOL, atol=1e-9)


# --- a registered arm far from the points: a warning beyond 2% of the reach ----------------------
def _reach(arm):
    """The arm's reach as the measured-data module states it: its body vectors' lengths (UR10:
    no prismatic joint)."""
    return float(np.linalg.norm(arm.b0[1:], axis=1).sum())


@pytest.mark.parametrize("share, warned", [(0.019, False), (0.021, True)])
def test_far_registration_warning_at_two_percent_of_the_reach(rng, share, warned):
    arm = robots.get("ur10")
    reach = _reach(arm)
    assert 1.2 < reach < 2.0
    q = random_joints(arm, 40, rng)
    P, _ = _points_with_residuals(arm, q, share * reach, rng)
    cal = zrp_ga.calibrate(arm, Measurements(q, P), algorithm="lm")
    assert cal.task.registration.rms == pytest.approx(share * reach, rel=1e-6)
    far = [w for w in cal.summary["warnings"] if "off the calibration points" in w]
    assert bool(far) is warned
    if warned:
        assert f"{share * reach * 1e3:.4g} mm RMS" in far[0] and "more than 2% of its" in far[0]


# --- a measured point far from the others: refused beyond 3 x (reach + 0.5 m) --------------------
def _file_with_a_far_point(tmp_path, arm, distance, rng):
    """20 points of the arm and one more ``distance`` m along x from the median point (the
    coordinate-wise median of all 21, computed by hand: the far point is the largest x, so the
    median x is the 11th smallest of the others; its y and z sit between the 10th and 11th of
    theirs, so they are the median)."""
    q = random_joints(arm, 21, rng)
    p = kinematics.forward(arm, q)[1]
    near = np.sort(p[:20], axis=0)
    far = np.array([near[10, 0] + distance, *(0.5 * (near[9, 1:] + near[10, 1:]))])
    p[20] = far
    assert np.linalg.norm(far - np.median(p, axis=0)) == pytest.approx(distance, rel=1e-12)
    df = pd.DataFrame(q, columns=[f"q{i}" for i in range(1, 7)])
    df[["x", "y", "z"]] = p
    path = tmp_path / "points.csv"
    df.to_csv(path, index=False, float_format="%.12g")
    return path


@pytest.mark.parametrize("share", [0.99, 1.01])
def test_far_point_refused_beyond_three_reaches_plus_a_tool(tmp_path, rng, share):
    arm = robots.get("ur10")
    limit = 3.0 * (_reach(arm) + 0.5)  # the arm's reach plus a tool of up to 0.5 m, three times
    path = _file_with_a_far_point(tmp_path, arm, share * limit, rng)
    fmt = measurements.zrp_format(6, "m", "rad")
    if share < 1:
        assert measurements.read(path, fmt, arm).M == 21
    else:
        with pytest.raises(ValueError, match=rf"points\.csv, line 22, column 'x': .* puts the point {share * limit:.4g} m from the others"):
            measurements.read(path, fmt, arm)
