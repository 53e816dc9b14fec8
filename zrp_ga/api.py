"""The Python entry point for scripts and notebooks: :func:`calibrate`.

It composes the same config as ``zrp-ga`` with Hydra (:mod:`zrp_ga.config`: the defaults are
the command line's), hands it typed to the run layer and builds the problem from the arm and the
measurements given in memory. Nothing is written unless
``out`` is given, and matplotlib's backend is left alone: figures are made on demand.

>>> import zrp_ga
>>> cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm")
>>> bool(cal.summary["validation_rms_mm"]["calibrated"] < 0.1 * cal.summary["validation_rms_mm"]["nominal"])
True
>>> cal.robot.n, list(cal.history.columns[:3])
(6, ['gen', 'nevals', 'best'])
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, overload

import numpy as np
from numpy.typing import ArrayLike

from zrp_ga import config
from zrp_ga.core import errors, schema, targets
from zrp_ga.core.schema import ConfigError, MeasuredConf
from zrp_ga.io.simulate import Simulated, simulate
from zrp_ga.model import so3
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.run.calibration import Calibration, Prediction, load

if TYPE_CHECKING:
    import pandas as pd


    # Measurements in memory or in a file, as calibrate() takes them (its docstring): a file, a DataFrame, a
    # tuple (q, positions[, orientations]) of arrays, a dict of arrays or of columns, or Measurements.
    MeasurementData: TypeAlias = Measurements | str | Path | pd.DataFrame | tuple[ArrayLike, ...] | list[ArrayLike] | Mapping[str, Any]


__all__ = ["Calibration", "Prediction", "Simulated", "calibrate", "load", "simulate"]


def _overrides(algorithm: str, seed: int, settings: dict[str, Any]) -> list[str]:
    """Command-line overrides of keyword settings: ``crossover="sbx"`` chooses an option,
    ``population={"mu": 50}`` sets keys, ``checkpoint_every=0`` sets a top-level key."""
    out = [f"algorithm={algorithm}", f"seed={seed}"]
    for key, value in settings.items():
        if isinstance(value, dict):
            out += [f"{key}.{k}={_value(v)}" for k, v in value.items()]
        else:
            out.append(f"{key}={_value(value)}")
    return out


def _value(v: Any) -> str:
    """A value in Hydra's override grammar (mappings and lists too: ``{compliance:[2,3]}``)."""
    if isinstance(v, dict):
        return "{" + ",".join(f"{k}:{_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ",".join(_value(x) for x in v) + "]"
    return "null" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def _load(overrides: list[str]) -> schema.Config:
    """The composed config, typed; a value Hydra or OmegaConf refuses is a ConfigError on one
    line, as ``zrp-ga`` says it (the key, or the options of a config group)."""
    try:
        return config.load(overrides)
    except Exception as exc:
        if type(exc).__module__.split(".")[0] in ("hydra", "omegaconf"):
            raise ConfigError(errors.one_line(exc)) from None
        raise


def _check_keys(settings: dict[str, Any], cfg: dict[str, Any], where: str = "") -> None:
    """A TypeError naming a keyword (or a key of a dict keyword) the config (as plain values,
    :func:`zrp_ga.core.schema.to_dict`) does not have, and the closest ones it has."""
    for key, value in settings.items():
        if key not in cfg:
            valid = sorted(cfg)
            close = difflib.get_close_matches(str(key), valid, n=3)
            hint = f"; did you mean {' or '.join(map(repr, close))}?" if close else f"; valid: {', '.join(valid)}"
            name = f"key {key!r} in {where}{{...}}" if where else f"keyword argument {key!r}"
            raise TypeError(f"calibrate() got an unexpected {name}{hint}")
        if isinstance(value, dict) and cfg[key] is not None:  # (a setting that is null by default may take a mapping: problem.terms)
            if not isinstance(cfg[key], dict):
                raise TypeError(f"calibrate(): {where}{key} is a single setting, not a dict of settings")
            _check_keys(value, cfg[key], f"{where}{key}=")


