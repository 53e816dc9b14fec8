"""A calibration you keep: what :func:`zrp_ga.calibrate` returns and :func:`load` reads back.

A :class:`Calibration` holds the calibrated arm as the robot files carry it (``arm``: the
robot's base frame, ending at the hand, ``calibrated_robot.yaml``; ``base``: that frame's pose
in the instrument's frame; ``tools``: the measured tool points' frames in the hand frame), the
nominal arm, the run's ``summary.json``, its convergence history, the covariance of what it
identified (:class:`~zrp_ga.model.uncertainty.Uncertainty`) and the region of joint space its
calibration poses cover (:class:`~zrp_ga.model.coverage.Coverage`). Made by a run it also
holds the optimiser's ``result`` and the ``task`` (None once loaded); nothing else differs.

- :meth:`Calibration.save`: the run directory's files, as ``zrp-ga`` writes them (robot files,
  ``best_params.csv``, ``summary.json``, ``convergence.csv``, ``uncertainty.json``,
  ``coverage.json``, ...); a loaded calibration copies the files it was read from.
- :func:`load`: a saved calibration or any ``zrp-ga`` run directory.
- :meth:`Calibration.export`: the URDF, DH and modified-DH tables (in the nominal table's
  conventions, with their corrections), Universal Robots' ``default_kinematics.yaml``, the ZRP
  file and the frames file, each to a path of one's choosing (the writers of the run's files:
  :func:`zrp_ga.io.robot_files.write_all`).
- :meth:`Calibration.predict`: positions and orientations of the calibrated arm at joint values
  (with its residual model's correction when it has one), with their predicted 1-sigma errors
  where the calibration has a covariance, and where the joint values lie against the
  calibration poses.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import shlex
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model import kinematics
from zrp_ga.model.coverage import Coverage
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.model.uncertainty import Uncertainty
from zrp_ga.run import directory

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

    from zrp_ga.algorithms import Result
    from zrp_ga.model.coverage import Assessment
    from zrp_ga.model.residual import Residual
    from zrp_ga.problems import Task

Array = NDArray[np.float64]
ROBOT_FILE = "calibrated_robot.yaml"  # the arm in its base frame (what every run writes)
INSTRUMENT_FILE = "calibrated_in_instrument.yaml"  # a measured run's arm in the instrument's frame
EXPORTS = {"urdf": ".urdf", "dh": "_dh.yaml", "mdh": "_mdh.yaml", "zrp": ".yaml", "frames": "_frames.yaml",
           "ur": "_default_kinematics.yaml"}  # fmt: skip
NOT_COPIED = (directory.LOCK, directory.CHECKPOINT)  # a saved copy of a run: not its lock, not its resumable state


@dataclasses.dataclass(frozen=True)
class Prediction:
    """What :meth:`Calibration.predict` gives at joint values q (M, n): positions ``p`` (M, 3) m
    and orientations ``R`` (M, 3, 3) in ``frame``; the predicted 1-sigma position error radius
    ``position_mm`` (M,) (the identified combinations' covariance and the prior of what was
    left at nominal together) and orientation error ``orientation_mrad`` (M,) (None without a
    covariance); where q lies against the calibration poses: ``outside`` (M,) bool and
    ``distance_ratio`` (M,) (None without them, :mod:`zrp_ga.model.coverage`).
    ``orientations_fitted``: whether the calibration fitted measured orientations; if not, the
    hand's own turn is the nominal's (positions cannot see it) and ``orientation_mrad`` holds
    only what the axes' uncertainty does to it."""

    p: Array
    R: Array
    frame: str
    position_mm: Array | None = None
    orientation_mrad: Array | None = None
    outside: NDArray[np.bool_] | None = None
    distance_ratio: Array | None = None
    orientations_fitted: bool = True

    def table(self) -> pd.DataFrame:
        """One row per pose (a pandas DataFrame): ``x_mm, y_mm, z_mm``, the rotation vector
        ``rx_rad, ry_rad, rz_rad``, and the uncertainty and coverage columns where known."""
        import pandas as pd
        from scipy.spatial.transform import Rotation

        cols: dict[str, Any] = {f"{c}_mm": self.p[:, j] * 1e3 for j, c in enumerate("xyz")}
        rv = Rotation.from_matrix(self.R).as_rotvec()
        cols.update({f"r{c}_rad": rv[:, j] for j, c in enumerate("xyz")})
        for k in ("position_mm", "orientation_mrad", "outside", "distance_ratio"):
            if getattr(self, k) is not None:
                cols[f"sigma_{k}" if k.startswith(("position", "orientation")) else k] = getattr(self, k)
        return pd.DataFrame(cols)


