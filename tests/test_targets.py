"""zrp_ga.core.targets builds what ``hydra.utils.instantiate`` builds: on every ``_target_`` spec
of every option of every config group (composed by Hydra with ``config.compose``; ours from the
typed config), the same callable with the same arguments, and the same objects; on small specs,
Hydra's meaning of ``_args_``, ``_partial_``, ``_recursive_`` and missing values."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import hydra.utils
import numpy as np
import pytest
from omegaconf import OmegaConf

from zrp_ga import config, robots
from zrp_ga.core import targets

CONF = Path(config.__file__).resolve().parents[1] / "conf"
GROUPS = ["robot", "problem", "algorithm", "population", "selection", "crossover", "mutation", "inversion", "rotation",
          "refine", "instance", "experiment"]  # fmt: skip
NEEDS = {"robot=file": [f"robot.file={robots.path('puma560')}"],
         "problem=measured": ["robot=ur10", "problem.format=ur10_ipa", "problem.calibration_file=pkg:ur10_ipa/series_b_joint_configurations.csv"],
         **{f"experiment={p.stem}": ["hydra.mode=RUN"] for p in (CONF / "experiment").glob("*.yaml")}}  # fmt: skip
OPTIONS = [f"{g}={p.stem}" for g in GROUPS for p in sorted((CONF / g).glob("*.yaml"))]
OPS = ("selection", "crossover", "mutation", "inversion", "rotation", "refine")


def hydras(node, *args, **kwargs):
    """``hydra.utils.instantiate`` with plain values (``_convert_: object``), zrp_ga's targets trusted (hydra-core 1.4)."""
    trusted = {"_execution_whitelist_": config.TRUSTED_TARGETS + ["builtins.*", "fractions.*"]} if config.hydra_14() else {}
    return hydra.utils.instantiate(node, *args, _convert_="object", **trusted, **kwargs)


def same(a, b, depth: int = 0) -> bool:
    """Equal values: arrays to the last bit, objects by type and attributes (a clock aside)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return type(a) is type(b) and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    if isinstance(a, functools.partial) or hasattr(a, "_hydra_full_key"):  # Hydra 1.3.8's partials check their target on calls
        return a.func is b.func and same(list(a.args), list(b.args)) and same(a.keywords, b.keywords)
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(same(a[k], b[k], depth) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(same(x, y, depth) for x, y in zip(a, b))
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        return type(a) is type(b) and all(same(getattr(a, f.name), getattr(b, f.name), depth) for f in dataclasses.fields(a))
    if hasattr(a, "__dict__") and " at 0x" in repr(a) and depth < 4:
        mine, theirs = ({k: v for k, v in vars(o).items() if k != "_t0"} for o in (a, b))  # _t0: a clock
        return type(a) is type(b) and same(mine, theirs, depth + 1)
    return type(a) is type(b) and (a == b or repr(a) == repr(b))


@pytest.mark.parametrize("option", OPTIONS)
def test_every_spec_of_every_option_is_hydras(option):
    """The same call (callable and arguments) for every spec, and the same object (problem
    instances, the slow ones to build, for a simulated and a measured kind: the same call with
    the same arguments builds the same instance)."""
    overrides = [option, *NEEDS.get(option, [])]
    composed = config.compose(overrides)
    cfg = config.typed(composed)  # config.load's
    specs = [("robot", {}), ("problem", {"robot": targets.instantiate(cfg.robot), "run_seed": 3}), ("algorithm", {})]
    specs += [(f"{g}.op", {}) for g in OPS if OmegaConf.select(composed, f"{g}.op") is not None]
    for key, kwargs in specs:
        node, section = OmegaConf.select(composed, key), _at(cfg, key)
        if key.endswith(".op"):  # a partial itself
            assert same(targets.instantiate(section), hydras(node)), key
            continue
        theirs, mine = hydras(node, _partial_=True), targets.instantiate(section, _partial_=True)
        assert same(mine, theirs), key  # the same callable with the same arguments
        if key != "problem" or option in ("problem=paper", "problem=ur10_ipa"):
            assert same(mine(**kwargs), theirs(**kwargs)), key  # and the same object


def _at(cfg, key: str):
    for part in key.split("."):
        cfg = cfg[part] if isinstance(cfg, dict) else getattr(cfg, part)
    return cfg


@dataclasses.dataclass
class Point:
    x: float = 0.0
    y: float = 0.0


@dataclasses.dataclass
class Boxed:
    _target_: str = "builtins.dict"
    inner: Point = dataclasses.field(default_factory=Point)
    items: list = dataclasses.field(default_factory=lambda: [{"_target_": "fractions.Fraction", "_args_": [1, 3]}, 2])


SPECS = [
    {"_target_": "builtins.dict", "a": 1, "b": {"_target_": "builtins.list", "_args_": [[1, 2]]}},  # nested, built first
    {"_target_": "builtins.dict", "_recursive_": False, "b": {"_target_": "builtins.list", "_args_": [[1, 2]]}},  # passed as is
    {"_target_": "fractions.Fraction", "_args_": [3, 6]},  # positional arguments
    {"_target_": "builtins.dict", "a": [{"_target_": "fractions.Fraction", "_args_": [1, 2]}, {"c": [3, "x"]}]},  # in lists
    {"_target_": "builtins.dict", "a": {"n": {"_target_": "fractions.Fraction", "_args_": [2, 4], "_partial_": False}}},
    {"_target_": "builtins.dict", "_partial_": True, "a": 1, "gone": "???"},  # a missing value: left out of a partial
]


@pytest.mark.parametrize("spec", SPECS + [Boxed()], ids=range(len(SPECS) + 1))
def test_plain_specs_mean_what_they_mean_to_hydra(spec):
    node = OmegaConf.structured(spec) if dataclasses.is_dataclass(spec) else OmegaConf.create(spec)
    theirs, mine = hydras(node), targets.instantiate(spec)
    assert same(mine, theirs)
    if isinstance(mine, functools.partial):
        assert mine(b=2) == theirs(b=2) == {"a": 1, "b": 2}


def test_arguments_given_to_instantiate_and_its_flags_win():
    spec = {"_target_": "fractions.Fraction", "_args_": [1, 2]}
    assert targets.instantiate(spec, 3, 4) == hydras(OmegaConf.create(spec), 3, 4) == 0.75  # positional: replace _args_
    later = targets.instantiate({"_target_": "builtins.sorted", "reverse": False}, _partial_=True, reverse=True)
    assert later([2, 3, 1]) == [3, 2, 1]  # a keyword given here goes to the target as it is


@pytest.mark.parametrize("spec, message", [
    ({"_target_": "zrp_ga.operators.crossover.nothing"}, r"cannot import 'zrp_ga.operators.crossover.nothing'"),
    ({"_target_": "no_such_package.f"}, r"cannot import 'no_such_package.f' \(ModuleNotFoundError"),
    ({"_target_": "math.pi"}, r"'math.pi' is not callable"),
    ({"_target_": "builtins.dict", "a": "???"}, r"a: has no value \(\?\?\?\), which builtins.dict needs"),
    ({"_target_": "builtins.dict", "_partial_": "yes"}, r"_partial_: must be true or false"),
    ({"_target_": "builtins.dict", "_args_": 3}, r"_args_: must be a list"),
    ({"a": 1}, r"not a spec to build"),
])  # fmt: skip
def test_a_spec_that_cannot_be_built_says_why(spec, message):
    with pytest.raises(targets.TargetError, match=message):
        targets.instantiate(spec)
