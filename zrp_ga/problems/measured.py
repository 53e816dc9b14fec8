"""Measured problems (``problem=measured``, ``problem=ur10_ipa``): points read from files in an
instrument's frame, for any serial arm.

:func:`build` reads the files (units found from the data unless stated, every bad input one
line naming file, line and column) and refuses data too few to identify the arm's parameters.
:func:`from_measurements` registers the nominal arm to the calibration points (base transform
and one offset per tool point, :mod:`zrp_ga.model.registration`) and identifies its parameters, the
base point included (and the hand orientation with measured orientations), in the instrument's
frame; several tool points share one arm, each with its own last body vector.

Gene ranges (``problem.ranges``): ``data`` (default) derives them from the registered nominal
arm's largest residual ``e`` (m): ``+-e`` on every body vector, the base point and the tools,
``+-e / L_i`` (rad) on axis i, with ``L_i`` the median lever of axis i over the calibration poses
(how far the end point moves per radian of tilt: the spectral norm of the position Jacobian's
block on the axis' tangent plane, at least 5 cm), and the largest orientation residual
on the hand, all times ``search_scale`` (axes at most 0.5 rad): wide enough for errors that
explain what the registration leaves, whatever the arm. ``fixed``: ``axis_error`` and
``body_error`` times ``search_scale``.

After the run the calibrated arm leaves as robot files (:meth:`MeasuredTask.export`): the arm in
its own base frame, ending at the hand (the registered first tool offset taken off), the base
transform (robot base in the instrument's frame) and each tool's transform in the hand frame.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import warnings as warnings_module
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from zrp_ga.core.errors import warn
from zrp_ga.core.schema import Format, MeasuredConf, Ranges, section
from zrp_ga.io import measurements, records
from zrp_ga.model import error_model, metrics
from zrp_ga.model import residual as residual_file
from zrp_ga.model.cost import CalibrationProblem, model_rank
from zrp_ga.model.coverage import Coverage
from zrp_ga.model.layout import Layout
from zrp_ga.model.metrics import Judge
from zrp_ga.model.poses import Measurements
from zrp_ga.model.registration import Registration, register
from zrp_ga.model.residual import Residual
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.problems import Task, choice, half_ranges, identify, masked, term_scales, with_terms
from zrp_ga.problems.size import ProblemSize, calibration, file_rows

log = logging.getLogger(__name__)
POSE_ERRORS = "pose_errors.csv"
INSTRUMENT_MODEL = "calibrated_in_instrument.yaml"
MIN_LEVER_M = 0.05  # axis levers below this count as this much for the gene ranges
MAX_AXIS_RAD = 0.5  # largest axis gene range
GENERIC_TOOL_M = np.array([0.05, 0.03, 0.02])  # a tool offset off every axis, for counting what can be identified
FAR_REGISTRATION = 0.02  # a registered nominal arm off by more than this share of its reach is suspect


def data_path(name: str) -> Path:
    """A measurement file: ``pkg:REL`` is a file shipped in zrp_ga/data, anything else a path."""
    from zrp_ga.data import resolve

    return resolve(name)


@dataclasses.dataclass
class MeasuredTask(Task):
    """A task on measured data: it also writes the registration, the calibrated arm in the
    instrument's frame and the position error of every pose before and after. A result worse
    than the nominal arm on the calibration data is replaced by the nominal arm."""

    registration: Registration | None = None
    sets: dict[str, Measurements] = dataclasses.field(default_factory=dict)
    gp: bool = False  # the model has a Gaussian-process residual (problem.model: zrp_ga.problems.choice)
    residual: Residual | None = None  # ... fitted to the final genome (fit_residual)
    nominal_if_worse: ClassVar[bool] = True

    def fit_residual(self, x: np.ndarray | None) -> None:
        """The Gaussian process on genome ``x``'s position residuals at the calibration poses
        (:func:`zrp_ga.problems.choice.residual_model`), the judge's correction; None: none."""
        if not self.gp:
            return
        self.residual = None if x is None else choice.residual_model(self, x, self.sets["calibration"])
        self.judge.correction = None if self.residual is None else self.residual.correction

    def errors(self, x: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Position errors (m) of every pose of each set, nominal and calibrated (the validation
        set registered as the judge registers it)."""
        p, judge = self.problem, self.judge
        out = {}
        for k, m in self.sets.items():
            how = judge.registration if k == "validation" else "none"
            out[k] = (metrics.position_errors(p.layout, p.nominal, np.zeros_like(x), m, how),
                      metrics.position_errors(p.layout, p.nominal, x, m, how, correction=self.judge.correction))
        return out

    def report(self, x: np.ndarray) -> dict[str, Any]:
        mm = lambda e: {k: v * 1e3 if k != "poses" else v for k, v in metrics.summary(e).items()}
        assert self.registration is not None  # from_measurements registers every measured task
        return {
            **({"residual_model": self.residual.hyperparameters()} if self.residual is not None else {}),
            "registration": self.registration.to_dict(),
            "position_error_mm": {k: {"nominal": mm(b), "calibrated": mm(a)} for k, (b, a) in self.errors(x).items()},
        }

    def export(self, x: np.ndarray) -> tuple[ZRPRobot, np.ndarray, dict[str, np.ndarray]]:
        """The calibrated arm in its base frame ending at the hand, the base transform (4, 4)
        (robot base in the instrument's frame, the registration's) and every tool's transform
        (4, 4) in the hand frame, so that ``base @ arm(q) @ tool_k`` is tool k's calibrated pose
        in the instrument's frame (module docstring)."""
        p, reg = self.problem, self.registration
        assert reg is not None  # from_measurements registers every measured task
        Rt = reg.R.T
        in_base = self.calibrated_robot(x).transformed(Rt, -Rt @ reg.t)
        turn = np.eye(3) if reg.tool_rotation is None else reg.tool_rotation
        arm = in_base.replace(R_h0=in_base.R_h0 @ turn.T).with_tool(-reg.tool)
        ends = p.layout.unpack(p.nominal, x).ends[:, :, 0]  # every tool's last body vector, instrument frame
        tools = {}
        for name, end in zip(self.tool_names, ends):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = turn, arm.R_h0.T @ (Rt @ end - arm.b0[-1])
            tools[name] = T
        return arm, reg.base(), tools

    @property
    def tool_names(self) -> tuple[str, ...]:
        """Names of the layout's tools: the calibration's, then the known ones (as the
        validation set's tool indices count them)."""
        return tuple(self.info["tools"]) + tuple(self.info.get("known_tools", {}))

    def write(self, out: Path, x: np.ndarray) -> None:
        """The registration, the calibrated arm in the instrument's frame and every pose's
        position error, nominal and calibrated, with where the pose lies against the
        calibration poses (``outside``, ``distance_ratio``: :mod:`zrp_ga.model.coverage`) and,
        for a calibrated arm, its predicted 1-sigma error (``predicted_mm``,
        :mod:`zrp_ga.model.uncertainty`, with a residual model's predictive spread in quadrature)."""
        assert self.registration is not None  # from_measurements registers every measured task
        records.write_json(out / "registration.json", self.registration.to_dict())
        if self.residual is not None:
            self.residual.write(out / residual_file.FILE)
        self.calibrated_robot(x).to_yaml(out / INSTRUMENT_MODEL)
        names, rows = self.tool_names, []
        region = Coverage(self.problem.data.q)
        unc = identify.uncertainty(self.problem, x, self.setup) if np.any(x) else None
        for k, (before, after) in self.errors(x).items():
            m = self.sets[k]
            where = region.assess(m.q)
            predicted = None if unc is None else unc.position_m(m.q, m.tools)
            assert m.lines is not None  # Measurements numbers its rows
            if predicted is not None and self.residual is not None:  # the residual model's own spread, as a radius
                predicted = np.hypot(predicted, self.residual.spread(m.q))
            rows += [{"set": k, "line": int(line), **({"tool": names[t]} if len(names) > 1 else {}),
                      "nominal_mm": b * 1e3, "calibrated_mm": a * 1e3,
                      "predicted_mm": float(predicted[j]) * 1e3 if predicted is not None else "",
                      "outside": bool(where.outside[j]), "distance_ratio": float(where.ratio[j])}
                     for j, (line, t, b, a) in enumerate(zip(m.lines, m.tools, before, after))]  # fmt: skip
        records.write_csv(out / POSE_ERRORS, rows)


def measured_format(robot: ZRPRobot, c: MeasuredConf) -> measurements.Format:
    """The file format of ``c``: the zrp CSV format in its units, or the UR10 files (whose
    orientation convention a stated one replaces)."""
    if c.format is Format.ur10_ipa:
        fmt = measurements.UR10_IPA
        return fmt if c.orientation_convention is None else dataclasses.replace(fmt, orientation_convention=c.orientation_convention)
    return measurements.zrp_format(robot.n, c.length_unit, c.angle_unit, c.orientation_convention)


def build(robot: ZRPRobot, run_seed: int = 0, **settings) -> MeasuredTask:
    """Read and split the measurement files of ``settings`` (``zrp_ga.core.schema.MeasuredConf``'s
    keys, :func:`read_sets`), choose the model (``problem.model``: :func:`chosen`), then
    :func:`from_measurements`."""
    c: MeasuredConf = section(MeasuredConf, settings, "problem")
    calib, val = read_sets(robot, run_seed, c)
    return chosen(robot, calib, val, c, run_seed)


def chosen(robot: ZRPRobot, calib: Measurements, val: Measurements | None, c: MeasuredConf, seed: int = 0,
           progress=None) -> MeasuredTask:  # fmt: skip
    """The task of the model ``problem.model`` names or chooses (:mod:`zrp_ga.problems.choice`:
    cross-validation on ``calib`` only, its fold scheme from the validation poses' joint values;
    the table in ``summary.json``'s ``problem.model``); one candidate: no cross-validation."""
    cands = choice.candidates(getattr(c, "model", "geometric"), getattr(c, "terms", None))
    if len(cands) == 1 and cands[0].name == "geometric":
        return from_measurements(robot, calib, val, c)
    calib = calib.with_tool_names(calib.tool_names or ("tool",))
    picked = choice.select(refit(robot, c), calib, cands, None if val is None else val.q, seed=seed, progress=progress)
    if picked.scheme.warning and len(cands) > 1:
        warn(picked.scheme.warning, log)
    task = from_measurements(robot, calib, val, with_candidate(c, picked.candidate))
    task.gp = picked.candidate.residual
    task.info["model"] = picked.to_dict()
    if picked.scheme.warning and len(cands) > 1:
        task.warnings.append(picked.scheme.warning)
    return task


def with_candidate(c: MeasuredConf, cand: choice.Candidate) -> MeasuredConf:
    """``c`` with the candidate's terms (and no further choice)."""
    return dataclasses.replace(c, terms=cand.terms, model="geometric")


def refit(robot: ZRPRobot, c: MeasuredConf) -> choice.Fit:
    """The parametric fit a fold of the cross-validation makes: the whole calibration again on
    its poses (registration, the identified genome) with the candidate's terms, by
    Levenberg-Marquardt from the nominal arm (kept when it fits no better); its warnings are not
    shown (the final calibration's are)."""
    from zrp_ga.problems.least_squares import levenberg_marquardt

    def fit(data: Measurements, terms) -> tuple[MeasuredTask, np.ndarray]:
        previous = logging.root.manager.disable
        logging.disable(logging.WARNING)
        try:
            with warnings_module.catch_warnings():
                warnings_module.simplefilter("ignore")
                task = from_measurements(robot, data, None, dataclasses.replace(c, terms=terms, model="geometric"))
                found = levenberg_marquardt(task.problem)
        finally:
            logging.disable(previous)
        zero = np.zeros(task.problem.lower.size)
        nominal = float(task.problem.costs(zero)[0])
        return task, found.x if found.x is not None and found.cost <= nominal else zero

    return fit


def read_sets(robot: ZRPRobot, seed: int, c: MeasuredConf) -> tuple[Measurements, Measurements | None]:
    """The calibration and validation measurements of ``c`` (None: no validation): the files,
    or the calibration file split at random. The validation file is read in the units the
    calibration file was found in."""
    fmt = measured_format(robot, c)
    assert c.calibration_file  # MeasuredConf.check requires it
    if c.format is Format.zrp:
        orientation_columns(header(data_path(c.calibration_file)), c.calibration_file, c)
    calib = measurements.read(data_path(c.calibration_file), fmt, robot, c.drop_bad_rows)
    if c.validation_file:
        length, joint = calib.units
        same = dataclasses.replace(fmt, length_unit=length, joint_unit=joint,
                                   angle_unit=joint if fmt.angle_unit == measurements.AUTO else fmt.angle_unit)  # fmt: skip
        return calib, measurements.read(data_path(c.validation_file), same, robot, c.drop_bad_rows)
    if c.validation_fraction:
        return measurements.split(calib, c.validation_fraction, np.random.default_rng([seed, 2]))
    return calib, None


def header(path: Path) -> list[str]:
    """The column names of a zrp CSV file (none if it cannot be read: reading it says why)."""
    if not Path(path).is_file():  # a FIFO or a device is never opened here (reading it refuses it)
        return []
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return [c.strip() for c in f.readline().split(",")]
    except OSError:
        return []


def orientation_columns(columns: list[str], source: Any, c: MeasuredConf) -> None:
    """Measured orientations (``rx, ry, rz``) without a stated convention are refused in one
    line naming the setting, unless ``problem.use_orientation=false`` says to leave them out."""
    if c.orientation_convention is None and c.use_orientation is not False and {"rx", "ry", "rz"} <= set(columns):
        raise ValueError(f"problem.orientation_convention: {source} has orientation columns rx, ry, rz but no convention is "
                         "stated: set it (an Euler sequence such as XYZ intrinsic or xyz extrinsic, or rotvec as UR "
                         "controllers report), or problem.use_orientation=false to fit positions only")  # fmt: skip


def resolve_orientation(calib: Measurements, c: MeasuredConf) -> tuple[MeasuredConf, list[str]]:
    """``c`` with ``use_orientation`` decided: as set, or (null) whenever the calibration data
    hold orientations of one tool point; a warning when orientations are left out."""
    if c.use_orientation is not None:
        return c, []
    use = calib.R is not None and len(calib.tool_names) <= 1
    why = []
    if calib.R is not None and not use:
        why = [f"{calib.source} measures orientations of {len(calib.tool_names)} tool points; they are not fitted "
               "(orientations are supported with one tool): positions only"]  # fmt: skip
    return dataclasses.replace(c, use_orientation=use), why


def from_measurements(robot: ZRPRobot, calib: Measurements, val: Measurements | None, c: MeasuredConf,
                      underdetermined: bool = False, prepared: bool = True) -> MeasuredTask:  # fmt: skip
    """Register ``robot`` to the calibration points, then the calibration problem in the
    instrument's frame; ``val`` (or None) validates (module docstring). Too few points for the
    parameters are refused unless ``underdetermined`` (pose selection judges small subsets so,
    and says how many directions they identify). ``prepared``: the problem passes its set-up
    (:func:`zrp_ga.problems.identify.prepare`: noise, outliers, the identified genome); pose
    selection's calibrations do not."""
    c, left_out = resolve_orientation(calib, c)
    _check_asked(calib, c)
    names = calib.tool_names or ("tool",)
    known = {str(k): np.asarray(v, dtype=float) * measurements.LENGTH[calib.units[0]] for k, v in (c.known_tools or {}).items()}
    calib = calib.with_tool_names(names)
    if val is not None:
        val = val.with_tool_names(names + tuple(known))
        if c.validation_registration.value == "rigid" and val.M < 3:
            raise ValueError(f"problem.validation_registration: rigid needs at least 3 validation points, {val.source} has {val.M}")
    shared = measurements.check_shared(calib, val) if val is not None else []  # the same rows again: refused or named
    if not underdetermined:
        _check_enough(robot, len(names), calib, bool(c.use_orientation))
    reg = register(robot, calib.q, calib.p, rotations=calib.R if c.use_orientation else None, tools=calib.tool,
                   tool_names=names)  # fmt: skip
    warnings = left_out + shared + _registration_warnings(robot, reg, calib)
    fixed_info: dict[str, Any] = {}
    layout, robot_terms = with_terms(c, Layout(robot.n, base=True, hand=bool(c.use_orientation), tools=tuple(map(tuple, reg.tools[1:] - reg.tool)),
                                               known_tools=tuple(tuple(v - reg.tool) for v in known.values())), robot, fixed_info)  # fmt: skip
    nominal = reg.apply(robot_terms)  # the mass model (with gravity along the base's -z) turns into the instrument's frame
    layout = masked(c, layout, fixed_info)
    scale = term_scales(nominal, layout.unmasked, calib.q)
    half = gene_half_widths(layout, nominal, calib.q, reg, c, scale) if c.ranges is Ranges.data else half_ranges(c, layout, scale)
    data = calib.for_calibration(bool(c.use_orientation), c.use_weights)
    problem = CalibrationProblem(nominal, data, layout, -half, half, c.cost, c.norm, c.orientation_weight, c.kernel)
    setup = None
    if prepared:
        problem, setup = identify.prepare(problem, half / c.search_scale, c.search_scale, c)
    validation = val.for_calibration() if val is not None else None
    name = c.name or f"{robot.name}-{Path(calib.source).stem}"
    info = {"kind": "measured", "files": {"calibration": calib.source, "validation": val.source if val is not None else None},
            "units": {"length": calib.units[0], "joint_angle": calib.units[1]}, "tools": list(names),
            "use_orientation": bool(c.use_orientation),
            **({"known_tools": {k: v.tolist() for k, v in known.items()}} if known else {}),
            **fixed_info, "gene_half_widths": dict(zip(problem.names, problem.upper.tolist())),
            **({"parameter_half_widths": dict(zip(layout.names, half.tolist()))} if problem.layout is not layout else {})}  # fmt: skip
    sets = {"calibration": calib, **({"validation": val} if val is not None else {})}
    judge = Judge(problem.layout, nominal, validation, registration=c.validation_registration.value)
    return MeasuredTask(name, problem, judge, robot, info, warnings, setup, c.if_worse.value if c.if_worse else None,
                        registration=reg, sets=sets)  # fmt: skip


def _check_asked(calib: Measurements, c: MeasuredConf) -> None:
    """What the settings ask of the data: orientations (with a stated convention), standard
    deviations, one tool with orientations."""
    if c.use_orientation and calib.R is None:
        if c.orientation_convention is None and c.format is Format.zrp:
            raise ValueError(f"problem.orientation_convention: state the convention of {calib.source}'s rx, ry, rz "
                             "(an Euler sequence such as XYZ intrinsic or xyz extrinsic, or rotvec as UR controllers report)")  # fmt: skip
        raise ValueError(f"problem.use_orientation: {calib.source} has no orientation columns")
    if c.use_weights and calib.std is None:
        raise ValueError(f"problem.use_weights: {calib.source} has no standard-deviation columns")
    if c.use_orientation and len(calib.tool_names) > 1:
        raise ValueError(f"problem.use_orientation: {calib.source} measures {len(calib.tool_names)} tool points; "
                         "orientations are supported with one tool")  # fmt: skip


def _check_enough(robot: ZRPRobot, n_tools: int, data: Measurements, orientation: bool) -> None:
    """Enough distinct measured points for the parameter combinations the model can identify
    (the unit-length rows give n of them); ValueError saying how many are needed. Before the
    registration the tools' offsets are not known: the rank is that of tools off every axis
    (multiples of ``GENERIC_TOOL_M``), as real tools and reflectors are."""
    tools = tuple(tuple(GENERIC_TOOL_M * (k + 1)) for k in range(1, n_tools))
    layout = Layout(robot.n, base=True, hand=orientation, tools=tools)
    rank = model_rank(robot.with_tool(GENERIC_TOOL_M), layout, not orientation)
    rows = 6 if orientation else 3
    need = math.ceil((rank - robot.n) / rows)
    poses = len(np.unique(data.q, axis=0))
    points = len(np.unique(np.column_stack([data.q, data.tools]), axis=0))
    why = (f"a calibration of {robot.name} needs at least {need} measured points ({rows} rows each for the "
           f"{rank - robot.n} parameter combinations it can identify beyond the axes' unit lengths), and several "
           "times more to average out the noise")  # fmt: skip
    if poses == 1:
        raise ValueError(f"{data.source}: a single pose; {why}")
    if points < need:
        raise ValueError(f"{data.source}: {points} distinct measured points in {poses} poses; {why}")


def _registration_warnings(robot: ZRPRobot, reg: Registration, calib: Measurements) -> list[str]:
    """A nominal arm that the registration leaves far from the points (more than 2% of its
    reach): wrong units, joint order, zero positions or directions, or the wrong robot file."""
    log.info("registered %s to %s: %.3f mm RMS, tool offsets %s mm", robot.name, calib.source, reg.rms * 1e3,
             np.round(reg.tools * 1e3, 2).tolist())  # fmt: skip
    reach = measurements.reach_m(robot)
    if reg.rms <= FAR_REGISTRATION * reach:
        return []
    worst = int(np.argmax(reg.errors))
    return [f"the registered nominal {robot.name} is {reg.rms * 1e3:.4g} mm RMS off the calibration points (more than "
            f"{FAR_REGISTRATION:.0%} of its {reach:.3g} m reach; worst: {calib.where(worst)}, {reg.errors[worst] * 1e3:.4g} mm): "
            f"check the robot file, the joint order, zero positions and directions, and the units (read as "
            f"{calib.units[0]} and {calib.units[1]})"]  # fmt: skip


def gene_half_widths(layout: Layout, nominal: ZRPRobot, q: np.ndarray, reg: Registration, c: MeasuredConf,
                     term_scale: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Half widths (K,) of the gene ranges from the registered arm's residuals (module
    docstring): body vectors, base point and tools ``e``, axis i ``e / L_i``, hand the largest
    orientation residual; times ``search_scale``. Fixed genes: the free ones' widths. Terms
    (``problem.terms``): ``axis_error / term_scale``, a joint turned by up to ``axis_error``."""
    free, layout = layout.free, layout.unmasked
    e = max(reg.max, 1e-6)
    J = error_model.pose_jacobians(nominal, q)[:, 3:, : 3 * layout.n]  # position rows, axis columns
    tilts = [np.eye(3) - np.outer(u, u) for u in nominal.u0]  # an axis only turns: its tangent directions
    lever = np.array([np.median(np.linalg.norm(J[:, :, 3 * i : 3 * i + 3] @ tilts[i], ord=2, axis=(1, 2))) for i in range(layout.n)])
    half = np.full(layout.size, e)
    half[layout.blocks["u0"]] = np.repeat(np.minimum(e / np.maximum(lever, MIN_LEVER_M), MAX_AXIS_RAD / c.search_scale), 3)
    if layout.hand:
        half[layout.blocks["hand"]] = min(max(reg.max_angle or 0.0, 1e-6), MAX_AXIS_RAD / c.search_scale)
    if layout.terms:
        half[layout.blocks["terms"]] = c.axis_error / (np.ones(layout.terms.size) if term_scale is None else term_scale)
    return half[free] * c.search_scale


# --- the size of an instance, before it is built (zrp_ga.problems.size) ------------------------------
def size(robot: ZRPRobot, **settings) -> ProblemSize:
    """The size of the instance :func:`build` makes of ``settings``: :func:`file_size`."""
    return file_size(robot, section(MeasuredConf, settings, "problem"))


def file_size(robot: ZRPRobot, c: MeasuredConf) -> ProblemSize:
    """The size of a calibration on the files of ``c``, their rows estimated from their length
    (:func:`zrp_ga.problems.size.file_rows`; a ``validation_fraction`` of the calibration file
    validates when there is no validation file), their text counted while it is read."""
    rows = [file_rows(data_path(f)) if f else 0 for f in (c.calibration_file, c.validation_file)]
    f = c.validation_fraction or 0.0
    M, V = (rows[0], rows[1]) if rows[1] else (round(rows[0] * (1 - f)), round(rows[0] * f))
    if c.use_orientation is None:  # fitted when the file has them: counted when it may
        assert c.calibration_file  # MeasuredConf.check requires it
        has = c.format is Format.ur10_ipa or {"rx", "ry", "rz"} <= set(header(data_path(c.calibration_file)))
        c = dataclasses.replace(c, use_orientation=bool((has and c.orientation_convention) or c.format is Format.ur10_ipa))
    columns = robot.n + 3 + 3 * bool(c.use_orientation)
    poses = ("problem.calibration_file", f"calibrate on fewer of its about {rows[0]} rows")
    validation = ("problem.validation_file", f"validate on fewer of its about {rows[1]} rows") if rows[1] else poses
    return _sized(robot, c, M, V, (rows[0] * columns, rows[1] * columns), {"poses": poses, "validation": validation})


def data_size(robot: ZRPRobot, c: MeasuredConf, calib: Measurements, val: Measurements | None) -> ProblemSize:
    """The size of :func:`from_measurements` on data in memory (``zrp_ga.calibrate``'s ``data``
    and ``validation``)."""
    c, _ = resolve_orientation(calib, c)
    lower = {"poses": ("data", f"calibrate on fewer of its {calib.M} rows"),
             "validation": ("validation", f"validate on fewer of its {val.M if val is not None else 0} rows")}  # fmt: skip
    return _sized(robot, c, calib.M, 0 if val is None else val.M, (0, 0), lower)


def _sized(robot: ZRPRobot, c: MeasuredConf, M: int, V: int, cells: tuple[int, int], lower: dict) -> ProblemSize:
    """A calibration of ``M`` and ``V`` measured poses; the base point (and the hand with
    orientations) are genes; one tool (the files' tool points are not read yet: 3 genes per
    further tool are left out)."""
    genes = Layout(robot.n, base=True, hand=bool(c.use_orientation)).size
    return calibration(robot.n, genes, M, V, 6 if c.use_orientation else 3, cells, lower)
