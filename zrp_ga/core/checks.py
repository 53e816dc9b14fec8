"""Checks of settings that are well typed but cannot run, or contradict each other; each
raises ValueError naming the key(s), before any work (the console script prints it as one
line). This module imports nothing of zrp_ga, so that the config schema can call it.

The config schema's sections call :func:`validation_sources`; the run layer calls
:func:`run_settings` on the whole config before it builds anything; the CMA-ES optimiser calls
:func:`cmaes_population`.
"""

from __future__ import annotations

from typing import Any

CMAES_MIN_POPULATION = 2  # cma's recombination weights need at least two offspring ("number of weights must be >=2")


def seed(value: Any, key: str) -> None:
    """A seed is a whole number >= 0 (numpy's seed sequences take no negative entropy)."""
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
        raise ValueError(f"{key}: must be a whole number >= 0, got {value}")


def validation_sources(validation_file: Any, validation_fraction: Any, key: str = "problem") -> None:
    """A validation file and a validation fraction contradict each other: the fraction would be
    ignored."""
    if validation_file and validation_fraction is not None:
        raise ValueError(f"{key}.validation_file and {key}.validation_fraction: give one of them (a validation file, or "
                          f"a fraction of the calibration file to hold out), not both (set the other to null); got {validation_file} "
                         f"and {validation_fraction}")  # fmt: skip


def cmaes_population(lambda_: int, key: str = "population.lambda_") -> None:
    """CMA-ES's population (``population.lambda_``) must be large enough for its weights."""
    if lambda_ < CMAES_MIN_POPULATION:
        raise ValueError(f"{key}: CMA-ES needs a population of at least {CMAES_MIN_POPULATION} (its recombination "
                          f"weights), got {lambda_}")  # fmt: skip


def run_settings(cfg: Any) -> None:
    """What the whole config (a :class:`zrp_ga.core.schema.Config`) must satisfy before anything is
    built: ``seed`` (and ``problem.seed``) >= 0; an optimiser's own needs of the shared settings
    (CMA-ES's population)."""
    seed(cfg.seed, "seed")
    seed(_setting(cfg.problem, "seed"), "problem.seed")
    target = str(_setting(cfg.algorithm, "_target_") or "")
    if target.endswith("cmaes.CMAES") and cfg.population is not None:
        cmaes_population(int(cfg.population.lambda_))


def _setting(node: Any, key: str) -> Any:
    """A setting of a section: a dataclass, or a plain dict (a kind without a schema)."""
    return node.get(key) if isinstance(node, dict) else getattr(node, key, None)


ROTVEC = "rotvec"  # the rotation vector (axis x angle), as Universal Robots' controllers report rx, ry, rz


def check_convention(convention: str | None, what: str) -> None:
    """ValueError naming ``what`` unless ``convention`` is None, ``rotvec`` or an Euler sequence."""
    if convention is None or convention == ROTVEC:
        return
    c = str(convention)
    euler = len(c) == 3 and (set(c) <= set("xyz") or set(c) <= set("XYZ")) and c[0] != c[1] and c[1] != c[2]
    if not euler:
        raise ValueError(f"{what}: {convention!r} is neither an Euler sequence (e.g. XYZ intrinsic, xyz extrinsic, "
                         "ZYX) nor rotvec")  # fmt: skip
