"""``zrp_ga.calibrate`` on in-memory data: a DataFrame, a tuple or a dict of arrays, and
Measurements, give the calibration the same numbers give from a CSV file written here; numbers
in mm and degrees are converted (the same validation numbers as in metres and radians); bad
in-memory data are refused as a file is, on one line naming the row and the column; warnings
are Python warnings of ``zrp_ga.ZrpGaWarning``; a misspelt keyword is a TypeError naming the
closest valid ones.

The data: a puma560 whose link vectors are off by up to 1 mm (drawn here), seen by a tracker in
another frame with 20 um of noise; the calibrated arm must predict the validation points better
than the nominal one (the file route is the reference, the in-memory routes must match it)."""

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import robots
from zrp_ga.core.schema import ConfigError
from zrp_ga.model import kinematics
from zrp_ga.model.poses import Measurements

ARM = robots.load("puma560")
FRAME = (Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix(), np.array([1.5, -0.4, 0.2]))


def _data(M: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Joint values (rad) and tracker points (m) of the perturbed arm."""
    rng = np.random.default_rng(seed)
    true = ARM.replace(b0=ARM.b0 + np.random.default_rng(7).uniform(-1e-3, 1e-3, ARM.b0.shape))
    q = rng.uniform(-1.5, 1.5, (M, ARM.n))
    p = kinematics.forward(true, q)[1] @ FRAME[0].T + FRAME[1]
    return q, p + rng.normal(0.0, 2e-5, p.shape)


Q, P = _data(40, 1)
QV, PV = _data(20, 2)


def _csv(path, q, p):
    frame = pd.DataFrame(np.column_stack([q, p]), columns=[f"q{i}" for i in range(1, 7)] + ["x", "y", "z"])
    frame.to_csv(path, index=False, float_format="%.17g")
    return frame


def _numbers(cal):
    s = cal.summary
    # the parameters the genome stands for (the identified genome's coordinates depend on its basis)
    return np.array(list(cal.task.problem.layout.expand(cal.x)) + list(s["validation_rms_mm"].values()))


@pytest.fixture(scope="module")
def from_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("data")
    _csv(d / "cal.csv", Q, P), _csv(d / "val.csv", QV, PV)
    cal = zrp_ga.calibrate(ARM, d / "cal.csv", validation=d / "val.csv", algorithm="lm")
    rms = cal.summary["validation_rms_mm"]
    assert rms["calibrated"] < 0.2 * rms["nominal"]  # a calibration took place: the reference is worth matching
    return _numbers(cal)


def _columns(q, p):
    return {**{f"q{i + 1}": q[:, i] for i in range(6)}, "x": p[:, 0], "y": p[:, 1], "z": p[:, 2]}


@pytest.mark.parametrize(
    "make",
    [
        lambda q, p: pd.DataFrame(_columns(q, p)),
        lambda q, p: (q, p),
        lambda q, p: {"q": q, "positions": p},
        _columns,
        lambda q, p: Measurements(q, p),
    ],
    ids=["dataframe", "tuple", "dict-of-arrays", "dict-of-columns", "measurements"],
)
def test_in_memory_data_calibrate_as_the_same_file(from_file, make):
    cal = zrp_ga.calibrate(ARM, make(Q, P), validation=make(QV, PV), algorithm="lm")
    np.testing.assert_allclose(_numbers(cal), from_file, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("make", [lambda q, p: (q, p), lambda q, p: Measurements(q, p)], ids=["tuple", "measurements"])
def test_mm_and_degrees_are_detected_and_converted(from_file, make):
    cal = zrp_ga.calibrate(ARM, make(np.degrees(Q), 1e3 * P), validation=make(np.degrees(QV), 1e3 * PV), algorithm="lm")
    assert cal.task.info["units"] == {"length": "mm", "joint_angle": "deg"}
    # converted numbers differ from the file's in the last bits, which move the registration by 1e-11 m and the
    # weakly identified combinations (standard errors near problem.max_se) by up to 0.03 um: the same arm
    np.testing.assert_allclose(_numbers(cal), from_file, rtol=1e-6, atol=1e-7)


def test_stated_units_are_used():
    """Joint values of 0.5 deg or less cannot be told from radians: stated, they are converted."""
    q = np.degrees(Q) / 100  # small angles: auto would read them as radians
    true = ARM.replace(b0=ARM.b0 + np.random.default_rng(7).uniform(-1e-3, 1e-3, ARM.b0.shape))
    p = 1e3 * (kinematics.forward(true, np.radians(q))[1] @ FRAME[0].T + FRAME[1])
    with warnings.catch_warnings():  # poses this close leave most parameters unidentifiable, as warned
        warnings.simplefilter("ignore", zrp_ga.ZrpGaWarning)
        cal = zrp_ga.calibrate(ARM, (q, p), algorithm="lm", problem={"angle_unit": "deg", "length_unit": "mm"})
    assert cal.task.info["units"] == {"length": "mm", "joint_angle": "deg"}
    np.testing.assert_allclose(cal.task.sets["calibration"].q, np.radians(q), rtol=1e-12)
    np.testing.assert_allclose(cal.task.sets["calibration"].p, p / 1e3, rtol=1e-12)


def test_warnings_are_python_warnings_of_the_package():
    """A NaN cell with drop_bad_rows: the row is dropped with a ZrpGaWarning naming it."""
    p = P.copy()
    p[3, 1] = np.nan
    with pytest.warns(zrp_ga.ZrpGaWarning, match=r"data, row 3, column 'y': 'nan' is not a finite number; dropped 1 rows"):
        cal = zrp_ga.calibrate(ARM, (Q, p), algorithm="lm", problem={"drop_bad_rows": True})
    rows = cal.task.sets["calibration"].q.shape[0]
    assert rows == len(Q) - 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", zrp_ga.ZrpGaWarning)  # a notebook can turn them into errors
        with pytest.raises(zrp_ga.ZrpGaWarning, match="dropped 1 rows"):
            zrp_ga.calibrate(ARM, (Q, p), algorithm="lm", problem={"drop_bad_rows": True})


def test_validation_worse_than_nominal_is_a_python_warning():
    """Few noisy points of the nominal arm itself: the calibration fits their noise."""
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (14, 6))
    p = kinematics.forward(ARM, q)[1] + rng.normal(0, 5e-4, (14, 3))
    qv = rng.uniform(-1.5, 1.5, (30, 6))
    with pytest.warns(zrp_ga.ZrpGaWarning, match="validation"):
        zrp_ga.calibrate(ARM, (q, p), validation=(qv, kinematics.forward(ARM, qv)[1]), algorithm="lm")


@pytest.mark.parametrize(
    "settings, expected",
    [
        ({"crosover": "sbx"}, r"keyword argument 'crosover'; did you mean 'crossover'"),
        ({"population": {"mux": 50}}, r"key 'mux' in population=\{\.\.\.\}; did you mean 'mu'"),
        ({"problem": {"n_pose": 5}}, r"key 'n_pose' in problem=\{\.\.\.\}; did you mean 'n_poses'"),
    ],
)
def test_misspelt_keywords_are_type_errors_naming_the_closest(settings, expected):
    with pytest.raises(TypeError, match=expected):
        zrp_ga.calibrate("puma560", algorithm="lm", **settings)


def test_misspelt_key_of_the_measured_problem():
    with pytest.raises(TypeError, match=r"key 'drop_bad_row' in problem=\{\.\.\.\}; did you mean 'drop_bad_rows'"):
        zrp_ga.calibrate(ARM, (Q, P), algorithm="lm", problem={"drop_bad_row": True})


def _bad(kind):
    p = P.copy()
    if kind == "nan":
        p[5, 2] = np.nan
        return (Q, p)
    if kind == "inf-in-q":
        q = Q.copy()
        q[7, 0] = np.inf
        return (q, P)
    if kind == "positions-2d":
        return (Q, P[:, :2])
    if kind == "rows-differ":
        return (Q, P[:-1])
    if kind == "five-joints":
        return (Q[:, :5], P)
    if kind == "duplicate-columns":
        frame = pd.DataFrame(np.column_stack([Q, P, P[:, :1]]), columns=[f"q{i}" for i in range(1, 7)] + ["x", "y", "z", "x"])
        return frame
    if kind == "missing-column":
        return pd.DataFrame(_columns(Q, P)).drop(columns="z")
    if kind == "repeated-rows":
        return (np.vstack([Q, Q[:1]]), np.vstack([P, P[:1]]))
    if kind == "text":
        frame = pd.DataFrame(_columns(Q, P)).astype(object)
        frame.loc[2, "q3"] = "abc"
        return frame
    raise AssertionError(kind)


@pytest.mark.parametrize(
    "kind, expected",
    [
        ("nan", r"^data, row 5, column 'z': 'nan' is not a finite number; set problem.drop_bad_rows=true"),
        ("inf-in-q", r"^data, row 7, column 'q1': 'inf' is not a finite number"),
        ("positions-2d", r"^data: positions must have shape \(40, 3\)"),
        ("rows-differ", r"^data: positions must have shape \(40, 3\) \(one row per row of q\), got \(39, 3\)"),
        ("five-joints", r"^data: 5 joint columns \(q1, q2, q3, q4, q5\), but the robot has 6 joints"),
        ("duplicate-columns", r"^data: column 'x' appears 2 times"),
        ("missing-column", r"^data: missing column 'z'"),
        ("repeated-rows", r"^data: 1 rows repeat earlier rows exactly \(first: row 40 repeats row 0\)"),
        ("text", r"^data, row 2, column 'q3': 'abc' is not a finite number"),
    ],
)
def test_bad_in_memory_data_refused_on_one_line(kind, expected):
    with pytest.raises(ValueError, match=expected) as exc:
        zrp_ga.calibrate(ARM, _bad(kind), algorithm="lm")
    assert "\n" not in str(exc.value)


def test_bad_validation_named_and_wrong_type_refused():
    with pytest.raises(ValueError, match=r"^validation, row 5, column 'z'"):
        zrp_ga.calibrate(ARM, (Q, P), validation=_bad("nan"), algorithm="lm")
    with pytest.raises(TypeError, match=r"^data: expected a measurement file, a pandas DataFrame.*got ndarray"):
        zrp_ga.calibrate(ARM, np.column_stack([Q, P]), algorithm="lm")


@pytest.mark.parametrize(
    "settings, expected",
    [
        ({"crossover": "sbxx"}, r"^In 'config': Could not find 'crossover/sbxx'; available options in 'crossover': blend, "),
        ({"population": {"mu": "abc"}}, r"^Value 'abc' of type 'str' could not be converted to Integer \(key: population.mu\)$"),
        ({"problem": {"n_poses": -3}}, r"^problem.n_poses: must be at least 1, got -3$"),
    ],
)
def test_bad_values_are_config_errors_on_one_line_as_on_the_command_line(settings, expected):
    with pytest.raises(ConfigError, match=expected) as exc:
        zrp_ga.calibrate("puma560", algorithm="lm", **settings)
    assert "\n" not in str(exc.value)


def test_registration_warning_names_a_row_of_in_memory_data():
    """A joint's zero 0.3 rad off: the registered nominal arm is far from the points, and the
    warning names the worst point as a row of the table (counted from 0), not a file line."""
    q = Q.copy()
    q[:, 1] += 0.3
    with pytest.warns(zrp_ga.ZrpGaWarning, match=r"worst: row \d+, ") as record:
        zrp_ga.calibrate(ARM, pd.DataFrame(_columns(q, P)), algorithm="lm")
    assert not any("line" in str(w.message) for w in record if "registered nominal" in str(w.message))


def test_rotation_matrices_one_per_measurement():
    """Rotation matrices in memory must come one per row of q: fewer or more are refused."""
    import zrp_ga

    q = np.zeros((12, 6))
    p = np.zeros((12, 3))
    for R in (np.tile(np.eye(3), (9, 1, 1)), np.tile(np.eye(3), (24, 1, 1))):
        with pytest.raises(ValueError, match=r"rotation matrices for 12 measurements"):
            zrp_ga.calibrate("puma560", (q, p, R), algorithm="lm")
