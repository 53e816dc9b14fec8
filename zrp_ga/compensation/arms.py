"""The arms a compensation uses: the calibrated arm and the nominal one (the controller's), in
the robot's base frame, with the base transform and the measured tool of the calibration.

:func:`load_arms` reads them from a ``zrp-ga`` run directory, a calibrated robot file, a
:class:`~zrp_ga.model.robot.ZRPRobot` or what :func:`zrp_ga.calibrate` returns. A nominal arm
given beside a run (``nominal``, ``--nominal``) that is not the run's own nominal arm is refused
(:func:`check_nominal`): corrections against another arm's model are metres and tens of degrees,
not a calibration.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.compensation import frames
from zrp_ga.core.files import as_path, regular_file
from zrp_ga.io.measurements import reach_m
from zrp_ga.model import kinematics, so3
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.run import directory
from zrp_ga.run.calibration import Calibration, load

Array = NDArray[np.float64]
RUN_MODEL = "calibrated_robot.yaml"
CALIBRATION_TYPES = ("a zrp-ga run directory or a calibrated robot file (str or pathlib.Path), a ZRPRobot, "
                     "or what zrp_ga.calibrate returns")  # fmt: skip
NOMINAL_SAMPLES = 64  # joint samples on which a given nominal arm is compared with the run's
NOMINAL_SLACK = 5.0  # a given nominal may differ from the run's by this many times what the calibration changed
NOMINAL_FLOOR_M = 1e-3  # ... plus this much (m), and this much (rad): a controller's model may differ a little
NOMINAL_FLOOR_RAD = np.radians(0.5)
FAR_SHARE = 0.05  # without a recorded nominal: a calibrated arm this share of its reach from the nominal is another arm


@dataclasses.dataclass(frozen=True)
class Arms:
    """The calibrated and the nominal arm (the same joints, the robot's base frame); ``base``
    (4, 4) the base frame's pose in the instrument's frame (None: the calibration had no
    instrument frame); where they came from; notes for ``compensation.json``; ``tool`` (4, 4) the
    calibration's (first) measured tool point in the hand frame (None: the calibration measured
    the end point itself); whether the calibration measured ``orientations``; ``frames``: how the
    base and the flange were set up (:mod:`zrp_ga.compensation.setups`) with the sizes of what
    the data leave open; ``noise_mm``: the calibration's measurement noise per coordinate as its
    residual shows it (RMS point distance over sqrt 3; None: not known); the calibration's
    ``uncertainty`` (its covariance, in the instrument's frame) and ``coverage`` (its
    calibration poses), None where not known (a robot file alone); ``residual``: its residual
    model (:class:`zrp_ga.model.residual.Residual`, a Gaussian process on joint space fitted to
    the measured point's position residuals in the instrument's frame; None: the calibration has
    none), which :meth:`correction` turns into the base frame: the calibrated model is then
    ``FK_cal(q) + correction(q)``. The process corrects the measured point's position; at
    another point of the hand (another tool, the flange) its correction is applied as the same
    translation (it carries no orientation)."""

    calibrated: ZRPRobot
    nominal: ZRPRobot
    base: Array | None = None
    source: str = "calibration"
    notes: tuple[str, ...] = ()
    tool: Array | None = None
    orientations: bool = True
    measured: bool = False
    frames: dict = dataclasses.field(default_factory=dict)
    noise_mm: float | None = None
    uncertainty: Any = None  # zrp_ga.model.uncertainty.Uncertainty of the calibration (None: not known)
    coverage: Any = None  # zrp_ga.model.coverage.Coverage of its calibration poses (None: not known)
    residual: Any = None  # zrp_ga.model.residual.Residual of the calibration, instrument frame (None: none)

    def correction(self, q: ArrayLike) -> Array:
        """The residual model's mean correction at joint values q, (n,) -> (3,) or (M, n) ->
        (M, 3) m, in the robot's base frame (zeros without a residual model)."""
        q = np.asarray(q, dtype=float)
        rows = np.atleast_2d(q)
        if self.residual is None:
            out = np.zeros((len(rows), 3))
        else:
            B = np.eye(3) if self.base is None else np.asarray(self.base, dtype=float)[:3, :3]
            out = np.asarray(self.residual.predict(rows), dtype=float) @ B  # instrument -> base: B^T c per row
        return out[0] if q.ndim == 1 else out

    def residual_spread(self, q: ArrayLike) -> Array:
        """The residual model's predictive spread as a radius (M,) m at joint values q (M, n)
        (:meth:`zrp_ga.model.residual.Residual.spread`; zeros without one)."""
        rows = np.atleast_2d(np.asarray(q, dtype=float))
        if self.residual is None:
            return np.zeros(len(rows))
        return np.asarray(self.residual.spread(rows), dtype=float)

    def noted(self, *notes: str) -> Arms:
        return dataclasses.replace(self, notes=(*self.notes, *notes))


