"""``zrp_ga.calibrate``'s inputs that used to pass silently (issue 27, "Silent in the API"):
validation data without calibration data, a seed that is a string (or a float, a bool, a
negative number), numbers held in float16, rotation matrices that are no rotations, and output
directories that cannot be written; each refused on one line before any work.

The rotations are checked against their definition computed here (``R^T R = I``, ``det R = +1``
within the stated tolerance 1e-6): a rotation perturbed by 1e-7 passes, by 1e-5 is refused; a
mirror is named as one; the row named is the first bad one, counted from 0."""

import os
import re
import time

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import robots
from zrp_ga.model import kinematics

ARM = robots.load("puma560")
RNG = np.random.default_rng(3)
Q = RNG.uniform(-1.5, 1.5, (30, 6))
R_TRUE, P = kinematics.forward(ARM, Q)[:2]  # a perfect arm, metres and radians


def _one_line(exc) -> str:
    text = str(exc.value)
    assert "\n" not in text
    return text


def test_validation_without_data_is_refused_not_a_simulated_calibration():
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"^calibrate\(\): validation= was given without data=") as exc:
        zrp_ga.calibrate(ARM, validation=(Q, P), algorithm="lm")
    assert "simulated problem" in _one_line(exc)
    assert time.perf_counter() - t0 < 60  # (not a timing claim: it stops before any work, which takes far less)


@pytest.mark.parametrize("seed, shown", [("abc", "'abc'"), ("12", "'12'"), (1.5, "1.5"), (True, "True"), ([0, 1.0], "1.0 in"),
                                         ([0, -2], "-2 in"), (-1, "-1"), (b"7", "b'7'"), (None, "None")])
def test_a_seed_that_is_no_whole_number_is_refused(seed, shown):
    with pytest.raises(ValueError, match=r"^calibrate\(\): seed: ") as exc:
        zrp_ga.calibrate(ARM, algorithm="lm", seed=seed)
    assert shown in _one_line(exc)


def test_numpy_integer_seeds_are_seeds():
    one = zrp_ga.calibrate("puma560", problem={"n_poses": 20}, algorithm="lm", seed=np.int64(3))
    assert one.summary["seed"] == 3
    two = zrp_ga.calibrate("puma560", problem={"n_poses": 20}, algorithm="lm", seed=np.array([3, 4]))
    assert [c.summary["seed"] for c in two] == [3, 4]


@pytest.mark.parametrize("make", [lambda q, p: (q, p), lambda q, p: {"q": q, "positions": p},
                                  lambda q, p: pd.DataFrame({**{f"q{i + 1}": q[:, i] for i in range(6)}, "x": p[:, 0], "y": p[:, 1], "z": p[:, 2]})],
                         ids=["tuple", "dict", "dataframe"])  # fmt: skip
def test_float16_numbers_are_refused_with_the_step_they_lose(make):
    p16 = (1e3 * P).astype(np.float16)  # mm: float16's step at 500-2000 mm is 0.5-1 mm
    with pytest.raises(ValueError, match=r"^data: (positions|column 'x') in float16: steps of ") as exc:
        zrp_ga.calibrate(ARM, make(Q, p16), algorithm="lm")
    line = _one_line(exc)
    step, top = (float(v) for v in re.search(r"steps of (\S+) at the largest value (\S+) \(3 significant", line).groups())
    column = p16 if "positions" in line else p16[:, :1]
    assert top == float(np.abs(column.astype(float)).max())
    assert step == float(np.spacing(np.float16(top)))  # the step at the largest value, numpy's float16
    assert step >= 0.25  # a quarter of a millimetre at least: no calibration survives it
    assert "give float32 or float64" in line


def test_float32_numbers_are_accepted_and_give_what_float64_gives():
    """float32 holds 7 digits (0.1 um at 1 m): calibrations on it and on float64 agree to the
    micrometre."""
    a = zrp_ga.calibrate(ARM, (Q, P), algorithm="lm", problem={"length_unit": "m", "angle_unit": "rad"})
    b = zrp_ga.calibrate(ARM, (Q.astype(np.float32), P.astype(np.float32)), algorithm="lm",
                         problem={"length_unit": "m", "angle_unit": "rad"})  # fmt: skip
    qs = RNG.uniform(-1.5, 1.5, (10, 6))
    pa, pb = kinematics.forward(a.robot, qs)[1], kinematics.forward(b.robot, qs)[1]
    assert np.abs(pa - pb).max() < 1e-6  # the two calibrated arms agree to the micrometre


def test_complex_numbers_are_refused():
    with pytest.raises(ValueError, match=r"^data: positions in complex numbers"):
        zrp_ga.calibrate(ARM, (Q, P.astype(complex)), algorithm="lm")


def _bad_rotations(k: int, how: str) -> np.ndarray:
    R = R_TRUE.copy()
    if how == "mirror":
        R[k] = R[k] @ np.diag([1.0, 1.0, -1.0])
    elif how == "scaled":
        R[k] = 1.001 * R[k]
    elif how == "sheared":
        R[k] = R[k] + 1e-5 * np.triu(np.ones((3, 3)), 1)
    elif how == "nan":
        R[k, 1, 2] = np.nan
    return R