@dataclasses.dataclass
class Calibration:
    """A calibration (module docstring): ``robot`` the calibrated arm in the measurements'
    frame (for measured data the instrument's, ending at the first measured point; else the
    arm's own), ``summary`` (``summary.json``), ``arm``, ``base``, ``tools`` and ``nominal`` as
    the robot files carry them, ``history`` one row per generation (``convergence.csv``);
    ``result`` and ``task`` from the run (None once loaded), ``directory`` where it was saved or
    loaded from (None: in memory only)."""

    robot: ZRPRobot
    summary: dict[str, Any] = dataclasses.field(repr=False)
    arm: ZRPRobot = dataclasses.field(repr=False)
    nominal: ZRPRobot | None = None
    base: Array | None = dataclasses.field(default=None, repr=False)
    tools: dict[str, Array] = dataclasses.field(default_factory=dict, repr=False)
    history_table: pd.DataFrame | None = dataclasses.field(default=None, repr=False)
    result: Result | None = dataclasses.field(default=None, repr=False)
    task: Task | None = dataclasses.field(default=None, repr=False)
    directory: Path | None = None
    _uncertainty: Uncertainty | Literal[False] | None = dataclasses.field(default=False, repr=False)  # False: not computed yet
    _coverage: Coverage | Literal[False] | None = dataclasses.field(default=False, repr=False)
    _residual: Residual | Literal[False] | None = dataclasses.field(default=False, repr=False)

    # --- made by a run ----------------------------------------------------------------------------
    @classmethod
    def from_run(cls, task: Task, result: Result, summary: dict[str, Any], out: str | Path | None = None) -> Calibration:
        """The calibration a run of ``task`` found (its ``result`` and ``summary``), written in
        ``out`` if it was given."""
        x = np.array([summary["best_genome"][k] for k in task.problem.names])
        arm, base, tools = task.export(x)
        return cls(task.calibrated_robot(x), summary, arm, task.robot, base, dict(tools), None, result, task,
                   None if out is None else Path(out))  # fmt: skip

    @property
    def x(self) -> np.ndarray:
        """The returned genome (the problem's genes, in ``summary.json``'s ``best_genome``; zero
        when the nominal arm was returned)."""
        genome = self.summary["best_genome"]
        names = self.task.problem.names if self.task is not None else list(genome)
        return np.array([genome[k] for k in names], dtype=float)

    @property
    def history(self) -> pd.DataFrame | None:
        """One row per generation (pandas DataFrame), the columns of ``convergence.csv``."""
        return self.result.history if self.result is not None else self.history_table

    @property
    def measured(self) -> bool:
        """Whether the calibration was made in an instrument's frame (a base transform)."""
        return self.base is not None

    @property
    def orientations(self) -> bool:
        """Whether the calibration data held orientations (fitted)."""
        if self.task is not None:
            return getattr(self.task.problem.data, "R", None) is not None
        problem = (self.summary.get("config") or {}).get("problem") or {}
        return not (problem.get("position_only") or problem.get("use_orientation") is False)

    @property
    def uncertainty(self) -> Uncertainty | None:
        """The calibration's :class:`zrp_ga.model.uncertainty.Uncertainty` (the covariance of
        the identified combinations and the prior of what was left at nominal), None when the
        nominal arm was returned or the data leave no degrees of freedom for the noise."""
        if self._uncertainty is False:
            self._uncertainty = self._find_uncertainty()
        return self._uncertainty

    def _find_uncertainty(self) -> Uncertainty | None:
        if self.summary.get("returned") == "nominal" or "uncertainty" not in self.summary:
            return None
        if self.task is not None:
            from zrp_ga.problems.identify import uncertainty

            return uncertainty(self.task.problem, self.x, self.task.setup)
        path = None if self.directory is None else self.directory / "uncertainty.json"
        return Uncertainty.read(path) if path is not None and path.is_file() else None

    @property
    def coverage(self) -> Coverage | None:
        """The region of joint space the calibration poses cover (None: not known)."""
        if self._coverage is False:
            if self.task is not None:
                self._coverage = Coverage(np.asarray(self.task.problem.data.q, dtype=float))
            else:
                path = None if self.directory is None else self.directory / "coverage.json"
                self._coverage = Coverage.read(path) if path is not None and path.is_file() else None
        return self._coverage

    @property
    def residual(self) -> Residual | None:
        """The calibration's residual model (:class:`zrp_ga.model.residual.Residual`: a Gaussian
        process on joint space, the measured point's position residuals in the measurements'
        frame; ``problem.model``'s ``+gp``), None without one."""
        if self._residual is False:
            from zrp_ga.model import residual

            if self.task is not None:
                self._residual = getattr(self.task, "residual", None)
            else:
                path = None if self.directory is None else self.directory / residual.FILE
                self._residual = residual.Residual.read(path) if path is not None and path.is_file() else None
        return self._residual

    # --- prediction ---------------------------------------------------------------------------------
    def predict_error(self, q: ArrayLike, tool: int = 0) -> dict[str, Any]:
        """Predicted 1-sigma errors of the calibrated arm at joint values q (M, n) (the model's
        units: rad, m; measured data: as read from the file, converted), each (M,):
        ``position_mm`` (the identified combinations' covariance and the prior of those left at
        nominal together, and a residual model's predictive spread), ``position_identified_mm``, ``position_unidentified_mm``,
        ``orientation_mrad``; and where q lies against the calibration poses: ``outside``
        (bool) and ``distance_ratio`` (:mod:`zrp_ga.model.coverage`). ValueError when there is
        no uncertainty (:attr:`uncertainty`).

        >>> import zrp_ga
        >>> cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm")
        >>> e = cal.predict_error(cal.task.problem.data.q[:3])
        >>> bool((e["position_mm"] < 1.0).all()), e["outside"].tolist()
        (True, [False, False, False])
        """
        u = self.uncertainty
        if u is None:
            raise ValueError("predict_error: this calibration has no uncertainty (the nominal arm was returned, or the data "
                             "leave no degrees of freedom to estimate the noise)")  # fmt: skip
        p = u.predict(q, tool)
        where = self._coverage_of(q)
        gp = self.residual  # its predictive spread, as a radius, in quadrature (predict)
        spread = 0.0 if gp is None else gp.spread(q)
        return {"position_mm": np.hypot(p["position_total_m"], spread) * 1e3, "position_identified_mm": p["position_m"] * 1e3,
                "position_unidentified_mm": p["position_unidentified_m"] * 1e3,
                "orientation_mrad": np.hypot(p["orientation_rad"], p["orientation_unidentified_rad"]) * 1e3,
                "outside": None if where is None else where.outside,
                "distance_ratio": None if where is None else where.ratio}  # fmt: skip

    def _coverage_of(self, q: ArrayLike) -> Assessment | None:
        c = self.coverage
        return None if c is None else c.assess(q)

    def _tool(self, tool: int | str | None) -> tuple[str | None, Array]:
        """The tool's name and its frame (4, 4) in the hand frame: ``None`` the calibration's
        first measured point (the hand without one), ``"hand"`` the hand, a name or an index of
        :attr:`tools`."""
        names = list(self.tools)
        if tool is None:
            tool = 0 if names else "hand"
        if isinstance(tool, str) and tool in ("hand", "flange"):
            return None, np.eye(4)
        if isinstance(tool, (int, np.integer)) and not isinstance(tool, bool) and 0 <= tool < len(names):
            tool = names[int(tool)]
        if tool not in self.tools:
            known = ", ".join(map(repr, ["hand", *names]))
            raise ValueError(f"predict: tool {tool!r} is not one of this calibration's tools ({known}, or an index)")
        return str(tool), np.asarray(self.tools[tool], dtype=float)

    def predict(self, q: ArrayLike, tool: int | str | None = None, frame: str = "measurements",
                angle_unit: str = "rad") -> Prediction:  # fmt: skip
        """The calibrated arm at joint values q (n,) or (M, n) (revolute joints in ``angle_unit``,
        rad or deg; prismatic in m): positions and orientations of ``tool`` (default: the
        calibration's first measured point, the hand when it measured the end point itself;
        ``"hand"``, a tool's name or its index) in ``frame``: ``"measurements"`` (the
        instrument's frame for measured data, else the arm's own) or ``"base"`` (the robot's base
        frame, as ``calibrated_robot.yaml``), with their predicted 1-sigma errors (the
        calibration's covariance, carried to the point by its lever arm from a measured point:
        :meth:`zrp_ga.model.uncertainty.Uncertainty.predict`) and where q lies against the
        calibration poses. A calibration with a residual model (:attr:`residual`) adds its
        correction to the positions (a translation of the hand: the process carries no
        orientation) and its predictive standard deviation to ``position_mm`` (``sqrt(3) s`` in
        quadrature).

        >>> import numpy as np, zrp_ga
        >>> cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm")
        >>> pr = cal.predict([10.0, -20.0, 30.0, 0.0, 45.0, 0.0], angle_unit="deg")
        >>> pr.p.shape, pr.R.shape, bool(0 < pr.position_mm[0] < 1.0), pr.outside.tolist()
        ((1, 3), (1, 3, 3), True, [False])
        """
        if frame not in ("measurements", "base"):
            raise ValueError(f"predict: frame {frame!r}, expected 'measurements' or 'base'")
        if angle_unit not in ("rad", "deg"):
            raise ValueError(f"predict: angle_unit {angle_unit!r}, expected 'rad' or 'deg'")
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.ndim != 2 or q.shape[1] != self.arm.n:
            raise ValueError(f"predict: q must have {self.arm.n} joint values per row, got shape {np.shape(q)}")
        if angle_unit == "deg":
            q = np.where(self.arm.prismatic, q, np.radians(q))
        name, T = self._tool(tool)
        R, p = kinematics.forward(self.arm, q)
        p = p + R @ T[:3, 3]
        R = R @ T[:3, :3]
        B = np.eye(4) if self.base is None else np.asarray(self.base, dtype=float)
        p_m, R_m = p @ B[:3, :3].T + B[:3, 3], B[:3, :3] @ R  # in the measurements' frame
        lever_at = p_m  # the point the covariance is carried to (the parametric model's)
        gp = self.residual
        if gp is not None:  # the full model: the residual model's correction (a translation of the hand)
            c = gp.predict(q)
            p_m, p = p_m + c, p + c @ B[:3, :3]
        pos = rot = None
        u = self.uncertainty
        if u is not None:
            names = list(self.tools)
            k = names.index(name) if name in names and names.index(name) < u.layout.n_tools else 0
            _, at = kinematics.forward(u.robot(k), q)
            e = u.predict(q, k, offset_m=lever_at - at)
            spread = 0.0 if gp is None else gp.spread(q)  # the process's own, as a radius
            pos = np.hypot(e["position_total_m"], spread) * 1e3
            rot = np.hypot(e["orientation_rad"], e["orientation_unidentified_rad"]) * 1e3
        where = self._coverage_of(q)
        base_frame = frame == "base" or self.base is None
        return Prediction(p if base_frame else p_m, R if base_frame else R_m, "base" if frame == "base" else "measurements",
                          pos, rot, None if where is None else where.outside, None if where is None else where.ratio,
                          self.orientations)  # fmt: skip

    def plot(self, ax: Axes | None = None) -> Figure | SubFigure:
        """The convergence curve (best cost per evaluation) on ``ax``, or on a new figure that is
        returned without being shown (``matplotlib.figure.Figure``: no backend is chosen); the
        figure ``ax`` is on (a ``SubFigure`` for an ``ax`` in one). ValueError without a
        convergence history (a loaded calibration without ``convergence.csv``)."""
        if ax is None:
            from matplotlib.figure import Figure

            ax = Figure(figsize=(6, 4)).subplots()
        h = self.history
        if h is None:
            raise ValueError("plot: this calibration has no convergence history (no convergence.csv where it was loaded from)")
        ax.semilogy(h["nevals"], h["best"], marker=".")
        ax.set_xlabel("evaluations")
        ax.set_ylabel("best cost")
        ax.set_title(self.summary["instance"], fontsize=9)
        return ax.figure

    # --- files --------------------------------------------------------------------------------------
    def save(self, out: str | Path) -> Path:
        """Write the calibration into the directory ``out`` (created) as a ``zrp-ga`` run writes
        its files, so that :func:`load`, ``zrp-ga-compensate`` and ``zrp-ga-report`` read it: a
        calibration from a run writes them with the run's writers
        (:func:`zrp_ga.run.summary.write`, the convergence rows, ``status.json``); a loaded one
        copies the files it was read from (not a lock or a checkpoint). A directory that
        already holds a run is refused (ValueError); returns ``out``."""
        out = Path(out)
        if out.exists() and not out.is_dir():
            raise ValueError(f"save: {out} is a file, not a directory")
        if self.directory is not None and out.exists() and out.resolve() == self.directory.resolve():
            return out  # already there
        if out.is_dir() and directory.holds_run(out):
            raise ValueError(f"save: {out} already holds a run; choose another directory")
        try:
            out.mkdir(parents=True, exist_ok=True)
            with directory.locked(out):
                if self.task is not None and self.result is not None:
                    self._write(out, self.task, self.result)
                elif self.directory is not None:
                    for f in sorted(self.directory.iterdir()):
                        if f.is_file() and f.name not in NOT_COPIED and not f.name.endswith(".tmp"):
                            shutil.copy2(f, out / f.name)
                else:
                    raise ValueError("save: this calibration holds neither its run nor the directory it was read from")
        except OSError as exc:
            raise ValueError(f"save: cannot write {exc.filename or out}: {exc.strerror or exc}") from None
        self.directory = out
        return out

    def _write(self, out: Path, task: Task, result: Result) -> None:
        from zrp_ga.run import callbacks, summary

        written = copy.deepcopy(self.summary)
        callbacks.write_rows(out / directory.CONVERGENCE, result.rows)
        summary.write(out, task, result, written, self.x)
        self.summary.setdefault("calibrated_robot", written.get("calibrated_robot"))
        directory.write_status(out, "done")

    def export(self, urdf: str | Path | None = None, dh: str | Path | None = None, mdh: str | Path | None = None,
               ur: str | Path | None = None, zrp: str | Path | None = None, frames: str | Path | None = None) -> dict[str, Path]:  # fmt: skip
        """Write the calibrated arm (in its base frame) to the paths given: ``urdf`` (an arm read
        from a URDF goes into that file), ``dh`` and ``mdh`` (the tables in the nominal table's
        conventions where the nominal arm came from one, each row the nominal's plus a
        correction, with ``<stem>_corrections.csv`` beside them), ``ur`` (Universal Robots'
        ``default_kinematics.yaml``; ValueError for other arms), ``zrp`` (the ZRP file) and
        ``frames`` (the base in the instrument's frame, the measured tools in the hand frame).
        The same files as the run's ``calibrated_robot*`` (:func:`zrp_ga.io.robot_files.write_all`).
        Returns what was written, by kind."""
        from zrp_ga.io import records, robot_files, ros_calibration

        asked = {k: Path(v) for k, v in dict(urdf=urdf, dh=dh, mdh=mdh, ur=ur, zrp=zrp, frames=frames).items() if v is not None}
        arm = self._arm_with_source()
        if "ur" in asked and not ros_calibration.is_ur(arm):
            raise ValueError(f"export: ur: {arm.name} is not a Universal Robots arm (no default_kinematics.yaml for it)")
        names = list(self.tools)
        with tempfile.TemporaryDirectory() as tmp:
            stem = "calibrated_robot"
            paths, _ = robot_files.write_all(arm, tmp, stem, base=self.base, tool=self.tools[names[0]] if names else None)
            if len(names) > 1:
                with open(paths["frames"], "a") as f:
                    f.write("# tools: every tool point's frame in the hand frame (tool: the first).\n")
                    entries = {k: robot_files._frame_entry(np.asarray(T)) for k, T in self.tools.items()}
                    f.write(records.yaml_text({"tools": entries}, sort_keys=False, default_flow_style=None))
            done = {}
            for kind, target in asked.items():
                source = Path(tmp) / f"{stem}{EXPORTS[kind]}"
                target.parent.mkdir(parents=True, exist_ok=True)
                text = source.read_text()
                if kind in ("dh", "mdh") and f"{kind}_corrections" in paths:
                    beside = target.with_name(f"{target.stem}_corrections.csv")
                    shutil.copyfile(paths[f"{kind}_corrections"], beside)
                    text = text.replace(paths[f"{kind}_corrections"].name, beside.name)
                    done[f"{kind}_corrections"] = beside
                target.write_text(text)
                done[kind] = target
        return done

    def _arm_with_source(self) -> ZRPRobot:
        """The arm with the nominal arm's source (its DH table or URDF): the exports then keep
        the nominal's conventions and file, as the run's own files do."""
        source = getattr(self.nominal, "source", None)
        if self.nominal is None or source is None or isinstance(source, str) or self.arm.joint_types != self.nominal.joint_types:
            return self.arm
        return self.arm.replace(source=source)


