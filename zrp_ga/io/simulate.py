"""Measurement files of any arm, simulated: a cell to rehearse before measuring one's own
(:func:`simulate`, public as ``zrp_ga.simulate``).

A true arm (the given one with random errors, or one given as such) is measured at joint
values (given, or drawn within the arm's joint limits) by an instrument whose frame holds the
robot's base at ``base``, at one or several tool points fixed to the hand: ``p = B T(q + dq)
t``, with Gaussian noise of the stated standard deviations on each coordinate (and on the
joints, the orientations). The files are in the package's measurement format
(:mod:`zrp_ga.io.measurements`: ``q1..qn, x, y, z`` [``rx, ry, rz``] [``sx, sy, sz``]
[``tool``]) in the stated units, with the settings that read them (``zrp-ga`` overrides and
:func:`zrp_ga.calibrate`'s ``problem=``) in ``simulation.json``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.checks import ROTVEC, check_convention
from zrp_ga.io.measurements import ANGLE, LENGTH
from zrp_ga.model import kinematics, simulation
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]
ERRORS = {"axis_rad": 1e-3, "body_m": 5e-4}  # the true arm's errors about the given one (uniform, per component)
NOISE_KEYS = ("position_m", "orientation_rad", "joint_rad")
FILES = {"calibration": "calibration.csv", "validation": "validation.csv", "truth": "true_robot.yaml",
         "settings": "simulation.json"}  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Simulated:
    """What :func:`simulate` made: the ``truth`` (the arm measured, its base frame), the
    instrument's pose ``base`` (4, 4) of that frame, the ``tools`` (4, 4) in the hand frame by
    name, the joint values commanded (``q_calibration``, ``q_validation``, rad and m), the
    ``calibration`` and ``validation`` tables (pandas DataFrames, as written), the noise
    (``noise``: standard deviations by kind), the ``settings`` that read the files
    (``problem=`` of :func:`zrp_ga.calibrate`) and the ``files`` written (empty without ``out``)."""

    truth: ZRPRobot
    base: Array
    tools: dict[str, Array]
    q_calibration: Array
    q_validation: Array
    calibration: Any
    validation: Any
    noise: dict[str, float]
    settings: dict[str, Any]
    files: dict[str, Path]

    @property
    def overrides(self) -> list[str]:
        """The ``zrp-ga`` command line's overrides for these files (with ``out``)."""
        f = self.files
        out = ["problem=measured", f"problem.calibration_file={f['calibration']}", f"problem.validation_file={f['validation']}"]
        return out + [f"problem.{k}={v}" for k, v in self.settings.items()]


def simulate(
    robot: ZRPRobot | str | Path,
    n_poses: int = 60,
    n_validation: int = 40,
    *,
    q: ArrayLike | None = None,
    q_validation: ArrayLike | None = None,
    truth: ZRPRobot | None = None,
    errors: dict[str, float] | None = None,
    tool: ArrayLike | dict[str, ArrayLike] | None = None,
    base: ArrayLike | None = None,
    noise: float | dict[str, float] | None = None,
    units: str | tuple[str, str] = "m,rad",
    orientation: str | None = None,
    std: bool = False,
    seed: int = 0,
    out: str | Path | None = None,
) -> Simulated:
    """Measurement files of ``robot`` (a :class:`ZRPRobot`, a preset name or a robot file: the
    nominal arm one has) as an instrument would take them (module docstring).

    ``n_poses``, ``n_validation``: joint values drawn uniformly within the arm's joint limits
    (``q``, ``q_validation`` (M, n), rad and m, give them instead: one's own program).
    ``truth``: the arm measured; default: ``robot`` with errors drawn uniformly within
    ``errors`` (``{"axis_rad": 1e-3, "body_m": 5e-4}`` by default; ``{}``: none) on every
    axis and body vector but the base point. ``tool``: the point measured, an offset (3,) m or a
    transform (4, 4) in the hand frame, or several by name (``{"A": [...], "B": [...]}``: every
    pose measured at each, a ``tool`` column); default: the hand's end point. ``base``: the
    robot's base frame in the instrument's frame, (4, 4) or an offset (3,) m; default: the same.
    ``noise``: standard deviation of each position coordinate (m), or a dict of
    ``position_m``, ``orientation_rad`` (a rotation vector's, left-multiplied) and ``joint_rad``
    (the joints move to the commanded value plus this; the file records the command).
    ``units``: ``"m,rad"``, ``"mm,deg"`` (lengths, angles) or a pair. ``orientation``: a
    convention (``rotvec``, or an Euler sequence such as ``ZYX``) to write ``rx, ry, rz``;
    None: positions only. ``std``: write ``sx, sy, sz`` (the position noise). ``seed``: the
    random stream. ``out``: the directory to write ``calibration.csv``, ``validation.csv``,
    ``true_robot.yaml`` and ``simulation.json`` into.

    >>> import numpy as np, zrp_ga
    >>> sim = zrp_ga.simulate("puma560", 40, 20, tool=[0.0, 0.0, 0.1], noise=2e-5, units="mm,deg")
    >>> cal = zrp_ga.calibrate("puma560", sim.calibration, validation=sim.validation, algorithm="lm",
    ...                        problem=sim.settings)
    >>> bool(cal.summary["validation_rms_mm"]["calibrated"] < 0.1)
    True
    """
    from zrp_ga.io import presets

    arm = robot if isinstance(robot, ZRPRobot) else presets.get(str(robot)) if str(robot) in presets.names() else _read(robot)
    rng = np.random.default_rng(seed)
    length, angle = _units(units)
    if orientation is not None:
        check_convention(orientation, "orientation")
    sd = _noise(noise)
    truth = _truth(arm, truth, errors, rng)
    tools = _tools(tool)
    B = _base(base)
    qc = _joints(arm, q, n_poses, rng, "q")
    qv = _joints(arm, q_validation, n_validation, rng, "q_validation")
    tables = [_measure(truth, B, tools, qq, sd, rng, length, angle, orientation, std) for qq in (qc, qv)]
    settings: dict[str, Any] = {"length_unit": length, "angle_unit": angle}
    if orientation is not None:
        settings["orientation_convention"] = orientation
    if std:
        settings["use_weights"] = True
    files: dict[str, Path] = {}
    if out is not None:
        files = _write(Path(out), tables, truth, B, tools, sd, settings, seed)
    return Simulated(truth, B, tools, qc, qv, tables[0], tables[1], sd, settings, files)