def load_arms(calibration: Any, nominal: ZRPRobot | str | Path | None = None) -> Arms:
    """The arms of ``calibration`` (module docstring); ``nominal`` (a robot, a preset name or a
    robot file) replaces the nominal arm the calibration records, and must be that arm."""
    given = None if nominal is None else _robot(nominal, "nominal")
    arms, recorded = _arms(calibration, given)
    if given is not None and recorded is not None:
        check_nominal(given, dataclasses.replace(arms, nominal=recorded))
    cal, nom = arms.calibrated, arms.nominal
    if (nom.n, nom.joint_types) != (cal.n, cal.joint_types):
        raise ValueError(f"{arms.source}: the calibrated arm has joints {cal.joint_types}, the nominal {nom.name} "
                         f"{nom.joint_types}: not the same arm")  # fmt: skip
    if given is not None and recorded is None:
        check_far(cal, nom, arms.source)
    return arms


def _arms(calibration: Any, given: ZRPRobot | None) -> tuple[Arms, ZRPRobot | None]:
    """The arms of a calibrated robot, a calibration, a run directory or a robot file, their
    nominal arm the ``given`` one, else the one recorded (:func:`_nominal`); and the nominal arm
    recorded (None where none is)."""
    if isinstance(calibration, ZRPRobot):
        source = "the calibrated robot"
        return Arms(calibration, _nominal(given, None, source), source=source), None
    if isinstance(calibration, Calibration):
        return _from_calibration(calibration, given)
    if isinstance(calibration, (str, os.PathLike)):
        return _from_path(as_path(calibration, "calibration"), given)
    raise TypeError(f"calibration: expected {CALIBRATION_TYPES}; got {_kind(calibration)}")


def _nominal(given: ZRPRobot | None, recorded: ZRPRobot | None, source: str) -> ZRPRobot:
    """The nominal arm: the one given, else the one the calibration records (ValueError: none)."""
    nominal = given if given is not None else recorded
    if nominal is None:
        raise ValueError(f"{source}: no nominal robot with it; give the nominal arm (a preset name or a robot file)")
    return nominal


def _kind(value: Any) -> str:
    return "None" if value is None else f"a {type(value).__module__}.{type(value).__qualname__}".replace("builtins.", "")


