"""The typed config: every key, its type and its default, in one place, without Hydra.

A run's config is a :class:`Config`, a tree of dataclasses: a section per group (``robot``,
``population``, ``selection``, ...), and for the ``problem`` and ``algorithm`` groups the schema
of the kind its ``_target_`` names (:data:`PROBLEMS`, :data:`ALGORITHMS`), or a plain dict for
a kind of one's own that has none. String choices are Enums. Values that are well typed but
meaningless (``population.mu=0``) are refused by each section's ``check``, which names the key
(called where the section is used).

- :func:`to_dict`: a config as plain values, Enums as their strings: what the run's files
  record (``summary.json``, the checkpoint);
- :func:`from_dict`: a config from plain values (a checkpoint's, or the command line's as Hydra
  composed them, :mod:`zrp_ga.config`), every key and type checked; an unknown key, a value of
  the wrong type or a bad Enum value is a :class:`ConfigError` naming the key.

The command line composes its config with Hydra, whose ConfigStore holds these dataclasses
(:mod:`zrp_ga.config`: ``conf/config.yaml`` starts from ``config_schema``, each option of the
problem and algorithm groups from its kind's schema), so that a bad key stops the composition;
this module itself imports neither Hydra nor OmegaConf, and nothing heavy. A key without a value
holds :data:`MISSING` (``???``, OmegaConf's mark for it).
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import math
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, Optional, TypeVar

MISSING: Any = "???"  # a key without a value (OmegaConf's literal mark for one): a target is called without it


class ConfigError(ValueError):
    """A setting that cannot run; the message names the key."""


class Cost(enum.Enum):
    linear = "linear"  # the paper: |[dr; dp; 0] - J x| with J at the nominal parameters
    nonlinear = "nonlinear"  # the forward-kinematics residual


class Objective(enum.Enum):
    final_cost = "final_cost"  # what a run returns to a sweeper (Optuna, nevergrad): its final cost
    over_floor = "over_floor"  # the final cost over the instance's floor (LM's cost, summary.json "floor")


class Outputs(enum.Enum):
    auto = "auto"  # study in a sweep (-m), full in a single run
    study = "study"  # what a study reads: convergence.csv, summary.json, best_params.csv, initial_population.csv, status.json
    full = "full"  # and the calibrated arm's files, the problem kind's own, the final checkpoint


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


def _shares(section: type) -> dict[str, type]:
    """The metadata of a field holding a root section (``${population}`` in the composed config,
    resolved by OmegaConf) of class ``section``: :func:`from_dict` puts a copy of it there."""
    return {"section": section}


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
    population: Any = dataclasses.field(default="${population}", metadata=_shares(PopulationConf))
    selection: Any = dataclasses.field(default="${selection}", metadata=_shares(SelectionConf))
    crossover: Any = dataclasses.field(default="${crossover}", metadata=_shares(VariationConf))
    mutation: Any = dataclasses.field(default="${mutation}", metadata=_shares(VariationConf))
    inversion: Any = dataclasses.field(default="${inversion}", metadata=_shares(VariationConf))
    rotation: Any = dataclasses.field(default="${rotation}", metadata=_shares(VariationConf))
    refine: Any = dataclasses.field(default="${refine}", metadata=_shares(RefineConf))
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
    population: Any = dataclasses.field(default="${population}", metadata=_shares(PopulationConf))  # lambda_: CMA-ES's population size; generations, max_evals: its budget
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
    terms: Optional[Any] = None  # non-geometric terms fitted with the geometry (zrp_ga.model.terms): {compliance: [2, 3], harmonics: {order: 1, joints: [1]}, payload: {mass: 5, com: [0, 0, 0.1]}}

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
    model: Optional[Any] = "geometric"  # geometric, auto (chosen by cross-validation) or a list of candidates (zrp_ga.problems.choice)

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
    outputs: Outputs = Outputs.auto  # a run's files: study (a sweep's default) or full (a single run's; zrp_ga.run.assembly)




# --- the kinds of problem and optimiser with a schema, by the _target_ they name ------------------------
PROBLEMS = (SimulatedConf, MeasuredConf, PoseSelectionConf)
ALGORITHMS = (GAConf, LMConf, CMAESConf, RandomSearchConf, ExchangeConf)
_BY_TARGET: dict[str, type] = {kind._target_: kind for kind in PROBLEMS + ALGORITHMS}
KINDS = ("problem", "algorithm")  # the sections whose schema their _target_ chooses


def schema_of(node: Any) -> type | None:
    """The schema of a ``problem`` or ``algorithm`` node by the ``_target_`` it names; None for a
    kind without one (its settings stay a plain dict)."""
    target = setting(node, "_target_")
    return _BY_TARGET.get(target) if isinstance(target, str) else None


def setting(node: Any, key: str, default: Any = None) -> Any:
    """The setting ``key`` of a section, a dataclass or a plain dict (a kind without a schema)."""
    if isinstance(node, Mapping):
        return node.get(key, default)
    return getattr(node, key, default)


# --- plain values and back -----------------------------------------------------------------------
_ATOMS = frozenset({str, int, float, bool, type(None)})


def to_dict(cfg: Any) -> Any:
    """``cfg`` (a config, a section or any value in one) as plain values: dicts in the fields'
    order, lists, Enums as their names (as ``OmegaConf.to_container(enum_to_str=True)`` gives
    them, equal to their values here). What the run's files record."""
    kind = cfg.__class__
    if kind in _ATOMS:
        return cfg
    if kind is dict or (kind is not list and kind is not tuple and isinstance(cfg, Mapping)):
        return {(k if k.__class__ is str or not isinstance(k, enum.Enum) else k.name): to_dict(v) for k, v in cfg.items()}
    if kind is list or kind is tuple:
        return [to_dict(v) for v in cfg]
    if isinstance(cfg, enum.Enum):
        return cfg.name
    if dataclasses.is_dataclass(cfg) and not isinstance(cfg, type):
        return {name: to_dict(getattr(cfg, name)) for name in _converters(kind)}
    return cfg