def calibrate(
    robot: ZRPRobot | str | Path,
    data: MeasurementData | None = None,
    *,
    validation: MeasurementData | None = None,
    algorithm: str = "ga",
    seed: int | Sequence[int] = 0,
    out: str | Path | None = None,
    progress: bool = False,
    terms: dict[str, Any] | None = None,
    **settings: Any,
) -> Calibration | list[Calibration]:
    """Calibrate ``robot`` (a :class:`ZRPRobot`, a preset name or a robot file) on ``data``
    measured in an instrument's frame, validated on ``validation``; without data, on the
    simulated problem of the config (the paper's case study unless ``problem=...`` says otherwise).

    ``data`` and ``validation``: a measurement file in the zrp CSV format, a pandas DataFrame
    with its columns (``q1..qn, x, y, z`` and optionally ``rx, ry, rz``, ``sx, sy, sz``,
    ``tool``), a tuple ``(q, positions[, orientations])`` of arrays ((M, n), (M, 3), and (M, 3)
    angles or (M, 3, 3) rotation matrices), a dict of such arrays (keys ``q``, ``positions``,
    ``orientations``, ``std``, ``tool``) or of columns, or
    :class:`~zrp_ga.model.poses.Measurements`. In-memory numbers get the checks a file gets
    (one ValueError naming the row, counted from 0, and the column) and are in the units of
    ``problem={"length_unit": ..., "angle_unit": ...}``: ``auto`` (the default) detects metres or
    millimetres, radians or degrees, and converts. Rotation matrices must be rotations
    (``R^T R = I`` and ``det R = +1`` within 1e-6, :data:`zrp_ga.model.so3.ROTATION_TOL`); numbers
    in float16 (about 3 significant digits) or complex are refused; ``validation`` without
    ``data`` is refused (a simulated problem draws its own validation poses).

    ``terms``: non-geometric terms fitted with the geometry (``problem.terms``,
    :mod:`zrp_ga.model.terms`), e.g. ``{"compliance": [2, 3], "harmonics": {"order": 1, "joints":
    [1]}, "payload": {"mass": 5.0, "com": [0, 0, 0.1]}}``; the calibrated robot carries them.

    ``algorithm``: ``"ga"``, ``"lm"`` or ``"cmaes"``; ``settings``: any setting of ``zrp-ga``,
    e.g. ``population={"mu": 50, "generations": 30}``, ``crossover="sbx"``,
    ``problem={"cost": "nonlinear"}``; a keyword (or a key of a dict) the config does not have
    is a TypeError naming the closest ones. ``out``: a directory to write the run's files into
    (as ``zrp-ga`` writes them, with the same checks, made before any work: a file in the way, a
    folder that cannot be written or a directory holding a run is refused).
    Warnings are Python warnings of class :class:`zrp_ga.ZrpGaWarning`.

    ``seed``: a whole number >= 0; a list of distinct seeds gives a list of calibrations, one per seed, each what
    ``calibrate(..., seed=s)`` gives; GA runs on the same data (measured data given here) are
    evolved together, in one evaluation of all their offspring per generation. With ``out``,
    each run writes into ``out/seed_S``.

    >>> import numpy as np, zrp_ga
    >>> from zrp_ga.io import presets
    >>> from zrp_ga.model import kinematics
    >>> arm = presets.load("puma560")
    >>> q = np.random.default_rng(1).uniform(-1, 1, (40, 6))
    >>> p = kinematics.forward(arm, q)[1]  # a perfect arm, in mm and degrees
    >>> cal = zrp_ga.calibrate(arm, (np.degrees(q[:30]), 1e3 * p[:30]), validation=(np.degrees(q[30:]), 1e3 * p[30:]),
    ...                        algorithm="lm")
    >>> bool(cal.summary["validation_rms_mm"]["calibrated"] < 1e-6), cal.task.info["units"]
    (True, {'length': 'mm', 'joint_angle': 'deg'})
    """
    if terms is not None:
        chosen = settings.get("problem")
        if isinstance(chosen, str):
            raise ValueError(f"calibrate(): terms= with problem={chosen!r}: give the problem's settings as problem={{...}} instead")
        settings = {**settings, "problem": {**(chosen or {}), "terms": terms}}
    with errors.python_warnings():
        if validation is not None and data is None:
            raise ValueError("calibrate(): validation= was given without data=: validation data check a calibration on "
                             "measured data; give the calibration data too (a simulated problem makes its own validation "
                             "poses: problem={'n_validation': ...})")  # fmt: skip
        seeds = _seeds(seed)
        if isinstance(seeds, int):
            outs = None if out is None else [_out(out)]
            return _calibrate(robot, data, validation, algorithm, [seeds], outs, progress, settings)[0]
        outs = None if out is None else [_out(Path(_out(out)) / f"seed_{s}") for s in seeds]
        return _calibrate(robot, data, validation, algorithm, seeds, outs, progress, settings)


