"""Structured configs: the schema every composed config is checked against.

The dataclasses are registered in Hydra's ConfigStore as ``config_schema``, which
``conf/config.yaml`` names first in its defaults list. A value of the wrong type or a key that
is not in the schema (``problem.n_pose=30``) then fails at composition, before anything runs.
Operator parameters (``crossover.op.eta``) are free-form here and checked against the
operator's signature when the toolbox is built.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from hydra import compose, initialize_config_module
from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig


@dataclasses.dataclass
class RobotConf:
    name: str = "puma560"
    file: str | None = None


@dataclasses.dataclass
class ProblemConf:
    kind: str = "simulated"  # simulated | measured
    robot: str | None = None  # measured data: the preset arm that was measured (over robot=...)
    # measured data (kind: measured)
    format: str = "zrp"  # zrp (zrp_ga/measurements.py) | ur10_ipa
    calibration_file: str | None = None  # a path, or pkg:NAME for the data shipped with zrp_ga
    validation_file: str | None = None
    validation_fraction: float | None = None  # or split the calibration file at random
    drop_bad_rows: bool = False
    length_unit: str = "m"  # zrp format
    angle_unit: str = "rad"
    use_orientation: bool = False  # fit measured orientations too (and the hand orientation)
    use_weights: bool = False  # weight position errors by the rows' standard deviations
    n_poses: int = 1
    n_validation: int = 100
    axis_error: float = 0.01
    body_error: float = 0.0005
    joint_noise: float = 0.001
    position_noise: float = 0.0
    orientation_noise: float = 0.0
    position_only: bool = False
    identify_base: bool = False
    identify_hand: bool = False
    search_scale: float = 1.0
    cost: str = "linear"
    norm: str = "spectral"
    orientation_weight: float = 1.0
    rcond: float = 1e-9
    seed: int | None = None


@dataclasses.dataclass
class AlgorithmConf:
    name: str = "ga"
    strategy: str = "mu_plus_lambda"
    elite: int = 1
    repair: str = "clip"
    target_cost: float | None = None
    stagnation: int | None = None
    max_evals: int | None = None  # LM's own cap on residual evaluations
    sigma0: float = 0.3  # CMA-ES


@dataclasses.dataclass
class PopulationConf:
    mu: int = 20
    lambda_: int = 20
    generations: int | None = 11
    max_evals: int | None = None


@dataclasses.dataclass
class OperatorConf:
    name: str = MISSING
    prob: float = 0.0
    op: Any = None


@dataclasses.dataclass
class SelectionConf:
    name: str = MISSING
    op: Any = MISSING


@dataclasses.dataclass
class RefineConf:
    name: str = "pinv"
    share: float = 0.1


@dataclasses.dataclass
class Config:
    robot: RobotConf = dataclasses.field(default_factory=RobotConf)
    problem: ProblemConf = dataclasses.field(default_factory=ProblemConf)
    algorithm: AlgorithmConf = dataclasses.field(default_factory=AlgorithmConf)
    population: PopulationConf = dataclasses.field(default_factory=PopulationConf)
    selection: SelectionConf = dataclasses.field(default_factory=SelectionConf)
    crossover: OperatorConf = dataclasses.field(default_factory=OperatorConf)
    mutation: OperatorConf = dataclasses.field(default_factory=OperatorConf)
    inversion: OperatorConf = dataclasses.field(default_factory=OperatorConf)
    rotation: OperatorConf = dataclasses.field(default_factory=OperatorConf)
    refine: RefineConf = dataclasses.field(default_factory=RefineConf)
    seed: int = 0
    checkpoint_every: int = 10  # generations between checkpoints; 0: none
    resume: str | None = None  # a run directory to continue
    progress: bool = True  # a line per generation on the terminal (single runs)


def register() -> None:
    """Store the schema in Hydra's ConfigStore (idempotent)."""
    ConfigStore.instance().store(name="config_schema", node=Config)


def load(overrides: list[str] | tuple[str, ...] = (), return_hydra_config: bool = False) -> DictConfig:
    """The composed config for ``overrides``, as ``zrp-ga`` would see it (for tests, notebooks and
    experiment scripts)."""
    register()
    with initialize_config_module("zrp_ga.conf", version_base="1.3"):
        return compose("config", overrides=list(overrides), return_hydra_config=return_hydra_config)