def _read(path) -> ZRPRobot:
    from zrp_ga.io.robot_files import read_robot

    return read_robot(path)


def _units(units: str | tuple[str, str]) -> tuple[str, str]:
    parts = [u.strip() for u in units.split(",")] if isinstance(units, str) else list(units)
    if len(parts) != 2 or parts[0] not in LENGTH or parts[1] not in ANGLE:
        raise ValueError(f"simulate: units {units!r}: expected a length and an angle unit, e.g. 'mm,deg' (lengths "
                         f"{', '.join(LENGTH)}; angles {', '.join(ANGLE)})")  # fmt: skip
    return parts[0], parts[1]


def _noise(noise: float | dict[str, float] | None) -> dict[str, float]:
    if noise is None:
        given: dict = {}
    elif isinstance(noise, dict):
        unknown = sorted(set(noise) - set(NOISE_KEYS))
        if unknown:
            raise ValueError(f"simulate: noise: unknown key(s) {', '.join(map(repr, unknown))}; known: {', '.join(NOISE_KEYS)}")
        given = noise
    else:
        given = {"position_m": noise}
    out = {}
    for k in NOISE_KEYS:
        v = given.get(k, 0.0)
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not np.isfinite(v) or v < 0:
            raise ValueError(f"simulate: noise {k}: a standard deviation >= 0, got {v!r}")
        out[k] = float(v)
    return out


def _truth(arm: ZRPRobot, truth: ZRPRobot | None, errors: dict[str, float] | None, rng) -> ZRPRobot:
    if truth is not None:
        if not isinstance(truth, ZRPRobot) or (truth.n, truth.joint_types) != (arm.n, arm.joint_types):
            raise ValueError(f"simulate: truth must be a ZRPRobot with the joints of {arm.name} ({arm.joint_types})")
        return truth
    e = dict(ERRORS if errors is None else errors)
    unknown = sorted(set(e) - set(ERRORS))
    if unknown:
        raise ValueError(f"simulate: errors: unknown key(s) {', '.join(map(repr, unknown))}; known: {', '.join(ERRORS)}")
    drawn = simulation.true_robot(arm, Layout(arm.n), rng, float(e.get("axis_rad", 0.0)), float(e.get("body_m", 0.0)))
    return drawn.replace(source=None)


def _transform(value: ArrayLike, what: str) -> Array:
    from zrp_ga.io.urdf import check_transform

    T = np.asarray(value, dtype=float)
    if T.shape == (3,):
        out = np.eye(4)
        out[:3, 3] = T
        T = out
    if T.shape != (4, 4):
        raise ValueError(f"simulate: {what}: an offset (3,) m or a transform (4, 4), got shape {T.shape}")
    return check_transform(T, f"simulate: {what}")