def _seeds(seed: Any) -> int | list[int]:
    """The one seed (a whole number >= 0) as an int, the seeds of a list of distinct ones; a
    ValueError on one line for anything else: a string (not read as a list of characters), a
    float, a bool, a negative number, repeats."""
    from zrp_ga.core import checks

    single = isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_))
    if single:
        checks.seed(int(seed), "calibrate(): seed")
        return int(seed)
    wanted = "a whole number >= 0, or a list of distinct ones"
    if isinstance(seed, (str, bytes)) or not isinstance(seed, (Sequence, np.ndarray)):
        raise ValueError(f"calibrate(): seed: {wanted}, got {seed!r}")
    seeds = list(seed)
    for s in seeds:
        if isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) or s < 0:
            raise ValueError(f"calibrate(): seed: {wanted}, got {s!r} in {seeds!r}")
    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) < len(seeds):
        raise ValueError(f"calibrate(): seed: a list of distinct seeds, got {seeds}")
    return seeds


def _out(out: Any) -> Path:
    """``out`` as a directory a run can be written into, checked before any work (one line: no
    file in the way, a writable folder on the way, no run in it already)."""
    from zrp_ga.core import files
    from zrp_ga.run import directory

    path = files.writable_dir(out, "calibrate(): out")
    if directory.holds_run(path):
        raise ConfigError(f"calibrate(): out: output directory {path} already holds a run; choose another directory")
    return path


def _calibrate(robot: ZRPRobot | str | Path, data: MeasurementData | None, validation: MeasurementData | None, algorithm: str,
               seeds: list[int], outs: Sequence[str | Path] | None, progress: bool, settings: dict[str, Any]) -> list[Calibration]:  # fmt: skip
    from zrp_ga.io import presets
    from zrp_ga.problems import measured
    from zrp_ga.run import budget, build, execute
    from zrp_ga.run.shared import Cache
    from zrp_ga.run.together import run_together

    measured_problem = data is not None and not isinstance(settings.get("problem"), str)  # problem={...}: its keys
    choices = {k: v for k, v in settings.items() if not isinstance(v, dict)}
    first = _overrides(algorithm, seeds[0], {})  # the keywords first: a misspelt one would stop Hydra
    _check_keys(dict.fromkeys(settings), schema.to_dict(_load(["problem=measured"] * measured_problem + first)))
    _check_keys(settings, schema.to_dict(_load(["problem=measured"] * measured_problem + _overrides(algorithm, seeds[0], choices))))
    over = _overrides(algorithm, seeds[0], settings)
    if measured_problem:
        over.insert(0, "problem=measured")
    base = _load(over + ["problem.calibration_file=memory"] if data is not None else over)
    arm = robot if isinstance(robot, ZRPRobot) else presets.load(**_robot_source(robot))
    task = None
    if data is not None:
        conf = schema.section(MeasuredConf, base.problem, "problem")
        calib, val = _measurements(data, arm, conf, "data"), _measurements(validation, arm, conf, "validation")
        budget.check_config(base, arm, problem=measured.data_size(arm, conf, calib, val))  # before the work: one line
        task = measured.chosen(arm, calib, val, conf, seeds[0])  # problem.model: the model named or chosen
    else:
        budget.check_config(base, arm)  # the problem of the config, before it is built
    cache = Cache()  # the instance is the one built here, not the config's
    prepared = []
    for k, seed in enumerate(seeds):
        cfg = dataclasses.replace(copy.deepcopy(base), seed=seed)
        seeded = task or targets.create(cfg.problem, "problem", robot=arm, run_seed=seed)
        prepared.append(build.prepare(cfg, None if outs is None else Path(outs[k]), cache=cache, task=seeded))
    together = len(prepared) > 1 and task is not None and all(
        p.algorithm.checkpointable and not p.algorithm.draws_from_random() for p in prepared)  # the GA on one instance
    if together:
        ended = run_together(prepared, cache)
        failed = [r for r in ended if isinstance(r, Exception)]
        if failed:
            raise failed[0]
        ran = [r for r in ended if not isinstance(r, Exception)]
    else:
        ran = [execute.execute(p, progress, cache=cache) if p.out is None else execute.run_prepared(p, progress, cache=cache)
               for p in prepared]  # fmt: skip
    return [Calibration.from_run(p.task, result, summary, p.out) for p, (result, summary) in zip(prepared, ran)]