def _from_calibration(
    calibration: Calibration, given: ZRPRobot | None, source: str = "the calibration"
) -> tuple[Arms, ZRPRobot | None]:
    """The arms of a :class:`~zrp_ga.run.calibration.Calibration` (what :func:`zrp_ga.calibrate`
    returns, or :func:`zrp_ga.load` reads), with its covariance and the region its poses cover;
    and its recorded nominal arm (:func:`_arms`)."""
    where = f"{source}: calibrated_robot"
    base = None if calibration.base is None else frames.check_transform(calibration.base, f"{where}.base")
    tool = next(iter(calibration.tools.values()), None)
    tool = None if tool is None else frames.check_transform(tool, f"{where}.tools")
    notes = []
    if calibration.summary.get("returned") == "nominal":
        notes.append(f"{source}: the run returned the nominal arm (it fitted no better): nothing to correct")  # fmt: skip
    if calibration.residual is not None:
        notes.append(f"{source}: the calibrated model includes its residual model (a Gaussian process on joint space, "
                     "residual.json): the inverse kinematics solves on the parametric model plus its correction, applied "
                     "as a translation of the hand, and sigma_mm adds its spread; far from the calibration poses the "
                     "correction fades to zero")  # fmt: skip
    arms = Arms(calibration.arm, _nominal(given, calibration.nominal, source), base, source, tuple(notes), tool=tool,
                orientations=calibration.orientations, measured=base is not None, noise_mm=_noise(calibration.summary),
                uncertainty=calibration.uncertainty, coverage=calibration.coverage, residual=calibration.residual)  # fmt: skip
    return arms, calibration.nominal


def _noise(summary: dict) -> float | None:
    """The measurement noise per coordinate (mm) a measured calibration's residual shows."""
    try:
        return float(summary["position_error_mm"]["calibration"]["calibrated"]["rms"]) / np.sqrt(3.0)
    except (KeyError, TypeError, ValueError):
        return None


def _from_path(path: Path, given: ZRPRobot | None) -> tuple[Arms, ZRPRobot | None]:
    """The arms of a run directory (:func:`zrp_ga.run.calibration.load`), or of a calibrated
    robot file (with its run's when it lies in a run directory); and the recorded nominal arm
    (:func:`_arms`)."""
    from zrp_ga.io.robot_files import read_robot

    if path.is_dir():
        if (path / RUN_MODEL).is_file() and not (path / directory.SUMMARY).is_file():  # the arm alone
            source = str(path / RUN_MODEL)
            return Arms(read_robot(path / RUN_MODEL), _nominal(given, None, source), source=source), None
        return _from_calibration(load(path), given, str(path / RUN_MODEL))
    regular_file(path, "a calibrated robot file or a zrp-ga run directory")
    cal = read_robot(path)
    if not (path.parent / directory.SUMMARY).is_file():
        return Arms(cal, _nominal(given, None, str(path)), source=str(path)), None
    arms, recorded = _from_calibration(load(path.parent), given, str(path))
    return dataclasses.replace(arms, calibrated=cal), recorded  # a run's URDF: its arm in the base frame too


def _robot(robot: Any, what: str) -> ZRPRobot:
    """A robot, a preset name or a robot file; TypeError naming ``what`` for anything else."""
    from zrp_ga.io import presets
    from zrp_ga.io.robot_files import read_robot

    if isinstance(robot, ZRPRobot):
        return robot
    if not isinstance(robot, (str, os.PathLike)):
        raise TypeError(f"{what}: expected a ZRPRobot, a preset name or a robot file path; got {_kind(robot)}")
    return presets.get(str(robot)) if str(robot) in presets.names() else read_robot(Path(robot))


# --- is the nominal arm the calibrated arm's? ---------------------------------------------------
def difference(a: ZRPRobot, b: ZRPRobot) -> tuple[float, float]:
    """The largest hand position (m) and orientation (rad) difference of two arms of the same
    joints over :data:`NOMINAL_SAMPLES` joint values within ``a``'s limits (q = 0 first; the
    samples drawn from ``numpy.random.default_rng(0)``, the same every time)."""
    lim = a.joint_limits
    q = np.vstack([np.clip(0.0, lim[:, 0], lim[:, 1]), np.random.default_rng(0).uniform(lim[:, 0], lim[:, 1], (NOMINAL_SAMPLES - 1, a.n))])
    (Ra, pa), (Rb, pb) = kinematics.forward(a, q), kinematics.forward(b, q)
    angles = np.linalg.norm(so3.log(np.swapaxes(Ra, 1, 2) @ Rb), axis=-1)
    return float(np.linalg.norm(pa - pb, axis=1).max()), float(angles.max())