def _tools(tool) -> dict[str, Array]:
    if tool is None:
        return {"": np.eye(4)}
    if isinstance(tool, dict):
        if not tool:
            raise ValueError("simulate: tool: an empty dict (give at least one tool point)")
        return {str(k): _transform(v, f"tool {k!r}") for k, v in tool.items()}
    return {"": _transform(tool, "tool")}


def _base(base) -> Array:
    return np.eye(4) if base is None else _transform(base, "base")


def _joints(arm: ZRPRobot, q, M: int, rng, what: str) -> Array:
    if q is not None:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != arm.n or not np.all(np.isfinite(q)):
            raise ValueError(f"simulate: {what}: finite joint values with {arm.n} columns (rad, m), got shape {q.shape}")
        return q
    if isinstance(M, bool) or not isinstance(M, (int, np.integer)) or M < 1:
        raise ValueError(f"simulate: the number of poses must be an integer >= 1, got {M!r}")
    lim = arm.joint_limits
    return rng.uniform(lim[:, 0], lim[:, 1], size=(int(M), arm.n))


def _measure(truth: ZRPRobot, B: Array, tools: dict[str, Array], q: Array, sd: dict[str, float], rng, length: str,
             angle: str, orientation: str | None, std: bool):  # fmt: skip
    """The table of the measurements at commanded joint values q (every tool at each pose)."""
    import pandas as pd
    from scipy.spatial.transform import Rotation

    moved = q + rng.normal(scale=sd["joint_rad"], size=q.shape) * ~truth.prismatic if sd["joint_rad"] > 0 else q
    R_h, p_h = kinematics.forward(truth, moved)
    frames = []
    for name, T in tools.items():
        p = (p_h + R_h @ T[:3, 3]) @ B[:3, :3].T + B[:3, 3]
        R = B[:3, :3] @ R_h @ T[:3, :3]
        if sd["position_m"] > 0:
            p = p + rng.normal(scale=sd["position_m"], size=p.shape)
        cols: dict[str, Any] = {f"q{j + 1}": q[:, j] / (LENGTH[length] if t == "P" else ANGLE[angle])
                                for j, t in enumerate(truth.joint_types)}  # fmt: skip
        cols.update({c: p[:, j] / LENGTH[length] for j, c in enumerate("xyz")})
        if orientation is not None:
            if sd["orientation_rad"] > 0:
                R = Rotation.from_rotvec(rng.normal(scale=sd["orientation_rad"], size=(len(q), 3))).as_matrix() @ R
            rot = Rotation.from_matrix(R)
            values = rot.as_rotvec() if orientation == ROTVEC else rot.as_euler(orientation)
            cols.update({c: values[:, j] / ANGLE[angle] for j, c in enumerate(("rx", "ry", "rz"))})
        if std:
            cols.update({c: np.full(len(q), max(sd["position_m"], 1e-9) / LENGTH[length]) for c in ("sx", "sy", "sz")})
        if name:
            cols["tool"] = name
        frames.append(pd.DataFrame(cols))
    table = pd.concat(frames, ignore_index=True)
    if len(frames) > 1:  # pose by pose, every tool at each
        order = np.argsort(np.tile(np.arange(len(q)), len(frames)), kind="stable")
        table = table.iloc[order].reset_index(drop=True)
    return table


def _write(out: Path, tables, truth: ZRPRobot, B: Array, tools: dict[str, Array], sd: dict, settings: dict, seed: int) -> dict[str, Path]:
    from zrp_ga.core import fileio

    files = {k: out / name for k, name in FILES.items()}
    try:
        out.mkdir(parents=True, exist_ok=True)
        tables[0].to_csv(files["calibration"], index=False, float_format="%.17g")
        tables[1].to_csv(files["validation"], index=False, float_format="%.17g")
        truth.to_yaml(files["truth"])
        fileio.write_json(files["settings"], {
            "what": "measurements simulated by zrp_ga.simulate: the true arm (true_robot.yaml, its base frame) measured in "
                    "the instrument's frame at base (4x4) and tools (4x4 in the hand frame)",
            "seed": seed, "noise_std": sd, "base": B.tolist(), "tools": {k: T.tolist() for k, T in tools.items()},
            "problem": settings,
            "zrp_ga_overrides": ["problem=measured", f"problem.calibration_file={files['calibration']}",
                                 f"problem.validation_file={files['validation']}", *[f"problem.{k}={v}" for k, v in settings.items()]],
        })  # fmt: skip
    except OSError as exc:
        raise ValueError(f"simulate: out: cannot write {exc.filename or out}: {exc.strerror or exc}") from None
    return files