# --- loading -----------------------------------------------------------------------------------------
def load(path: str | Path) -> Calibration:
    """The calibration saved in ``path`` (:meth:`Calibration.save`) or written there by a
    ``zrp-ga`` run: one ValueError naming what is missing or damaged (a sweep's directory: give
    one of its jobs; a run written with ``outputs=study``, as a sweep's are: how to get its files).

    >>> import tempfile, zrp_ga
    >>> cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = zrp_ga.load(cal.save(d + "/puma"))
    ...     same = np.allclose(back.predict(np.zeros(6)).p, cal.predict(np.zeros(6)).p, rtol=0, atol=1e-12)
    >>> same, back.task is None
    (True, True)
    """
    from zrp_ga.core.files import as_path
    from zrp_ga.io.robot_files import read_robot

    path = as_path(path, "calibration directory")
    if not path.is_dir():
        raise ValueError(f"{path}: not a directory (a saved calibration or a zrp-ga run directory)")
    check_run_dir(path)
    damaged = directory.damage(path) if (path / directory.CONVERGENCE).exists() else _summary_damage(path)
    if damaged:
        raise ValueError(f"{path}: not a finished run: {damaged}")
    s = directory.read_summary(path)
    arm = read_robot(path / ROBOT_FILE)
    robot = read_robot(path / INSTRUMENT_FILE) if (path / INSTRUMENT_FILE).is_file() else arm
    files = s.get("calibrated_robot") or {}
    base = None if files.get("base") is None else np.array(files["base"], dtype=float)
    tools = {k: np.array(T, dtype=float) for k, T in (files.get("tools") or {}).items()}
    history = None
    if (path / directory.CONVERGENCE).is_file():
        import pandas as pd

        history = pd.read_csv(path / directory.CONVERGENCE)
    return Calibration(robot, s, arm, _nominal(s, path), base, tools, history, None, None, path)