def check_nominal(given: ZRPRobot, arms: Arms) -> None:
    """Refuse a given nominal arm that differs from the nominal arm the calibration records by
    more than :data:`NOMINAL_SLACK` times what the calibration changed (plus a millimetre and
    half a degree): the corrections would be those between two different arms."""
    recorded, cal = arms.nominal, arms.calibrated
    if (given.n, given.joint_types) != (recorded.n, recorded.joint_types):
        raise ValueError(f"nominal (--nominal): {given.name} has joints {given.joint_types}, but {arms.source} was "
                         f"calibrated from {recorded.name} ({recorded.joint_types}): not the same arm")  # fmt: skip
    dp, da = difference(given, recorded)
    cp, ca = difference(cal, recorded)
    if dp > NOMINAL_SLACK * cp + NOMINAL_FLOOR_M or da > NOMINAL_SLACK * ca + NOMINAL_FLOOR_RAD:
        raise ValueError(f"nominal (--nominal): {given.name} is not the nominal arm of {arms.source} ({recorded.name}, "
                         f"recorded in its {directory.SUMMARY}): their hands differ by up to {dp * 1e3:.4g} mm and "
                         f"{np.degrees(da):.3g} deg over the joint range, the calibration changed it by {cp * 1e3:.3g} mm "
                         f"and {np.degrees(ca):.3g} deg; leave --nominal out to use the recorded arm")  # fmt: skip


def check_far(cal: ZRPRobot, nominal: ZRPRobot, source: str) -> None:
    """Refuse a nominal arm whose hand lies farther from the calibrated arm's than
    :data:`FAR_SHARE` of its reach somewhere in the joint range (a calibration corrects
    millimetres): another arm's model, or the calibrated arm in another frame."""
    dp, da = difference(cal, nominal)
    if dp > FAR_SHARE * reach_m(nominal):
        raise ValueError(f"nominal (--nominal): {nominal.name} is not the nominal arm of {source}: their hands differ by up "
                         f"to {dp * 1e3:.4g} mm and {np.degrees(da):.3g} deg over the joint range ({nominal.name} "
                         f"reaches {reach_m(nominal) * 1e3:.4g} mm); a calibration corrects millimetres")  # fmt: skip


# --- tools -----------------------------------------------------------------------------------------
def tool_transform(tool: Any, what: str = "tool") -> Array | None:
    """``tool`` as a transform (4, 4) in the hand frame: an offset (3,) m or a transform (4, 4)
    (checked: :func:`zrp_ga.compensation.frames.check_transform`); None stays None."""
    if tool is None:
        return None
    if isinstance(tool, (dict, str, set)):
        raise TypeError(f"{what}: expected an offset (3,) m or a 4x4 transform in the hand frame; got {_kind(tool)}")
    try:
        T = np.asarray(tool, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected an offset (3,) m or a 4x4 transform, got {tool!r}") from None
    if T.shape == (3,):
        if not np.all(np.isfinite(T)):
            raise ValueError(f"{what}: NaN or inf in the offset")
        return frames.transform(np.eye(3), T)
    if T.shape != (4, 4):
        raise ValueError(f"{what}: expected an offset (3,) or a 4x4 transform, got shape {T.shape}")
    return frames.check_transform(T, what)


def with_tool(robot: ZRPRobot, tool: ArrayLike | None) -> ZRPRobot:
    """``robot`` ending at a tool: ``tool`` an offset (3,) m or a transform (4, 4) in the hand frame."""
    T = tool_transform(tool)
    if T is None:
        return robot
    return robot.with_tool(T[:3, 3]).replace(R_h0=robot.R_h0 @ T[:3, :3])