def from_dict(data: Mapping[str, Any]) -> Config:
    """The typed :class:`Config` of plain values (what :func:`to_dict` gives, a checkpoint holds or
    Hydra composed): every section in its dataclass, ``problem`` and ``algorithm`` in the schema
    their ``_target_`` names (a plain dict for a kind without one), the sections an optimiser
    shares with the root (``algorithm.population``: ``${population}``) copied from it when not
    given. A key missing takes its default; an unknown key, a value of the wrong type or a bad
    Enum value is a :class:`ConfigError` naming the key."""
    cfg = _typed(Config, data, "")
    for name in KINDS:
        node = getattr(cfg, name)
        if not isinstance(node, Mapping) or not isinstance(node.get("_target_"), str):
            raise ConfigError(f"{name}: must be the settings of a {name} kind, naming it by _target_; got {node!r}")
        kind = schema_of(node)
        setattr(cfg, name, _plain(node) if kind is None else _typed(kind, node, name))
    _share(cfg)
    return cfg


S = TypeVar("S")


def section(cls: type[S], node: Any, key: str) -> S:
    """``node`` (the settings of one section, as a dict or already a ``cls``) as a checked ``cls``
    instance (:func:`from_dict`'s checks, then the section's own ``check``)."""
    obj = _typed(cls, node, key)
    if hasattr(obj, "check"):
        obj.check(key)
    return obj


def _share(cfg: Config) -> None:
    """Fill the fields of the algorithm that hold a root section (:func:`_shares`) and were not
    given with a copy of it (as OmegaConf resolves ``${population}``)."""
    algorithm = cfg.algorithm
    if not dataclasses.is_dataclass(algorithm):
        return
    for f in dataclasses.fields(algorithm):
        value = getattr(algorithm, f.name)
        if "section" in f.metadata and isinstance(value, str) and value != MISSING:
            name = value.removeprefix("${").removesuffix("}")
            if value != f"${{{name}}}" or name not in _converters(Config):
                raise ConfigError(f"algorithm.{f.name}: must be the settings of {f.metadata['section'].__name__} "
                                  f"or a reference to a section (${{{f.name}}}), got {value!r}")  # fmt: skip
            setattr(algorithm, f.name, copy.deepcopy(getattr(cfg, name)))