def _robot_source(robot: str | Path) -> dict[str, str]:
    from zrp_ga.io import presets

    return {"name": str(robot)} if str(robot) in presets.names() else {"file": str(robot)}


@overload
def _measurements(data: MeasurementData, robot: ZRPRobot, c: MeasuredConf, what: str) -> Measurements: ...
@overload
def _measurements(data: None, robot: ZRPRobot, c: MeasuredConf, what: str) -> None: ...
def _measurements(data: MeasurementData | None, robot: ZRPRobot, c: MeasuredConf, what: str) -> Measurements | None:
    """``data`` read, or checked and converted as a file is (units from ``problem.length_unit``
    and ``problem.angle_unit``, ``auto`` detected), whatever form it takes."""
    if data is None:
        return None
    from zrp_ga.io import measurements
    from zrp_ga.problems.measured import header, orientation_columns

    fmt = measurements.zrp_format(robot.n, c.length_unit, c.angle_unit, c.orientation_convention)
    if isinstance(data, (str, Path)):
        orientation_columns(header(Path(data)), data, c)
        return measurements.read(Path(data), fmt, robot, c.drop_bad_rows)
    table, rotations = _table(data, what)
    orientation_columns([str(k) for k in table.columns], what, c)
    m = measurements.from_table(table, fmt, robot, c.drop_bad_rows, source=what)
    return m if rotations is None else dataclasses.replace(m, R=rotations[m.lines])


def _table(data: MeasurementData, what: str) -> tuple[pd.DataFrame, np.ndarray | None]:
    """The zrp CSV format's table of in-memory ``data`` (a DataFrame, Measurements, a tuple
    ``(q, positions[, orientations])`` or a dict of arrays or of columns), and its rotation
    matrices when given as such (they have no unit)."""
    import pandas as pd

    if isinstance(data, pd.DataFrame):
        for column in data.columns:
            _precise(what, f"column {column!r}", data[column])
        return data, None
    if isinstance(data, Measurements):
        names = data.tool_names or ("tool",)
        frame = _frame(what, data.q, data.p, None, data.std, None if data.tool is None else np.asarray(names)[data.tool])
        return frame, _rotations(what, data.R, len(frame))
    if isinstance(data, (tuple, list)) and len(data) in (2, 3):
        frame = _frame(what, *data)
        return frame, _rotations(what, data[2] if len(data) == 3 else None, len(frame))
    if isinstance(data, dict) and "q" in data:
        known = {"q", "positions", "orientations", "std", "tool"}
        for k in data:
            if k not in known:
                close = difflib.get_close_matches(str(k), sorted(known), n=1)
                raise ValueError(f"{what}: unknown key {k!r}" + (f" (did you mean {close[0]!r}?)" if close else "")
                                 + f"; known: {', '.join(sorted(known))}")  # fmt: skip
        if "positions" not in data:
            raise ValueError(f"{what}: missing key 'positions' (an (M, 3) array beside 'q')")
        o = data.get("orientations")
        frame = _frame(what, data["q"], data["positions"], o, data.get("std"), data.get("tool"))
        return frame, _rotations(what, o, len(frame))
    if isinstance(data, dict):
        try:
            return pd.DataFrame(data), None
        except ValueError as exc:
            raise ValueError(f"{what}: cannot be read as columns ({exc})") from None
    raise TypeError(f"{what}: expected a measurement file, a pandas DataFrame, a tuple (q, positions[, orientations]) "
                    f"of arrays, a dict of arrays or Measurements; got {type(data).__name__}")  # fmt: skip