def check_run_dir(path: Path) -> None:
    """A ValueError unless ``path`` holds a calibration run's robot file and summary (a sweep
    directory: one of its jobs named; a run written with ``outputs=study``: how to get its files)."""
    if (path / ROBOT_FILE).is_file() and (path / directory.SUMMARY).is_file():
        return
    study = _study_run(path)
    if study is not None:
        raise ValueError(study)
    jobs = sorted(p.parent.name for p in path.glob(f"*/{ROBOT_FILE}")) or sorted(p.parent.name for p in path.glob(f"*/{directory.SUMMARY}"))
    hint = f"; a sweep directory? give one of its jobs ({path / jobs[0]}, ...)" if jobs else ""
    missing = ROBOT_FILE if not (path / ROBOT_FILE).is_file() else directory.SUMMARY
    raise ValueError(f"{path}: not a calibration run directory (no {missing}){hint}")


def _study_run(path: Path) -> str | None:
    """Why ``path`` holds no robot files when it was written with ``outputs=study`` (a sweep's
    run by default, ``outputs=auto``: its summary.json without ``calibrated_robot``; or Hydra's
    ``.hydra/config.yaml`` when there is no summary), with the command that writes them: the
    run's overrides alone (``.hydra/overrides.yaml``, else its sweep's manifest), or the sweep
    with ``outputs=full``. None for any other directory."""
    if (path / ROBOT_FILE).is_file():
        return None
    outputs: object = None
    if (path / directory.SUMMARY).is_file():
        try:
            s = directory.read_summary(path)
        except (OSError, ValueError):
            return None
        conf = s.get("config") if isinstance(s, dict) and "calibrated_robot" not in s else None
        outputs = conf.get("outputs") if isinstance(conf, dict) else None
    else:  # no summary: Hydra's record; outputs=auto is full in a single run, study in a sweep: unknown here
        conf = _yaml(path / ".hydra" / "config.yaml")
        outputs = "study" if isinstance(conf, dict) and conf.get("outputs") == "study" else None
    if outputs not in ("study", "auto"):
        return None
    how = "outputs=study" if outputs == "study" else "outputs=auto, which is outputs=study in a sweep"
    overrides = [o for o in _overrides(path) if not o.lstrip("+~").startswith(("outputs=", "hydra.", "progress="))]
    again = (f"run `zrp-ga {shlex.join(overrides)}` alone, or the sweep with outputs=full" if overrides else
             "run it again with outputs=full (a sweep's job: its overrides alone, from the sweep's manifest.csv)")  # fmt: skip
    return f"{path}: written with {how} (a study's files, no {ROBOT_FILE}); for the calibrated arm's files {again}"


