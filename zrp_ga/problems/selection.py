"""Pose selection (``problem=pose_selection``, ``problem=ur10_selection``): choose k of N
candidate poses so that a calibration on them alone identifies the parameters well.

The candidates are joint configurations sampled within the arm's limits and measured on a
simulated true arm, or the rows of a measurement file. A genome is k distinct candidate
indices; its cost is an observability index of the scaled error Jacobian of the identifiable
parameters (:mod:`zrp_ga.model.observability`, docs/model.md section 6), computed for a whole
population from precomputed per-pose Jacobian blocks. The GA finds subsets through the
problem's sampling and repair (its declared parts, :mod:`zrp_ga.problems.protocol`) and the subset operators
(:mod:`zrp_ga.operators.subset`); the baselines are :mod:`zrp_ga.algorithms.random_search` and
:mod:`zrp_ga.algorithms.exchange`.

What counts is judged at the end, not per generation (the convergence log's validation
columns stay empty): a calibration (Levenberg-Marquardt) on the chosen poses alone, as
``zrp-ga algorithm=lm`` would run it on a file of those rows (registered to them first, for
measured data), its error on validation poses it never saw and, in simulation, its distance
to the true parameters; beside it the same calibration on all candidates.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.problem import GeneBlocks, Problem, Repairing, Sampling
from zrp_ga.core.schema import Cost, Index, PoseSelectionConf, section
from zrp_ga.io import records
from zrp_ga.model import error_model, metrics, observability, simulation
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.metrics import Judge
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.operators import subset
from zrp_ga.problems import Task, half_ranges, masked
from zrp_ga.problems.least_squares import levenberg_marquardt
from zrp_ga.problems.measured import MeasuredTask, file_size, from_measurements, read_sets
from zrp_ga.problems.protocol import Found, Identifiable, SelfJudging
from zrp_ga.problems.size import EVAL_S, FLOAT, ProblemSize, calibration

Array = NDArray[np.float64]
SELECTED = "selected_poses.csv"


@dataclasses.dataclass
class SelectionProblem(Problem, Sampling, Repairing, GeneBlocks, Identifiable):
    """Choose ``k`` of the poses of ``calibration`` (the calibration problem on all candidates,
    whose nominal arm, data, layout and weights define the Jacobian) to minimise the cost of
    ``index`` (``observability.index_cost``). Genomes: k candidate indices in [0, N), as floats.
    Its parts (:mod:`zrp_ga.problems.protocol`): the costs, its own sampling and repair of
    subsets, one gene block, and the identifiability of its candidates; no Jacobian (no
    least squares, no pseudo-inverse step on subsets).
    ``length_m``: the scale of angle parameters (None: the arm's summed body-vector lengths);
    ``rcond``: which directions count as identifiable; ``ridge``: information added to every
    subset's, relative to the mean eigenvalue of one candidate's (keeps subsets that identify
    too little finite and ranked by how much they identify)."""

    calibration: CalibrationProblem
    k: int
    index: Index = Index.O1
    length_m: float | None = None
    rcond: float = 1e-4
    ridge: float = 1e-6

    def __post_init__(self) -> None:
        c, N, k = self.calibration, self.calibration.data.M, int(self.k)
        if not 1 <= k < N:
            raise ValueError(f"problem.k: must be in [1, {N - 1}] (there are {N} candidate poses), got {self.k}")
        self.k, self.index = k, Index(self.index)
        self.length_m = float(self.length_m or observability.characteristic_length(c.nominal))
        rows = observability.scaled_pose_rows(c.nominal, c.data.q, c.layout, c.data.position_only, self.length_m,
                                              c.orientation_weight, c.data.weights)  # fmt: skip
        self.basis = observability.identifiable_basis(rows, self.rcond)  # (K, m)
        self.blocks = observability.reduced_rows(rows, self.basis)  # (N, r, m)
        self.ridge_information = self.ridge * np.sum(self.blocks**2) / (N * self.m)  # trace of sum A_c / (N m)
        self.lower, self.upper = np.zeros(k), np.full(k, N - 1.0)
        self.gene_blocks = [(0, k)]  # one block: the GA's block-wise operators act on the whole genome

    @property
    def names(self) -> list[str]:
        return [f"pose_{j}" for j in range(1, self.k + 1)]

    @property
    def m(self) -> int:
        """The number of identifiable directions."""
        return self.basis.shape[1]

    @property
    def n_candidates(self) -> int:
        return self.calibration.data.M

    # --- Identifiable: the candidates' calibration data, whose identifiability a run records ----
    @property
    def nominal(self) -> ZRPRobot:
        return self.calibration.nominal

    @property
    def data(self) -> Measurements:
        return self.calibration.data

    @property
    def layout(self) -> Layout:
        return self.calibration.layout

    def identifiability(self) -> error_model.IdentifiabilityReport:
        """The identifiability of all candidates together (:meth:`CalibrationProblem.identifiability`)."""
        return self.calibration.identifiability()

    # --- a population -----------------------------------------------------------------------
    def information(self, X: ArrayLike) -> Array:
        """``G_S + ridge I`` (P, m, m) of every subset (row) of X (P, w), any width w."""
        X = np.atleast_2d(np.rint(np.asarray(X, dtype=float))).astype(np.intp)
        G = observability.subset_information(self.blocks, X)
        G[:, np.arange(self.m), np.arange(self.m)] += self.ridge_information
        return G

    def indices(self, X: ArrayLike) -> dict[str, Array]:
        """O1, O2, O3, O4 and A of every subset of X (P, w), each (P,)."""
        X = np.atleast_2d(X)
        return observability.indices(self.information(X), X.shape[1])

    def costs(self, X: ArrayLike) -> Array:
        """The cost (P,) of every subset of X (P, w): ``1 / O`` for O1-O4, A for A-optimality."""
        X = np.atleast_2d(X)
        return observability.index_cost(self.information(X), X.shape[1], self.index.value)

    # --- Sampling and Repairing: a combinatorial genome --------------------------------------
    def sample(self, rng: np.random.Generator, size: int) -> Array:
        """``size`` subsets, uniform: (size, k)."""
        return subset.sample(rng, size, self.k, self.n_candidates)

    def repair(self, X: Array, rng: np.random.Generator) -> Array:
        """Indices rounded into [0, N), repeats replaced by random candidates; in place."""
        return subset.repair(X, rng, self.n_candidates)


@dataclasses.dataclass
class Judgement:
    """A calibration (LM) on some candidate rows: its ``task`` and gauge-fixed genome ``x``;
    validation RMS and max position error (m) of the nominal and the calibrated arm; distance
    to the true parameters (NaN unless simulated); RMS error on the rows themselves (m)."""

    task: Task
    x: Array
    val_rms_m: tuple[float, float]
    val_max_m: tuple[float, float]
    param_err: tuple[float, float]
    fit_rms_m: float
    nevals: int


def judge(task: Task) -> Judgement:
    """Calibrate ``task`` with Levenberg-Marquardt from the nominal arm and judge the result."""
    from threadpoolctl import threadpool_limits

    p = task.problem
    with threadpool_limits(limits=1, user_api="blas"):  # as the app runs its optimisers
        fit = levenberg_marquardt(p)  # as zrp-ga algorithm=lm runs it
    assert fit.x is not None  # the start, the nominal arm, has a finite cost
    x = error_model.canonical(p.layout, p.nominal, fit.x) if p.cost is Cost.nonlinear else fit.x
    zero = np.zeros_like(x)
    both = np.vstack([zero, x])
    rms, vmax = task.judge.validation_errors(both)
    err = task.judge.param_error(both)
    fit_err = metrics.position_errors(p.layout, p.nominal, x, p.data)
    pair = lambda a: (float(a[0]), float(a[1]))
    return Judgement(task, x, pair(rms), pair(vmax), pair(err), float(np.sqrt(np.mean(fit_err**2))), fit.nevals)


@dataclasses.dataclass
class SelectionTask(Task, SelfJudging):
    """A pose-selection instance. ``calibrate_on(rows)`` builds the calibration task of some
    candidate rows; ``reference``: also judge the calibration on all candidates. It judges its
    own results (:class:`zrp_ga.problems.protocol.SelfJudging`): :meth:`judged`, :meth:`params_table`."""

    # Not Task's CalibrationProblem: the methods of Task that use one are overridden here.
    problem: SelectionProblem  # type: ignore[assignment]  # a pose subset's problem, not a calibration's
    calibrate_on: Callable[[NDArray[np.intp]], Task] | None = None
    candidates: Measurements | None = None
    reference: bool = True
    truth_x: Array | None = None
    _judged: dict = dataclasses.field(default_factory=dict, repr=False)

    def chosen(self, x: ArrayLike) -> NDArray[np.intp]:
        """The candidate indices of a genome, as integers."""
        return np.rint(np.asarray(x, dtype=float)).astype(np.intp)

    def judgement(self, rows: ArrayLike) -> Judgement:
        """:func:`judge` of the calibration on ``rows`` (cached)."""
        rows = self.chosen(rows)
        key = tuple(sorted(rows.tolist()))
        if key not in self._judged:
            assert self.calibrate_on is not None  # build() gives it
            self._judged[key] = judge(self.calibrate_on(rows))
        return self._judged[key]

    def candidates_rms_m(self, x: ArrayLike) -> float:
        """RMS position error (m) over all candidates of the calibration on the poses of ``x``:
        how it does on the poses it could have used (with a validation set from elsewhere,
        the difference tells a shift between the two sets from a poor calibration)."""
        j = self.judgement(x)
        p = j.task.problem
        err = metrics.position_errors(p.layout, p.nominal, j.x, self.problem.data)
        return float(np.sqrt(np.mean(err**2)))

    def calibrated_robot(self, x: ArrayLike) -> ZRPRobot:
        """The arm calibrated on the poses of genome ``x``."""
        j = self.judgement(x)
        return j.task.calibrated_robot(j.x)

    def export(self, x: ArrayLike) -> tuple[ZRPRobot, Array | None, dict[str, Array]]:
        """The arm calibrated on the poses of genome ``x`` as robot files carry it (:meth:`Task.export`)."""
        j = self.judgement(x)
        return j.task.export(j.x)

    def judged(self, result: Found) -> tuple[dict[str, Any], NDArray[np.intp]]:
        """``summary.json``'s judgement of the best subset (see :func:`zrp_ga.run.summary.judged`)."""
        assert result.x is not None  # every pose subset has a finite cost
        x = self.chosen(result.x)
        j = self.judgement(x)
        mm = lambda pair: {"nominal": pair[0] * 1e3, "calibrated": pair[1] * 1e3}
        judged = {"final_cost": result.cost, "optimiser_cost": result.cost, "returned": "optimiser",
                  "nominal_cost": None, "validation_rms_mm": mm(j.val_rms_m), "validation_max_mm": mm(j.val_max_m),
                  "param_err": {"nominal": j.param_err[0], "calibrated": j.param_err[1]},
                  "warnings": [*self.warnings, *self.subset_warnings(x, j)], "best_genome": dict(zip(self.problem.names, x.tolist()))}  # fmt: skip
        return judged, x

    def identified(self, x: ArrayLike) -> int:
        """How many of the m identifiable directions the poses of ``x`` identify (without the ridge)."""
        G = observability.subset_information(self.problem.blocks, self.chosen(x)[None])[0]
        s = np.sqrt(np.maximum(np.linalg.eigvalsh(G), 0.0))
        return int(np.sum(s > self.problem.rcond * s[-1]))

    def subset_warnings(self, x: NDArray[np.intp], j: Judgement) -> list[str]:
        """Too few directions identified by the chosen poses; a calibration on them worse than nominal."""
        out, p = [], self.problem
        r = self.identified(x)
        if r < p.m:
            per_pose = 3 if p.data.position_only else 6
            out.append(f"the {p.k} chosen poses identify {r} of the {p.m} directions the candidates can "
                       f"({per_pose} equations per pose; at least {-(-p.m // per_pose)} poses needed): choose more")  # fmt: skip
        if np.isfinite(j.val_rms_m[1]) and j.val_rms_m[1] > j.val_rms_m[0]:
            out.append(f"the calibration on the chosen poses predicts the validation poses worse than the nominal arm "
                       f"(RMS {j.val_rms_m[1] * 1e3:.4g} mm > {j.val_rms_m[0] * 1e3:.4g} mm)")  # fmt: skip
        return out

    def report(self, x: ArrayLike) -> dict[str, Any]:
        """``summary.json``'s ``selection`` entry: the chosen poses, their indices, the
        calibration on them and (``reference``) the calibration on all candidates."""
        x, p = self.chosen(x), self.problem
        assert self.candidates is not None and self.candidates.lines is not None  # build() gives them, rows numbered
        values = {k: float(v[0]) for k, v in p.indices(x[None]).items()}
        out = {"k": p.k, "index": p.index.value, "candidates": p.n_candidates, "identifiable_directions": p.m,
               "identified_directions": self.identified(x), "length_scale_m": p.length_m,
               "poses": x.tolist(), "lines": self.candidates.lines[x].tolist(), "indices": values,
               "calibration": {**_entry(self.judgement(x)), "candidates_rms_mm": self.candidates_rms_m(x) * 1e3}}  # fmt: skip
        if self.reference:
            every = np.arange(p.n_candidates)
            out["all_candidates"] = {"indices": {k: float(v[0]) for k, v in p.indices(every[None]).items()},
                                     "identified_directions": self.identified(every), **_entry(self.judgement(every))}  # fmt: skip
        return {"selection": out}

    def params_table(self, x: ArrayLike) -> list[dict]:
        """``best_params.csv``: the parameter errors calibrated on the chosen poses, by joint,
        beside the true ones in simulation."""
        j = self.judgement(x)
        p = j.task.problem
        truth = None if self.truth_x is None else error_model.canonical(p.layout, p.nominal, self.truth_x)
        return records.params_by_joint(p.layout, j.x, truth)

    def write(self, out: Path, x: ArrayLike) -> None:
        """``selected_poses.csv``: candidate index, file line, joint values (the arm calibrated
        on them goes to the robot files, :func:`zrp_ga.run.summary.write_robot`)."""
        assert self.candidates is not None  # build() gives them
        x, q = self.chosen(x), self.candidates.q
        assert self.candidates.lines is not None  # Measurements numbers its rows
        records.write_csv(out / SELECTED, [{"candidate": int(c), "line": int(self.candidates.lines[c]),
                                            **{f"q{i + 1}": v for i, v in enumerate(q[c])}} for c in x])  # fmt: skip


def _entry(j: Judgement) -> dict[str, Any]:
    out = {"val_rms_mm": j.val_rms_m[1] * 1e3, "val_max_mm": j.val_max_m[1] * 1e3, "param_err": j.param_err[1],
           "fit_rms_mm": j.fit_rms_m * 1e3, "nominal_val_rms_mm": j.val_rms_m[0] * 1e3, "lm_nevals": j.nevals}  # fmt: skip
    if isinstance(j.task, MeasuredTask) and j.task.registration is not None:  # measured: registered to these rows
        out["registration_rms_mm"] = j.task.registration.rms * 1e3
    return out


# --- building an instance --------------------------------------------------------------------------
def joints_within_limits(robot: ZRPRobot, M: int, rng: np.random.Generator) -> Array:
    """M configurations (M, n) uniform within the arm's joint limits (rad, m)."""
    lo, hi = robot.joint_limits.T
    return rng.uniform(lo, hi, size=(M, robot.n))


def _simulated_task(robot, layout, candidates, validation, truth_x, projector, c, rows) -> Task:
    data = candidates.subset(rows)
    half = half_ranges(c, layout)
    problem = CalibrationProblem(robot, data, layout, -half, half, c.cost, c.norm, c.orientation_weight)
    return Task(f"{robot.name}-{len(rows)}poses", problem, Judge(layout, robot, validation, truth_x, projector), robot)


def simulated(robot: ZRPRobot, seed: int, c: PoseSelectionConf) -> dict[str, Any]:
    """A true arm around ``robot``, ``n_candidates`` candidate and ``n_validation`` validation
    poses within its limits, measured on it (drawn from ``[problem.seed or seed, 1]`` in that order)."""
    info = {"kind": "pose_selection"}
    full = Layout(robot.n, base=c.identify_base, hand=c.identify_hand)
    layout = masked(c, full, info)  # the calibrations' choice; the true arm is the same either way
    instance = seed if c.seed is None else c.seed
    rng = np.random.default_rng([instance, 1])
    truth = simulation.true_robot(robot, full, rng, c.axis_error, c.body_error)
    noise: dict[str, Any] = dict(joint_noise=c.joint_noise, position_noise=c.position_noise, orientation_noise=c.orientation_noise,
                 position_only=c.position_only)  # fmt: skip
    cand = simulation.measure(truth, joints_within_limits(robot, c.n_candidates, rng), rng, **noise)
    val = simulation.measure(truth, joints_within_limits(robot, c.n_validation, rng), rng, **noise)
    truth_x = full.pack(robot, truth)
    projector = metrics.identifiable_projector(robot, full, np.vstack([cand.q, val.q]), c.position_only)
    on = functools.partial(_simulated_task, robot, layout, cand, val, truth_x, projector, c)
    name = f"{robot.name}-select{c.k}of{c.n_candidates}-{c.index.value}-seed{instance}"
    return dict(candidates=cand, calibrate_on=on, truth_x=truth_x, name=name, info=info | {"seed": instance})


def measured(robot: ZRPRobot, seed: int, c: PoseSelectionConf) -> dict[str, Any]:
    """The rows of ``calibration_file`` as candidates, validated on ``validation_file`` (or a
    random ``validation_fraction`` of the rows); each calibration registers to its own rows."""
    cand, val = read_sets(robot, seed, c)
    on = lambda rows: from_measurements(robot, cand.subset(rows), val, c, underdetermined=True, prepared=False)
    files = {"calibration": cand.source, "validation": val.source if val is not None else None}
    name = f"{robot.name}-{Path(cand.source).stem}-select{c.k}-{c.index.value}"
    return dict(candidates=cand, calibrate_on=on, truth_x=None, name=name, info={"kind": "pose_selection", "files": files})


def build(robot: ZRPRobot, run_seed: int = 0, **settings) -> SelectionTask:
    """The pose-selection instance of ``settings`` (``zrp_ga.core.schema.PoseSelectionConf``'s keys):
    simulated candidates, or the rows of ``calibration_file``."""
    c: PoseSelectionConf = section(PoseSelectionConf, settings, "problem")
    if c.terms:  # the observability indices are those of the geometric model
        raise ValueError("problem.terms: pose selection chooses poses for the geometric model; calibrate with terms afterwards "
                         "(problem=measured with the chosen poses)")  # fmt: skip
    parts = measured(robot, run_seed, c) if c.calibration_file else simulated(robot, run_seed, c)
    everything = parts["calibrate_on"](np.arange(parts["candidates"].M))
    problem = SelectionProblem(everything.problem, c.k, c.index, c.length_scale, c.rcond, c.ridge)
    cheap = Judge(everything.problem.layout, everything.problem.nominal)  # per generation: nothing (see the module docstring)
    task = SelectionTask(c.name or parts["name"], problem, cheap, robot, parts["info"], calibrate_on=parts["calibrate_on"],
                         candidates=parts["candidates"], reference=c.reference, truth_x=parts["truth_x"])  # fmt: skip
    task.info.update(k=c.k, index=c.index.value, candidates=problem.n_candidates, identifiable_directions=problem.m)
    return task


def size(robot: ZRPRobot, **settings) -> ProblemSize:
    """The size of the instance :func:`build` makes of ``settings``: the calibration problem on
    all N candidates (:func:`zrp_ga.problems.size.calibration`; the rows of ``calibration_file``,
    :func:`zrp_ga.problems.measured.file_size`) and, per subset of ``k`` evaluated at once, its
    information matrix and blocks: ``k r K + 2 K^2 + 2 k`` numbers, ``3e-8 s k K^2``."""
    c: PoseSelectionConf = section(PoseSelectionConf, settings, "problem")
    if c.calibration_file:
        p, r = file_size(robot, c), 6 if c.use_orientation else 3
    else:
        r = 3 if c.position_only else 6
        genes = Layout(robot.n, base=c.identify_base, hand=c.identify_hand).size
        p = calibration(robot.n, genes, c.n_candidates, c.n_validation, r,
                        lower={"poses": ("problem.n_candidates", "lower problem.n_candidates")})  # fmt: skip
    K, k = p.genes, c.k
    N = (p.rows - robot.n) // r
    return dataclasses.replace(p, genes=k, rows=0, genome_bytes=FLOAT * (k * r * K + 2 * K * K + 2 * k),
                               evaluation_s=EVAL_S * k * K * K, choices=N)  # fmt: skip