def _frame(what: str, q: ArrayLike, p: ArrayLike, o: ArrayLike | None = None, std: ArrayLike | None = None,
           tool: ArrayLike | None = None) -> pd.DataFrame:  # fmt: skip
    """Arrays as the zrp CSV format's columns (q1..qn, x, y, z, rx, ry, rz, sx, sy, sz, tool)."""
    import pandas as pd

    q = _array(what, "q", q, 2)
    M = len(q)
    cols = {f"q{i + 1}": q[:, i] for i in range(q.shape[1])}
    groups = [("positions", p, ("x", "y", "z")), ("std", std, ("sx", "sy", "sz"))]
    if o is not None and np.ndim(o) == 2:
        groups.append(("orientations", o, ("rx", "ry", "rz")))
    for name, a, names in groups:
        if a is not None:
            a = _array(what, name, a, 2)
            if a.shape != (M, 3):
                raise ValueError(f"{what}: {name} must have shape ({M}, 3) (one row per row of q), got {a.shape}")
            cols.update({c: a[:, j] for j, c in enumerate(names)})
    if tool is not None:
        tool = np.asarray(tool, dtype=str)
        if tool.shape != (M,):
            raise ValueError(f"{what}: tool must have shape ({M},) (one name per row of q), got {tool.shape}")
        cols["tool"] = tool
    return pd.DataFrame(cols)


LOSSY_EPS = 1e-6  # a float type with a relative step above this (float16's 1e-3: about 1 mm at 1 m) is refused


def _precise(what: str, name: str, a: object) -> None:
    """ValueError on one line for numbers held in a type that loses what a calibration needs: a
    float type of fewer than 7 significant digits (float16: steps of about 1 mm at 1 m, 0.25
    degrees at 180), complex numbers. float32 (7 digits: 0.1 um at 1 m) passes."""
    dtype = getattr(a, "dtype", None)
    if dtype is None:
        return
    dtype = np.dtype(dtype) if not hasattr(dtype, "kind") else dtype
    if dtype.kind == "c":
        raise ValueError(f"{what}: {name} in complex numbers ({dtype}); give real numbers")
    if dtype.kind == "f" and np.finfo(dtype).eps > LOSSY_EPS:
        values = np.asarray(a)
        top = float(np.nanmax(np.abs(values))) if values.size and np.isfinite(values).any() else 1.0
        step = float(np.spacing(np.asarray(top, dtype=dtype)))
        raise ValueError(f"{what}: {name} in {dtype}: steps of {step:.3g} at the largest value {top:.4g} "
                         f"({np.finfo(dtype).precision} significant digits), precision lost before the calibration; "
                         "give float32 or float64 (if they were measured so, .astype(float) to use them anyway)")  # fmt: skip


def _array(what: str, name: str, a: ArrayLike, ndim: int) -> np.ndarray:
    _precise(what, name, a)
    try:
        array = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what}: {name} is not an array of numbers ({exc})") from None
    if array.ndim != ndim:
        raise ValueError(f"{what}: {name} must be a {ndim}-D array (one row per measurement), got shape {array.shape}")
    return array


def _rotations(what: str, o: ArrayLike | None, M: int) -> np.ndarray | None:
    """Orientations given as rotation matrices (M, 3, 3), one per measurement; None for angles
    (M, 3) or none."""
    if o is None or np.ndim(o) == 2:
        return None
    R = _array(what, "orientations", o, 3)
    if R.shape[1:] != (3, 3):
        raise ValueError(f"{what}: orientations must have shape (M, 3) (angles) or (M, 3, 3) (rotation matrices), "
                         f"got {R.shape}")  # fmt: skip
    if R.shape[0] != M:
        raise ValueError(f"{what}: {R.shape[0]} rotation matrices for {M} measurements (one per row of q)")
    so3.check_rotations(R, f"{what}: orientations", tuple(f"row {k}" for k in range(M)))  # R^T R = I, det R = +1
    return R