@pytest.mark.parametrize("k, how, why", [(4, "mirror", r"a mirror \(det R = -1\)"), (0, "scaled", "R\\^T R differs from I by 0.002"),
                                         (17, "sheared", "R\\^T R differs from I by"), (29, "nan", "NaN or inf")])  # fmt: skip
def test_rotation_matrices_that_are_no_rotations_are_refused_naming_the_row(k, how, why):
    R = _bad_rotations(k, how)
    # the definition, computed here: which rows are rotations within 1e-6
    off = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(R)
    first_bad = int(np.flatnonzero(~((off <= 1e-6) & (np.abs(det - 1) <= 1e-6)))[0])
    assert first_bad == k
    with pytest.raises(ValueError, match=rf"^data: orientations, row {k}: not a rotation matrix \({why}") as exc:
        zrp_ga.calibrate(ARM, (Q, P, R), algorithm="lm", problem={"use_orientation": True})
    _one_line(exc)
    with pytest.raises(ValueError, match=rf"^validation: orientations, row {k}: not a rotation matrix"):
        zrp_ga.calibrate(ARM, (Q, P, R_TRUE), validation=(Q, P, R), algorithm="lm", problem={"use_orientation": True})


def test_rotations_within_the_tolerance_pass_beyond_it_are_refused():
    """Round-off of 1e-7 (a float32 rotation) passes; 1e-5 is refused: the tolerance is 1e-6."""
    small = R_TRUE + 1e-7 * RNG.standard_normal(R_TRUE.shape)
    cal = zrp_ga.calibrate(ARM, (Q, P, small), algorithm="lm", problem={"use_orientation": True})
    assert cal.summary["final_cost"] <= cal.summary["nominal_cost"]  # it ran: the rotations were taken
    large = R_TRUE.copy()
    large[3] = large[3] + 1e-5 * RNG.standard_normal((3, 3))
    with pytest.raises(ValueError, match=r"row 3: not a rotation matrix .*the tolerance is 1e-06"):
        zrp_ga.calibrate(ARM, (Q, P, large), algorithm="lm", problem={"use_orientation": True})


def test_measurements_with_rotations_are_checked_too():
    from zrp_ga.model.poses import Measurements

    with pytest.raises(ValueError, match=r"^data: orientations, row 2: not a rotation matrix \(a mirror"):
        zrp_ga.calibrate(ARM, Measurements(Q, P, R=_bad_rotations(2, "mirror")), algorithm="lm")


def test_rotations_from_scipy_pass_the_check():
    from zrp_ga.model import so3

    R = Rotation.from_quat(RNG.standard_normal((1000, 4))).as_matrix()  # rotations, whatever they are
    so3.check_rotations(R, "orientations")  # no error
    so3.check_rotations(R.astype(np.float32), "orientations")  # float32 round-off (1e-7) is within 1e-6


@pytest.mark.parametrize("where, message", [
    ("afile/run", r"^calibrate\(\): out: cannot create .*afile/run: .*afile is a file, not a directory$"),
    ("locked/run", r"^calibrate\(\): out: cannot write into .*locked \(permission denied\)$"),
    ("held", r"^calibrate\(\): out: .*held already holds a run; choose another directory$"),
])  # fmt: skip
def test_an_output_directory_that_cannot_be_used_is_refused_before_any_work(tmp_path, monkeypatch, where, message):
    if where.startswith("locked") and os.geteuid() == 0:
        pytest.skip("root writes into any folder")
    (tmp_path / "afile").write_text("x")
    (tmp_path / "locked").mkdir(mode=0o500)
    (tmp_path / "held").mkdir()
    (tmp_path / "held" / "summary.json").write_text("{}")
    built = []
    from zrp_ga.run import build

    monkeypatch.setattr(build, "build", lambda *a, **k: built.append(1))  # any work would come through here
    with pytest.raises(ValueError, match=message) as exc:
        zrp_ga.calibrate(ARM, (Q, P), out=tmp_path / where, algorithm="lm")
    _one_line(exc)
    assert not built
    if where == "held":  # a list of seeds writes into out/seed_S: the one holding a run is named
        (tmp_path / "held" / "seed_2").mkdir()
        (tmp_path / "held" / "seed_2" / "summary.json").write_text("{}")
        (tmp_path / "held" / "summary.json").unlink()
        message = r"^calibrate\(\): out: .*held/seed_2 already holds a run"
    with pytest.raises(ValueError, match=message):
        zrp_ga.calibrate(ARM, (Q, P), out=tmp_path / where, algorithm="lm", seed=[1, 2])
    assert not built


def test_an_output_that_is_no_path_is_a_type_error():
    with pytest.raises(TypeError, match=r"^calibrate\(\): out: expected a file path .* got a list"):
        zrp_ga.calibrate(ARM, (Q, P), out=["a"], algorithm="lm")