def _overrides(path: Path) -> list[str]:
    """The command-line overrides of the run in ``path``: Hydra's record, else its sweep's manifest."""
    recorded = _yaml(path / ".hydra" / "overrides.yaml")
    if isinstance(recorded, list):
        return [str(o) for o in recorded]
    if (path.parent / directory.MANIFEST).is_file():
        try:
            jobs = directory.job_states(path.parent)
        except (OSError, ValueError, TypeError):
            return []
        for job in jobs:
            if job.get("dir") == path.name and job.get("overrides"):
                return str(job["overrides"]).split(" ")  # the manifest joins them with spaces
    return []


def _yaml(path: Path) -> Any:
    """A YAML file's content; None when it is missing or not YAML."""
    import yaml

    try:
        return yaml.safe_load(path.read_text())
    except (OSError, ValueError, yaml.YAMLError):
        return None


def _summary_damage(path: Path) -> str | None:
    """What is wrong with a summary written without a convergence log (a run's files put
    together by hand): it must be a JSON mapping."""
    try:
        s = directory.read_summary(path)
    except (OSError, ValueError) as exc:
        return f"{path / directory.SUMMARY} cannot be read as JSON ({type(exc).__name__}: {exc})"
    return None if isinstance(s, dict) else f"{path / directory.SUMMARY} is not a run's summary (a JSON mapping)"


def _nominal(s: dict[str, Any], path: Path) -> ZRPRobot | None:
    """The nominal arm of a run's summary (``robot_model``); its robot file or preset when that
    still gives the same arm (its DH table or URDF then shapes the exports)."""
    if "robot_model" not in s:
        return None
    recorded = ZRPRobot.from_dict(s["robot_model"], source=f"{path / directory.SUMMARY}: robot_model")
    given = _configured_robot(json.dumps((s.get("config") or {}).get("robot") or {}, sort_keys=True))
    if given is not None and given.n == recorded.n and given.joint_types == recorded.joint_types:
        same = all(np.allclose(getattr(given, k), getattr(recorded, k), rtol=0, atol=1e-12) for k in ("u0", "b0", "R_h0"))
        if same:
            return given
    return recorded


@functools.lru_cache(maxsize=8)
def _configured_robot(conf: str) -> ZRPRobot | None:
    from zrp_ga.io import presets

    c = json.loads(conf)
    try:
        return presets.load(c.get("name"), c.get("file"), c.get("base_link"), c.get("tip_link"))
    except (OSError, ValueError, TypeError):
        return None
