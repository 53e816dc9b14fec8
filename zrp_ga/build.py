"""Objects from the composed config: robot, problem, GA settings and toolbox.

Every check names the config key it refuses (``crossover.prob``), so that a bad setting stops
the run with one line before anything is computed.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.resources
import inspect
import logging
from pathlib import Path

import numpy as np
from hydra.utils import get_method
from omegaconf import DictConfig, OmegaConf

from zrp_ga import ga, measurements, robots
from zrp_ga.measurements import MeasuredData
from zrp_ga.problem import CalibrationProblem, Layout, Simulation, simulate
from zrp_ga.registration import Registration, register
from zrp_ga.robot import ZRPRobot

log = logging.getLogger(__name__)

FAMILIES = ("crossover", "mutation", "inversion", "rotation")  # operator groups


class ConfigError(ValueError):
    """A setting that cannot run; the message names the key."""


def robot(cfg: DictConfig, measured: str | None = None) -> ZRPRobot:
    """The preset ``cfg.name``, or the ZRP YAML file ``cfg.file``; a measured problem's own arm
    (``problem.robot``) first."""
    if measured:
        return robots.get(measured)
    if cfg.get("file"):
        return ZRPRobot.from_yaml(Path(cfg.file).expanduser())
    return robots.get(cfg.name)


@dataclasses.dataclass(frozen=True)
class Measured:
    """What a problem on measured data was built from."""

    registration: Registration
    calibration: MeasuredData
    validation: MeasuredData | None


def data_path(name: str) -> Path:
    """A measurement file: ``pkg:REL`` is a file shipped in zrp_ga/data, anything else a path."""
    if name.startswith("pkg:"):
        return Path(str(importlib.resources.files("zrp_ga.data").joinpath(name[4:])))
    return Path(name).expanduser()


def measured_problem(cfg: DictConfig, arm: ZRPRobot, seed: int) -> tuple[CalibrationProblem, Measured]:
    """Measured poses in an instrument's frame: read, split, registered, then a calibration problem
    in that frame with the base point identified (and the hand orientation with orientation data)."""
    formats = {"ur10_ipa": lambda n: measurements.UR10_IPA,
               "zrp": lambda n: measurements.zrp_format(n, cfg.length_unit, cfg.angle_unit)}  # fmt: skip
    if cfg.format not in formats:
        raise ConfigError(f"problem.format: unknown format {cfg.format!r}; known: {', '.join(formats)}")
    if not cfg.calibration_file:
        raise ConfigError("problem.calibration_file: a measured problem needs a file")
    fmt = formats[cfg.format](arm.n)
    calib = measurements.read(data_path(cfg.calibration_file), fmt, arm.n, cfg.drop_bad_rows)
    if cfg.validation_file:
        val = measurements.read(data_path(cfg.validation_file), fmt, arm.n, cfg.drop_bad_rows)
    elif cfg.validation_fraction:
        calib, val = measurements.split(calib, cfg.validation_fraction, np.random.default_rng([seed, 2]))
    else:
        val = None
    if cfg.use_orientation and calib.R is None:
        raise ConfigError(f"problem.use_orientation: {calib.source} has no orientation columns")
    if cfg.use_weights and calib.std is None:
        raise ConfigError(f"problem.use_weights: {calib.source} has no standard-deviation columns")
    reg = register(arm, calib.q, calib.p, rotations=calib.R if cfg.use_orientation else None)
    log.info("registered %s to %s: %.3f mm RMS, tool offset %s mm", arm.name, calib.source, reg.rms * 1e3,
             np.round(reg.tool * 1e3, 2))  # fmt: skip
    nominal = reg.apply(arm)
    layout = Layout(arm.n, base=True, hand=bool(cfg.use_orientation))
    half = _half_ranges(cfg, layout)
    try:
        prob = CalibrationProblem(
            nominal=nominal, calibration=calib.measurements(cfg.use_orientation, cfg.use_weights), layout=layout, lower=-half,
            upper=half, validation=val.measurements() if val is not None else None, cost=cfg.cost, norm=cfg.norm,
            orientation_weight=cfg.orientation_weight, rcond=cfg.rcond,
        )  # fmt: skip
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    return prob, Measured(reg, calib, val)


def _half_ranges(cfg: DictConfig, layout: Layout) -> np.ndarray:
    half = np.empty(layout.size)
    for name, block in layout.blocks.items():
        half[block] = cfg.axis_error if name in ("u0", "hand") else cfg.body_error
    half *= cfg.search_scale
    if not np.all(half > 0):
        raise ConfigError("problem.search_scale, axis_error, body_error: every gene range must be wider than zero")
    return half


def problem(cfg: DictConfig, arm: ZRPRobot, seed: int) -> tuple[CalibrationProblem, Simulation | Measured]:
    """The calibration problem: simulated (the paper's case study and its multi-pose forms) or
    measured (``problem.kind: measured``)."""
    if cfg.kind == "measured":
        return measured_problem(cfg, arm, seed)
    if cfg.kind != "simulated":
        raise ConfigError(f"problem.kind: unknown kind {cfg.kind!r}; known: simulated, measured")
    for key in ("n_poses", "n_validation"):
        if cfg[key] < (1 if key == "n_poses" else 0):
            raise ConfigError(f"problem.{key}: must be at least {1 if key == 'n_poses' else 0}, got {cfg[key]}")
    for key in ("axis_error", "body_error", "joint_noise", "position_noise", "orientation_noise", "search_scale"):
        if not cfg[key] >= 0:
            raise ConfigError(f"problem.{key}: must be >= 0, got {cfg[key]}")
    layout = Layout(arm.n, base=cfg.identify_base, hand=cfg.identify_hand)
    # A stream of its own: with the optimiser's, the first genome would be the true errors.
    rng = np.random.default_rng([seed if cfg.seed is None else cfg.seed, 1])
    sim = simulate(
        arm, layout, rng, n_poses=cfg.n_poses, n_validation=cfg.n_validation, axis_error=cfg.axis_error,
        body_error=cfg.body_error, joint_noise=cfg.joint_noise, position_noise=cfg.position_noise,
        orientation_noise=cfg.orientation_noise, position_only=cfg.position_only,
    )  # fmt: skip
    half = _half_ranges(cfg, layout)
    try:
        prob = CalibrationProblem(
            nominal=arm, calibration=sim.calibration, validation=sim.validation if cfg.n_validation else None,
            layout=layout, lower=-half, upper=half, cost=cfg.cost, norm=cfg.norm,
            orientation_weight=cfg.orientation_weight, true_de=sim.true_de, rcond=cfg.rcond,
        )  # fmt: skip
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    return prob, sim


# GASettings' field names, as the config calls them
SETTING_KEYS = {"p_cx": "crossover.prob", "p_mut": "mutation.prob", "p_inv": "inversion.prob",
                "p_rot": "rotation.prob", "refine_share": "refine.share", "generations": "population.generations",
                "max_evals": "population.max_evals", "stagnation": "algorithm.stagnation"}  # fmt: skip


def settings(cfg: DictConfig) -> ga.GASettings:
    """GA sizes, probabilities and stop criteria, checked by GASettings; errors name the config key."""
    pop, alg = cfg.population, cfg.algorithm
    try:
        return ga.GASettings(
            mu=pop.mu, lambda_=pop.lambda_, generations=pop.generations, max_evals=pop.max_evals,
            target_cost=alg.get("target_cost"), stagnation=alg.get("stagnation"),
            strategy=alg.get("strategy", "mu_plus_lambda"), elite=alg.get("elite", 1),
            p_cx=cfg.crossover.prob, p_mut=cfg.mutation.prob, p_inv=cfg.inversion.prob, p_rot=cfg.rotation.prob,
            refine_share=cfg.refine.share,
        )  # fmt: skip
    except ValueError as exc:
        field, _, rest = str(exc).partition(":")
        raise ConfigError(f"{SETTING_KEYS.get(field, field)}:{rest}") from None


def operator(node: DictConfig) -> functools.partial:
    """The ``_target_`` function of an operator node with its parameters bound.

    Same meaning as ``hydra.utils.instantiate(node)`` with ``_partial_: true``, but a plain
    ``functools.partial``: hydra-core 1.3.8 wraps instantiated partials in a target-policy
    check that runs on every call (about 0.4 ms, more than a generation's variation).
    """
    params = OmegaConf.to_container(node, resolve=True)
    target = params.pop("_target_")
    params.pop("_partial_", None)
    fn = get_method(target)
    takes = [k for k in inspect.signature(fn).parameters if k not in ("ind", "ind1", "ind2", "costs", "k", "rng")]
    unknown = sorted(set(params) - set(takes))
    if unknown:
        raise ValueError(f"unknown parameter {unknown[0]!r} for {target} (takes: {', '.join(takes) or 'none'})")
    return functools.partial(fn, **params)


def toolbox(cfg: DictConfig, prob: CalibrationProblem, rng: np.random.Generator):
    """The DEAP toolbox of the configured operators ("none" registers nothing)."""
    ops = {}
    for family in FAMILIES + ("selection",):
        node = cfg[family].get("op")
        try:
            ops[family] = operator(node) if node is not None else None
        except Exception as exc:  # hydra wraps import errors; keep the first line
            raise ConfigError(f"{family}.op: cannot build it ({str(exc).splitlines()[0]})") from None
    if ops["selection"] is None:
        raise ConfigError("selection.op: a selection operator is required")
    return ga.build_toolbox(
        prob, rng, ops["crossover"], ops["mutation"], ops["inversion"], ops["rotation"], ops["selection"],
        repair=cfg.algorithm.get("repair", "clip"),
    )