def _typed(cls: type, data: Any, key: str) -> Any:
    """``data`` (a mapping) as a ``cls`` instance, each value checked against its field's type."""
    if isinstance(data, cls):
        return data
    if data.__class__ is not dict and not isinstance(data, Mapping):
        raise ConfigError(f"{key or 'the config'}: must be a mapping of settings, got {data!r}")
    converters = _converters(cls)
    values = {}
    for name, value in data.items():
        convert = converters.get(name)
        if convert is None:
            raise ConfigError(f"{_join(key, name)}: not a setting (known: {', '.join(sorted(converters))})")
        values[name] = convert(value, _join(key, name))
    return cls(**values)


Convert = Callable[[Any, str], Any]  # a value and its key -> the value as its field holds it (ConfigError if it cannot)
_CONVERTERS: dict[type, dict[str, Convert]] = {}


def _converters(cls: type) -> dict[str, Convert]:
    """Per field of the dataclass ``cls``, in order, the conversion of its values (made once per class)."""
    if cls not in _CONVERTERS:
        hints = typing.get_type_hints(cls)
        _CONVERTERS[cls] = {f.name: _shared_section(f.metadata["section"]) if "section" in f.metadata else _converter(hints[f.name])
                            for f in dataclasses.fields(cls)}  # fmt: skip
    return _CONVERTERS[cls]


def _shared_section(section: type) -> Convert:
    """A field holding a root section: a reference to it (``${population}``, which :func:`_share`
    fills) or its settings."""
    return lambda v, key: v if isinstance(v, str) else _typed(section, v, key)


def _converter(kind: Any) -> Convert:
    """The conversion of values of the type ``kind``, as OmegaConf converts them (an int for a
    float, a string for an Enum); a missing value (``???``) stays."""
    convert = _conversion(kind)
    return lambda v, key: v if v.__class__ is str and v == MISSING else convert(v, key)


def _conversion(kind: Any) -> Convert:
    if kind is Any:
        return lambda v, key: _plain(v)
    if typing.get_origin(kind) in (typing.Union, types.UnionType):
        nullable = type(None) in typing.get_args(kind)
        (inner,) = [_converter(k) for k in typing.get_args(kind) if k is not type(None)]
        return lambda v, key: None if v is None and nullable else inner(v, key)
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        return lambda v, key: _typed(kind, v, key)
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        return lambda v, key: _enum(kind, v, key)
    if typing.get_origin(kind) is list:
        item = _converter(typing.get_args(kind)[0])
        return lambda v, key: [item(x, f"{key}[{i}]") for i, x in enumerate(_listed(v, key))]
    ok, what = _SCALARS[kind]
    as_kind = float if kind is float else (lambda v: v)
    return lambda v, key: as_kind(v) if ok(v) else _refuse(key, what, v)


_SCALARS: dict[Any, tuple[Callable[[Any], bool], str]] = {
    bool: (lambda v: v.__class__ is bool, "true or false"),
    int: (lambda v: isinstance(v, int) and v.__class__ is not bool, "a whole number"),
    float: (lambda v: isinstance(v, (int, float)) and v.__class__ is not bool, "a number"),
    str: (lambda v: isinstance(v, str), "a string"),
}


def _refuse(key: str, what: str, value: Any) -> Any:
    raise ConfigError(f"{key}: must be {what}, got {value!r}")


def _listed(value: Any, key: str) -> list | tuple:
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{key}: must be a list, got {value!r}")
    return value


def _enum(kind: type[enum.Enum], value: Any, key: str) -> enum.Enum:
    if isinstance(value, kind):
        return value
    for member in kind:
        if value in (member.value, member.name):
            return member
    raise ConfigError(f"{key}: {value!r} is not one of {', '.join(m.value for m in kind)}")


def _plain(value: Any) -> Any:
    """A copy of nested dicts and lists (the settings of a kind without a schema)."""
    kind = value.__class__
    if kind in _ATOMS:
        return value
    if kind is dict or (kind is not list and kind is not tuple and isinstance(value, Mapping)):
        return {k: _plain(v) for k, v in value.items()}
    if kind is list or kind is tuple:
        return [_plain(v) for v in value]
    return value


def _join(key: str, name: str) -> str:
    return f"{key}.{name}" if key else str(name)
