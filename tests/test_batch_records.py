"""The launcher's own readings of a job's config (``hydra_plugins.zrp_ga_launcher._batch``)
against OmegaConf's and Hydra's: the containers its ``.hydra`` records are written from
(``OmegaConf.to_container``), the task's config (``run_job``'s deep copy without ``hydra``)."""

from __future__ import annotations

import copy
import enum
import pickle
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from omegaconf import MISSING, DictConfig, ListConfig, OmegaConf, open_dict

from hydra_plugins.zrp_ga_launcher import _batch


class Color(enum.Enum):
    RED = 1
    BLUE = 2


@dataclass
class Inner:
    color: Color = Color.BLUE
    path: Path = Path("/a/b")
    missing: int = MISSING
    maybe: Inner2 | None = None


@dataclass
class Inner2:
    x: float = 1.5


@dataclass
class Outer:
    inner: Inner = field(default_factory=Inner)
    by_color: dict[Color, int] = field(default_factory=lambda: {Color.RED: 1})
    items: list[int] | None = None
    name: str = "${inner.color}"
    later: Inner2 = MISSING
    alias: Inner2 = "${later}"  # type: ignore[assignment]
    none_list: list[int] | None = None


def _odd() -> DictConfig:
    cfg = OmegaConf.structured(Outer)
    with open_dict(cfg):
        cfg.extra = {"a": [1, "two", None, {"b": "${name}"}, [True, 2.5]], "c": "???", "d": {}, "e": [], 3: "yes", "f": b"\x00"}
        cfg.inter_dict = "${extra}"
    return cfg


@pytest.fixture
def hydra_loader():
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    from zrp_ga import config

    config.register()
    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        yield GlobalHydra.instance().hydra.config_loader


def test_containers_are_omegaconfs(hydra_loader):
    from hydra.types import RunMode

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    configs = [hydra_loader.load_sweep_config(master, o) for o in (["seed=1", "crossover=sbx"], ["algorithm=lm"], ["instance=ur10_30poses"])]
    for node in [*configs, _odd(), ListConfig([1, {"a": None}, "${x}"]), OmegaConf.create({"n": None})]:
        ours = _batch._container(node)
        assert ours == OmegaConf.to_container(node, resolve=False, enum_to_str=True)
        assert repr(ours) == repr(OmegaConf.to_container(node, resolve=False, enum_to_str=True))  # the same types (1 is no True)
    for cfg in configs:
        assert _batch._container(cfg.hydra) == OmegaConf.to_container(cfg.hydra, resolve=False, enum_to_str=True)


def test_the_task_config_is_a_copy_without_hydra(hydra_loader):
    """``_without_hydra`` against what Hydra's ``run_job`` makes: a deep copy with ``hydra``
    deleted; the config itself unchanged."""
    from hydra.types import RunMode
    from test_sweeps import _nodes

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    for cfg in (hydra_loader.load_sweep_config(master, ["seed=1", "crossover=sbx"]), _odd()):
        if "hydra" not in cfg:
            with open_dict(cfg):
                cfg.hydra = {"x": 1}
        before = (OmegaConf.to_yaml(cfg), _nodes(cfg), pickle.dumps(cfg))
        ours = _batch._without_hydra(cfg)
        theirs = copy.deepcopy(cfg)
        with open_dict(theirs):
            del theirs["hydra"]
        assert OmegaConf.to_yaml(ours) == OmegaConf.to_yaml(theirs) and _nodes(ours) == _nodes(theirs)
        assert (OmegaConf.to_yaml(cfg), _nodes(cfg), pickle.dumps(cfg)) == before
        key = "seed" if "seed" in cfg else "name"
        ours[key] = 12345  # independent of the config
        assert cfg[key] != 12345 and ours._get_node(key)._get_parent() is ours
