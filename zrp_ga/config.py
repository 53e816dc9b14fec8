"""The typed config schema: every key, its type and its default, in one place.

The dataclasses are registered in Hydra's ConfigStore (:func:`register`): ``config_schema`` is
the first entry of ``conf/config.yaml``'s defaults list, and the options of the
``problem`` and ``algorithm`` groups extend their own schema (``- /ga_schema@_here_`` in
``conf/algorithm/ga.yaml``). A key that is not in the schema (``problem.n_pose=30``) or a value
of the wrong type fails at composition, before anything runs; string choices are Enums, so
``algorithm.strategy=steady`` fails there too. Values that are well typed but meaningless
(``population.mu=0``) are refused by each section's ``check``, which names the key.

Objects are built from the ``_target_`` entries by ``hydra.utils.instantiate``: the robot, the
problem (a :class:`zrp_ga.problems.Task`) and the optimiser. This module imports nothing heavy,
so that ``zrp-ga --help`` starts fast.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
import re
import typing
from typing import Any, Optional

from omegaconf import MISSING, DictConfig, ListConfig


class ConfigError(ValueError):
    """A setting that cannot run; the message names the key."""


class Cost(enum.Enum):
    linear = "linear"  # the paper: |[dr; dp; 0] - J x| with J at the nominal parameters
    nonlinear = "nonlinear"  # the forward-kinematics residual


class Objective(enum.Enum):
    final_cost = "final_cost"  # what a run returns to a sweeper (Optuna, nevergrad): its final cost
    over_floor = "over_floor"  # the final cost over the instance's floor (LM's cost, summary.json "floor")


class Norm(enum.Enum):
    spectral = "spectral"  # 2-norm of the residual vector
    rms = "rms"  # 2-norm / sqrt(rows)


class Subspace(enum.Enum):
    identified = "identified"  # move only the combinations the data identify (zrp_ga.model.subspace)
    full = "full"  # move every free parameter (zrp_ga 0.1)


class Loss(enum.Enum):
    linear = "linear"  # least squares
    soft_l1 = "soft_l1"  # scipy.optimize.least_squares' robust losses (zrp_ga.problems.robust)
    huber = "huber"


class Outliers(enum.Enum):
    report = "report"  # name them (file, line, size)
    drop = "drop"  # and fit without them


class IfWorse(enum.Enum):
    nominal = "nominal"  # return the nominal arm instead
    keep = "keep"  # return the calibrated one anyway (with the warning)


class Kernel(enum.Enum):
    rodrigues = "rodrigues"  # float64, bit-identical to zrp_ga 0.1
    matrix = "matrix"  # float64, matrix form with fused multiply-adds: 2x faster, last bits differ
    float32 = "float32"  # float32 with float64 sums: 3.5x faster; ranks a GA population, not for costs near 1e-7


class Strategy(enum.Enum):
    mu_plus_lambda = "mu_plus_lambda"  # the paper: parents and offspring compete
    mu_comma_lambda = "mu_comma_lambda"  # the best mu of the offspring
    generational = "generational"  # the offspring, keeping `elite` parents


class Repair(enum.Enum):
    clip = "clip"  # to the bound
    reflect = "reflect"  # off the bound, folding any distance back into the range


class Format(enum.Enum):
    zrp = "zrp"  # zrp_ga's CSV format (zrp_ga/io/measurements.py)
    ur10_ipa = "ur10_ipa"  # the UR10 laser-tracker files of Landgraf et al.


class Index(enum.Enum):
    """Observability indices for pose selection (docs/model.md, section 6; zrp_ga.model.observability)."""

    O1 = "O1"  # D-optimality: (s_1 ... s_m)^(1/m) / sqrt(M)
    O2 = "O2"  # inverse condition number s_m / s_1
    O3 = "O3"  # minimum singular value s_m
    O4 = "O4"  # noise amplification index s_m^2 / s_1
    A = "A"  # A-optimality: trace(G^-1)


def _require(ok: bool, key: str, what: str, value: Any) -> None:
    if not ok:
        raise ConfigError(f"{key}: must be {what}, got {value}")


def _finite(value: float | None) -> bool:
    return value is None or math.isfinite(value)


# --- the GA's parts ------------------------------------------------------------------------------
@dataclasses.dataclass
class PopulationConf:
    mu: int = 20  # parents
    lambda_: int = 20  # offspring per generation (CMA-ES: its population size)
    generations: Optional[int] = 11  # stop after this many generations (null: no limit)
    max_evals: Optional[int] = None  # stop after this many cost evaluations (null: no limit)

    def check(self, key: str = "population") -> None:
        _require(self.mu >= 1, f"{key}.mu", "at least 1", self.mu)
        _require(self.lambda_ >= 1, f"{key}.lambda_", "at least 1", self.lambda_)
        if self.generations is None and self.max_evals is None:
            raise ConfigError(f"{key}: set generations or max_evals, or both")
        _require(self.generations is None or self.generations >= 1, f"{key}.generations", "at least 1", self.generations)
        _require(self.max_evals is None or self.max_evals > self.mu, f"{key}.max_evals",
                 f"more than the initial population (mu = {self.mu})", self.max_evals)  # fmt: skip


@dataclasses.dataclass
class VariationConf:
    """crossover, mutation, inversion, rotation: an operator and the probability of applying it
    (per pair for crossover, per child otherwise)."""

    prob: float = 0.0
    op: Optional[Any] = None  # {_target_: dotted.name, _partial_: true, params...}; null: none

    def check(self, key: str) -> None:
        _require(0.0 <= self.prob <= 1.0, f"{key}.prob", "a probability in [0, 1]", self.prob)


@dataclasses.dataclass
class SelectionConf:
    op: Any = MISSING  # {_target_: dotted.name, _partial_: true, params...}


@dataclasses.dataclass
class RefineConf:
    """The pseudo-inverse step (the paper's step 8) for a share of each generation's children."""

    share: float = 0.0
    op: Optional[Any] = None

    def check(self, key: str = "refine") -> None:
        _require(0.0 <= self.share <= 1.0, f"{key}.share", "a share in [0, 1]", self.share)


# --- optimisers ----------------------------------------------------------------------------------
@dataclasses.dataclass
class GAConf:
    _target_: str = "zrp_ga.algorithms.ga.GA"
    _recursive_: bool = False  # the GA binds its operators itself (see zrp_ga.operators.build)
    population: Any = "${population}"
    selection: Any = "${selection}"
    crossover: Any = "${crossover}"
    mutation: Any = "${mutation}"
    inversion: Any = "${inversion}"
    rotation: Any = "${rotation}"
    refine: Any = "${refine}"
    strategy: Strategy = Strategy.mu_plus_lambda
    elite: int = 1  # parents kept by the generational strategy
    repair: Repair = Repair.clip  # how genes come back into their ranges
    target_cost: Optional[float] = None  # stop when the best cost reaches it
    stagnation: Optional[int] = None  # stop after this many generations without improvement


@dataclasses.dataclass
class LMConf:
    _target_: str = "zrp_ga.algorithms.lm.LM"
    max_evals: Optional[int] = None  # cap on residual evaluations (null: MINPACK's own)


@dataclasses.dataclass
class CMAESConf:
    _target_: str = "zrp_ga.algorithms.cmaes.CMAES"
    population: Any = "${population}"  # lambda_: CMA-ES's population size; generations, max_evals: its budget
    sigma0: float = 0.3  # initial standard deviation, as a fraction of each gene's range


@dataclasses.dataclass
class RandomSearchConf:
    _target_: str = "zrp_ga.algorithms.random_search.RandomSearch"
    samples: int = 1  # random genomes (pose selection: subsets) drawn; the best is kept (1: a random choice)
    batch: int = 100  # genomes per row of convergence.csv


@dataclasses.dataclass
class ExchangeConf:
    _target_: str = "zrp_ga.algorithms.exchange.Exchange"
    max_evals: Optional[int] = None  # cap on index evaluations (null: until no exchange improves)


# --- problems and robots -------------------------------------------------------------------------
@dataclasses.dataclass
class ProblemConf:
    """What every problem kind shares: the genome, the cost, the gene ranges."""

    name: Optional[str] = None  # the instance's name in every file (null: derived from the config)
    identify_base: bool = False  # add b0_1 to the genome
    identify_hand: bool = False  # add the hand orientation
    fixed: Optional[list[str]] = None  # parameters held at nominal: u0_i, b0_i, base, tool, hand, tools, axes, links, b0_3x (docs/model.md 3.1)
    free: Optional[list[str]] = None  # or the only ones calibrated (with fixed: fixed less these)
    axis_error: float = 0.01  # gene ranges: +-axis_error x search_scale on the axes (rad) ...
    body_error: float = 0.0005  # ... +-body_error x search_scale (m) on the body vectors
    search_scale: float = 1.0
    cost: Cost = Cost.linear
    norm: Norm = Norm.spectral
    orientation_weight: float = 1.0  # m per rad in the residual
    kernel: Kernel = Kernel.rodrigues  # the compiled cost of a population (zrp_ga.model.kinematics.KERNELS)
    subspace: Subspace = Subspace.identified  # what the fit may move: the identified combinations, or every free parameter
    max_se: float = 0.5  # identified: a combination's standard error at most this many expected errors (zrp_ga.model.subspace)
    loss: Loss = Loss.linear  # soft_l1 or huber: a robust fit
    loss_scale: Optional[float] = None  # m, where the robust loss turns linear (null: 1.345 x the noise, Huber's)
    outliers: Outliers = Outliers.report  # points far beyond the noise: named, or dropped and the fit repeated
    if_worse: Optional[IfWorse] = None  # a model worse than nominal: nominal or keep (null: measured nominal, simulated keep)

    def check(self, key: str = "problem") -> None:
        _require(math.isfinite(self.max_se) and self.max_se > 0, f"{key}.max_se", "a number > 0", self.max_se)
        s = self.loss_scale
        _require(s is None or (math.isfinite(s) and s > 0), f"{key}.loss_scale", "a length > 0 (m) or null", s)
        for name in ("axis_error", "body_error", "search_scale"):
            value = getattr(self, name)
            _require(math.isfinite(value) and value > 0, f"{key}.{name}", "a number > 0", value)
        _require(math.isfinite(self.axis_error * self.search_scale) and self.axis_error * self.search_scale < 1.0,
                 f"{key}.axis_error", f"below 1 / search_scale (axis errors are rad; {self.search_scale} x {self.axis_error} "
                 "would let an axis turn over)", self.axis_error)  # fmt: skip
        w = self.orientation_weight
        _require(math.isfinite(w) and w >= 0, f"{key}.orientation_weight", "a number >= 0", w)


@dataclasses.dataclass
class SimulatedConf(ProblemConf):
    _target_: str = "zrp_ga.problems.simulated.build"
    n_poses: int = 1
    n_validation: int = 100  # unseen poses, never in the cost
    joint_noise: float = 0.001  # U(+-joint_noise) rad on the joints the arm really took
    position_noise: float = 0.0  # Gaussian measurement noise, m (standard deviation)
    orientation_noise: float = 0.0  # rad
    position_only: bool = False
    seed: Optional[int] = None  # the instance's seed (null: the run's seed)

    def check(self, key: str = "problem") -> None:
        super().check(key)
        _require(self.n_poses >= 1, f"{key}.n_poses", "at least 1", self.n_poses)
        _require(self.n_validation >= 0, f"{key}.n_validation", "at least 0", self.n_validation)
        from zrp_ga.core import checks

        checks.seed(self.seed, f"{key}.seed")
        for name in ("joint_noise", "position_noise", "orientation_noise"):
            value = getattr(self, name)
            _require(math.isfinite(value) and value >= 0, f"{key}.{name}", "a number >= 0", value)


class Ranges(enum.Enum):
    data = "data"  # from the registered nominal arm's residuals (zrp_ga.problems.measured.gene_half_widths)
    fixed = "fixed"  # +-axis_error and +-body_error, times search_scale


class ValidationRegistration(enum.Enum):
    none = "none"  # the validation poses are in the calibration's frame
    rigid = "rigid"  # another instrument frame: predictions moved rigidly onto the measurements before scoring


@dataclasses.dataclass
class MeasuredConf(ProblemConf):
    _target_: str = "zrp_ga.problems.measured.build"
    format: Format = Format.zrp
    calibration_file: Optional[str] = None  # a path, or pkg:NAME for the data shipped with zrp_ga
    validation_file: Optional[str] = None
    validation_fraction: Optional[float] = None  # or split the calibration file at random
    validation_registration: ValidationRegistration = ValidationRegistration.none
    known_tools: Optional[Any] = None  # {NAME: [x, y, z]}: tool points of the validation file not in the calibration, offset from the hand's end point in its frame (length_unit)
    drop_bad_rows: bool = False  # drop rows with bad cells and repeated rows (listed in a warning)
    length_unit: str = "auto"  # zrp format: m, mm or auto (whichever puts the points within the arm's reach)
    angle_unit: str = "auto"  # rad, deg or auto (degrees when a joint value is beyond any turn)
    orientation_convention: Optional[str] = None  # rx, ry, rz: an Euler sequence (XYZ intrinsic, xyz extrinsic, ...) or rotvec
    use_orientation: Optional[bool] = None  # fit measured orientations (and the hand orientation); null: when the file has them
    use_weights: bool = False  # weight position errors by the rows' standard deviations
    ranges: Ranges = Ranges.data  # gene ranges: data (x search_scale) or fixed (axis_error, body_error x search_scale)

    def check(self, key: str = "problem") -> None:
        super().check(key)
        if not self.calibration_file:
            raise ConfigError(f"{key}.calibration_file: a measured problem needs a file")
        f = self.validation_fraction
        _require(f is None or 0.0 < f < 1.0, f"{key}.validation_fraction", "in (0, 1) or null", f)
        from zrp_ga.core import checks

        checks.validation_sources(self.validation_file, f, key)
        _require(self.length_unit in ("m", "mm", "auto"), f"{key}.length_unit", "m, mm or auto", self.length_unit)
        _require(self.angle_unit in ("rad", "deg", "auto"), f"{key}.angle_unit", "rad, deg or auto", self.angle_unit)
        from zrp_ga.core.checks import check_convention

        try:
            check_convention(self.orientation_convention, f"{key}.orientation_convention")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        _require(self.known_tools is None or hasattr(self.known_tools, "items"), f"{key}.known_tools",
                 "a mapping {NAME: [x, y, z]}", self.known_tools)  # fmt: skip
        for name, offset in (self.known_tools or {}).items():
            ok = not isinstance(offset, str) and hasattr(offset, "__len__") and len(offset) == 3
            ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in offset)
            _require(ok, f"{key}.known_tools.{name}", "a list of 3 finite numbers (x, y, z)", offset)


@dataclasses.dataclass
class PoseSelectionConf(MeasuredConf):
    """Pose selection (zrp_ga.problems.selection): choose ``k`` of the candidate poses to
    optimise an observability index. The candidates are simulated (``n_candidates`` joint
    configurations within the arm's limits, measured on a true arm drawn as in SimulatedConf)
    unless ``calibration_file`` is given: then they are its rows (MeasuredConf's keys), and the
    validation poses those of ``validation_file`` (or ``validation_fraction`` of the file). The
    ProblemConf keys describe the calibration (LM) that judges the chosen poses at the end."""

    _target_: str = "zrp_ga.problems.selection.build"
    k: int = 30  # poses to choose
    index: Index = Index.O1  # what the choice optimises; the cost is 1/O1 .. 1/O4, or A
    length_scale: Optional[float] = None  # m, scales angle parameters (null: the arm's summed body-vector lengths)
    rcond: float = 1e-4  # directions seen below rcond x the best-seen one (over all candidates) are left out
    ridge: float = 1e-6  # added to the information matrix, x the mean eigenvalue of one candidate's information
    reference: bool = True  # also calibrate on all candidates, for comparison (summary.json)
    cost: Cost = Cost.nonlinear
    n_candidates: int = 500  # simulated candidates
    n_validation: int = 200  # simulated validation poses, never candidates
    joint_noise: float = 0.001
    position_noise: float = 0.0
    orientation_noise: float = 0.0
    position_only: bool = False
    seed: Optional[int] = None  # the simulated instance's seed (null: the run's seed)

    def check(self, key: str = "problem") -> None:
        ProblemConf.check(self, key)  # MeasuredConf's check wants a file; here it is optional
        _require(self.k >= 1, f"{key}.k", "at least 1", self.k)
        _require(0.0 < self.rcond < 1.0, f"{key}.rcond", "in (0, 1)", self.rcond)
        _require(math.isfinite(self.ridge) and self.ridge >= 0.0, f"{key}.ridge", "a number >= 0", self.ridge)
        s = self.length_scale
        _require(s is None or (math.isfinite(s) and s > 0.0), f"{key}.length_scale", "a length > 0 (m) or null", s)
        f = self.validation_fraction
        _require(f is None or 0.0 < f < 1.0, f"{key}.validation_fraction", "in (0, 1) or null", f)
        from zrp_ga.core import checks

        checks.validation_sources(self.validation_file, f, key)
        if not self.calibration_file:
            _require(self.n_candidates > self.k, f"{key}.n_candidates", f"more than problem.k = {self.k}", self.n_candidates)
            _require(self.n_validation >= 1, f"{key}.n_validation", "at least 1", self.n_validation)
        for name in ("joint_noise", "position_noise", "orientation_noise"):
            value = getattr(self, name)
            _require(math.isfinite(value) and value >= 0, f"{key}.{name}", "a number >= 0", value)


@dataclasses.dataclass
class RobotConf:
    _target_: str = "zrp_ga.io.presets.load"
    name: Optional[str] = "puma560"  # a preset
    file: Optional[str] = None  # or a robot file: DH/MDH table, ZRP YAML or URDF (takes precedence)
    base_link: Optional[str] = None  # URDF: the chain's first link (null: the root)
    tip_link: Optional[str] = None  # URDF: its last link (null: the single leaf)


# --- the whole config ----------------------------------------------------------------------------
@dataclasses.dataclass
class Config:
    robot: RobotConf = dataclasses.field(default_factory=RobotConf)
    problem: Any = MISSING
    algorithm: Any = MISSING
    population: PopulationConf = dataclasses.field(default_factory=PopulationConf)
    selection: SelectionConf = dataclasses.field(default_factory=SelectionConf)
    crossover: VariationConf = dataclasses.field(default_factory=VariationConf)
    mutation: VariationConf = dataclasses.field(default_factory=VariationConf)
    inversion: VariationConf = dataclasses.field(default_factory=VariationConf)
    rotation: VariationConf = dataclasses.field(default_factory=VariationConf)
    refine: RefineConf = dataclasses.field(default_factory=RefineConf)
    seed: int = 0  # seeds numpy, `random` and the simulated problem (unless problem.seed is set)
    checkpoint_every: int = 10  # generations between checkpoints; 0: none
    resume: Optional[str] = None  # a run directory to continue from its checkpoint
    progress: bool = True  # a progress line on stderr: a run's, and a sweep's with zrp_ga's launcher
    objective: Objective = Objective.final_cost  # what the run returns to a sweeper (zrp_ga.run.summary.objective)


# --- zrp_ga's Hydra launcher (hydra/launcher=zrp_ga; hydra_plugins/zrp_ga_launcher) --------------
class Executor(enum.Enum):
    local = "local"  # this machine's cores: long-lived worker processes
    slurm = "slurm"  # a SLURM cluster through submitit, a batch of runs per cluster job
    ray = "ray"  # a Ray cluster, a batch of runs per task


@dataclasses.dataclass
class ZrpGaLauncherConf:
    """The settings of zrp_ga's launcher (``hydra.launcher.*``)."""

    _target_: str = "hydra_plugins.zrp_ga_launcher.launcher.ZrpGaLauncher"
    n_jobs: int = -1  # worker processes; -1: one per core this process may use
    batch_size: int = 1  # jobs handed to a worker at a time (it holds two batches, so it never waits)
    start_method: Optional[str] = None  # multiprocessing's: null is fork on Linux, spawn elsewhere
    cached_composition: bool = True  # job configs from a few of Hydra's compositions (equal to Hydra's)
    warm_up: Optional[str] = "zrp_ga.run.execute.warm_up"  # called with the sweep's config before the first job
    table_every_s: float = 1.0  # manifest.csv rewritten at most this often (and at the end)
    lockstep: bool = True  # GA jobs on one problem instance with one population shape evolved together (zrp_ga.run.execute.sweep_batch)
    # Beyond this machine (hydra_plugins/zrp_ga_launcher/_remote.py): the jobs in batches, a batch per cluster job.
    executor: Executor = Executor.local
    runs_per_job: int = 300  # jobs of the sweep run one after another in one cluster job (those of one batch_key together)
    cpus_per_task: int = 1  # cores of a cluster job (SLURM's cpus_per_task; Ray's num_cpus of a task)
    # SLURM, through submitit:
    cluster: Optional[str] = "slurm"  # submitit's AutoExecutor cluster: slurm; local or debug try it on this machine; null: SLURM where found
    partition: Optional[str] = None
    account: Optional[str] = None
    timeout_min: int = 60  # of a cluster job: runs_per_job runs
    mem_gb: float = 2.0
    array_parallelism: int = 64  # cluster jobs of the sweep running at a time
    submitit_folder: str = "${hydra.sweep.dir}/.submitit/%j"  # submitit's job files and logs
    # Ray:
    ray_address: Optional[str] = None  # a running cluster (auto: the one this node belongs to); null: a Ray started on this machine
    ray_num_cpus: Optional[int] = None  # cores of the Ray started on this machine (null: all)

    def check(self, key: str = "hydra.launcher") -> None:
        _require(self.runs_per_job >= 1, f"{key}.runs_per_job", "at least 1", self.runs_per_job)
        _require(self.cpus_per_task >= 1, f"{key}.cpus_per_task", "at least 1", self.cpus_per_task)


# Stored at the root of the config tree, not in a group, so that they are no options of their own
# (a group option extends one with ``- /ga_schema@_here_`` in its defaults list).
SCHEMAS = {"config_schema": Config, "ga_schema": GAConf, "lm_schema": LMConf, "cmaes_schema": CMAESConf,
           "simulated_schema": SimulatedConf, "measured_schema": MeasuredConf,
           "pose_selection_schema": PoseSelectionConf, "random_search_schema": RandomSearchConf,
           "exchange_schema": ExchangeConf}  # fmt: skip


def register() -> None:
    """Store the schemas in Hydra's ConfigStore (idempotent)."""
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    for name, node in SCHEMAS.items():
        cs.store(name=name, node=node)
    cs.store(group="hydra/launcher", name="zrp_ga", node=ZrpGaLauncherConf, provider="zrp_ga")


def _enums(cls: type, data: dict, key: str) -> dict:
    """``data`` with the strings of Enum-typed fields turned into the Enum (configs read back
    from a checkpoint or given from Python hold plain strings)."""
    hints = typing.get_type_hints(cls)
    out = dict(data)
    for name, value in data.items():
        kind = hints.get(name)
        if isinstance(kind, type) and issubclass(kind, enum.Enum) and not isinstance(value, kind):
            try:
                out[name] = kind(value)
            except ValueError:
                raise ConfigError(f"{key}.{name}: {value!r} is not one of {', '.join(m.value for m in kind)}") from None
    return out


def section(cls: type, node: Any, key: str) -> Any:
    """``node`` (a config node, a dict or already a ``cls``) as a checked ``cls`` instance."""
    if isinstance(node, cls):
        obj = node
    else:
        from omegaconf import OmegaConf

        data = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else dict(node)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(f"{key}.{unknown[0]}: not a setting (known: {', '.join(sorted(names))})")
        obj = cls(**_enums(cls, data, key))
    if hasattr(obj, "check"):
        obj.check(key)
    return obj


def instantiate(node: DictConfig, key: str, root: DictConfig | None = None, **kwargs: Any) -> Any:
    """``hydra.utils.instantiate(node)(**kwargs)`` with the user's mistakes (ValueError from the
    target) raised as themselves, so that they reach the console as one line. ``kwargs`` are
    passed to the partial rather than to ``instantiate``, which would merge them into the
    config (a robot, being a dataclass, would become a config node). ``root``: the config
    ``node`` belongs to, where its interpolations (``${population}``) point."""
    from hydra.errors import InstantiationException
    from hydra.utils import instantiate as hydra_instantiate

    direct = _direct(node, root)
    if direct is not None:
        target, settings = direct
        return target(**{**settings, **kwargs})  # as functools.partial: the call's keywords win
    trusted = {"_execution_whitelist_": TRUSTED_TARGETS} if hydra_14() else {}
    try:
        return hydra_instantiate(node, _partial_=True, **trusted)(**kwargs)
    except InstantiationException as exc:
        cause = exc.__cause__
        if isinstance(cause, (ValueError, OSError)):
            raise cause from None
        raise ConfigError(f"{key}: {str(exc).splitlines()[0]}") from None


_SPECIAL = ("_target_", "_recursive_", "_convert_", "_partial_", "_args_")


def _direct(node: Any, root: DictConfig | None) -> tuple[Any, dict] | None:
    """The target and settings of a node that :func:`instantiate` calls itself, as Hydra would
    (a sweep builds an optimiser per run: Hydra's deep copy and resolution of the config cost
    more than the rest of the run's set-up): a zrp_ga target given its settings' values, where
    Hydra would hand it the same values (no nested objects to build: ``_recursive_: false``, or
    plain values only). A setting that names another node of ``root`` (``${population}``) is
    that node, as OmegaConf resolves it. None: Hydra builds it."""
    from omegaconf import OmegaConf

    if not isinstance(node, DictConfig):
        return None
    raw = OmegaConf.to_container(node, resolve=False)
    name = raw.get("_target_")
    if not isinstance(name, str) or not name.startswith("zrp_ga.") or any(k in raw for k in _SPECIAL[2:]):
        return None
    settings = {}
    for k, v in raw.items():
        if k in _SPECIAL:
            continue
        path = _reference(v, root)
        settings[str(k)] = node[k] if path is None else OmegaConf.select(root, path)
    if raw.get("_recursive_", True) is not False and any(isinstance(v, DictConfig | ListConfig) for v in settings.values()):
        return None
    target = _target(name)
    return None if target is None else (target, settings)


_NODE = re.compile(r"\$\{([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\}")  # ${a.b}: a reference to a node, from the root


def _reference(value: Any, root: DictConfig | None) -> str | None:
    """The path of the config node (a dict or list in ``root``) that ``value`` names as the whole
    of its text (``${population}``); None for anything else."""
    from omegaconf import OmegaConf

    if root is None or not isinstance(value, str) or not (m := _NODE.fullmatch(value)):
        return None
    target = OmegaConf.select(root, m[1], default=None)
    return m[1] if isinstance(target, DictConfig | ListConfig) else None


def resolved(cfg: DictConfig) -> dict:
    """``OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)``, the config as its files
    record it, with the interpolations that name another node of ``cfg`` (``algorithm.population:
    ${population}``) copied from that node rather than parsed one by one (a sweep records the
    config of every run); any other interpolation: OmegaConf resolves the whole."""
    from omegaconf import OmegaConf

    raw = OmegaConf.to_container(cfg, resolve=False, enum_to_str=True)

    def filled(o: Any, seen: tuple[str, ...]) -> Any:
        if isinstance(o, dict):
            return {k: filled(v, seen) for k, v in o.items()}
        if isinstance(o, list):
            return [filled(v, seen) for v in o]
        if isinstance(o, str) and "${" in o:
            path = _NODE.fullmatch(o)
            target = _at(raw, path[1]) if path and path[1] not in seen else None
            if not isinstance(target, (dict, list)):
                raise _Unresolved
            return filled(target, (*seen, path[1]))
        return o

    try:
        return filled(raw, ())
    except _Unresolved:
        return OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)


class _Unresolved(Exception):
    """An interpolation :func:`resolved` leaves to OmegaConf."""


def _at(tree: Any, path: str) -> Any:
    """The value at dotted ``path`` in nested dicts (None if there is none)."""
    for part in path.split("."):
        if not isinstance(tree, dict) or part not in tree:
            return None
        tree = tree[part]
    return tree


@functools.cache
def _target(name: str) -> Any:
    """The object ``module.attr`` names (None if it cannot be imported: Hydra then says why)."""
    import importlib

    module, _, attr = name.rpartition(".")
    try:
        return getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError):
        return None


# --- what differs between the Hydra releases zrp_ga supports (hydra-core 1.3.2 - 1.4) -------------
# The targets zrp_ga's configs name; hydra-core 1.4 asks for them to be declared (its "execution
# whitelist") and warns about others, which 1.5 will refuse.
TRUSTED_TARGETS = ["zrp_ga.*", "deap.*", "hydra_plugins.*"]


@functools.cache
def hydra_14() -> bool:
    """Whether the installed hydra-core is 1.4 or later."""
    from importlib import metadata

    major, minor = (int("".join(c for c in part if c.isdigit()) or 0) for part in metadata.version("hydra-core").split(".")[:2])
    return (major, minor) >= (1, 4)


def hydra_options() -> dict[str, Any]:
    """Keyword arguments of ``hydra.main`` and ``initialize_config_module``: Hydra's defaults of
    the installed release (1.3 and 1.4 give zrp_ga the same config; the output directory never
    is the working directory, conf/config.yaml sets ``hydra.job.chdir=false``). 1.3 wants
    ``version_base`` (else the defaults of 1.1), 1.4 warns about it."""
    return {} if hydra_14() else {"version_base": None}


def load(overrides: list[str] | tuple[str, ...] = (), return_hydra_config: bool = False) -> DictConfig:
    """The composed config for ``overrides``, as ``zrp-ga`` would see it (for tests, notebooks and
    experiment scripts)."""
    from hydra import compose, initialize_config_module

    register()
    with initialize_config_module("zrp_ga.conf", **hydra_options()):
        return compose("config", overrides=list(overrides), return_hydra_config=return_hydra_config)
