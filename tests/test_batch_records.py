"""The launcher's own readings of a job's config (``hydra_plugins.zrp_ga_launcher._batch``)
against OmegaConf's and Hydra's: the containers its ``.hydra`` records are written from
(``OmegaConf.to_container``), the task's config (``run_job``'s deep copy without ``hydra``)."""

from __future__ import annotations

import copy
import enum
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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

    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        yield GlobalHydra.instance().hydra.config_loader


def test_containers_with_enum_names_are_omegaconfs(hydra_loader):
    """``_names`` of a container against OmegaConf's own ``enum_to_str=True``: enum keys and
    values (the odd config's, Hydra's ``RunMode``) as their names, nothing else changed."""
    from hydra.types import RunMode

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    configs = [hydra_loader.load_sweep_config(master, o) for o in (["seed=1", "crossover=sbx"], ["algorithm=lm"], ["instance=ur10_30poses"])]
    for node in [*configs, *(c.hydra for c in configs), _odd(), ListConfig([1, {"a": None}, "${x}"]), OmegaConf.create({"n": None})]:
        ours = _batch._names(OmegaConf.to_container(node, resolve=False))
        assert ours == OmegaConf.to_container(node, resolve=False, enum_to_str=True)
        assert repr(ours) == repr(OmegaConf.to_container(node, resolve=False, enum_to_str=True))  # the same types (1 is no True)


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


def test_the_task_config_is_made_when_something_could_read_it(hydra_loader):
    """Where ``_task_config_read`` says the task's config need not be made (zrp_ga's own
    callbacks, no interpolation naming ``hydra`` in the task's part), the typed config of the
    whole config is that of Hydra's task config (``run_job``'s deep copy, ``hydra`` deleted);
    a callback of the user's (it gets the job's return) or such an interpolation, at any depth,
    makes it."""
    from hydra.types import RunMode

    from zrp_ga.config import typed

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    for overrides in (["seed=1", "crossover=sbx"], ["algorithm=lm"], ["instance=ur10_30poses"]):
        cfg = hydra_loader.load_sweep_config(master, overrides)
        whole = _batch._names(OmegaConf.to_container(cfg, resolve=False))
        hydra = whole.pop("hydra")
        assert not _batch._task_config_read(hydra, whole), overrides
        theirs = copy.deepcopy(cfg)
        with open_dict(theirs):
            del theirs["hydra"]
        assert typed(cfg) == typed(theirs), overrides
    mine = {**hydra, "callbacks": {**hydra["callbacks"], "mine": {"_target_": "my_package.Recorder"}}}
    assert _batch._task_config_read(mine, whole)
    for odd in ({"note": "${hydra.job.name}"}, {"problem": {**whole["problem"], "x": ["a", {"y": "run ${hydra:job.num}"}]}}):
        assert _batch._task_config_read(hydra, {**whole, **odd}), odd
        assert not _batch._task_config_read(hydra, {**whole, **{k: "${problem}" for k in odd}}), odd


ODD_STRINGS = ["yes", "No", "y", "null", "NULL", "~", "", "nan", "inf", "Infinity", "-inf", "1e3", "1_000", "0x1F", "0o7", "+1", ".5",
               "2001-12-14", "=", "<<", "-a", "- a", "a: b", "a:b", "a #b", "#a", "/tmp/x/1", "crossover=sbx,seed=1", "a,b", "[a]",
               "{a}", "a b", "x" * 200, "a " * 60, "/" + "d" * 150, "a\nb", "é", "'q'", '"q"', "%a", "@a", "`a", "!a", "&a", "*a",
               "?a", "|a", ">a", "a+b", "_a", "a.b.c", "7", "-7", "True", "off", "a=", "a-", "a,", "Null"]  # fmt: skip


def test_yaml_texts_of_odd_values_at_any_depth_are_omegaconfs():
    """``to_yaml`` (its texts written directly, kept, or PyYAML's) against ``OmegaConf.to_yaml``:
    strings and numbers YAML reads as something else, long ones, in mappings and sequences at
    several depths, written twice (the second time from the kept texts)."""
    import random

    rng = random.Random(7)
    alphabet = "ab_/.=,+-:# 0129'\"~é\n"
    strings = ODD_STRINGS + ["".join(rng.choice(alphabet) for _ in range(rng.randrange(0, 12))) for _ in range(300)]
    values = [*strings, 0, -5, 10**30, True, False, 1.0, 1e-20, None, [], {}]
    for depth in range(4):
        for chunk in range(0, len(values), 40):
            part = values[chunk : chunk + 40]
            doc: dict = {"v": {f"k{k}": v for k, v in enumerate(part)}, "seq": part, "x" * 130: part[0], 5: part[-1],
                         "y" * 130: part, "z" * 130: {"a": part[1], "b": part}, "w" * 130: 7, "u" * 130: "/a/b"}  # fmt: skip
            for _ in range(depth):
                doc = {"p": doc}
            cfg = OmegaConf.create(doc)
            for _ in range(2):
                assert _batch.to_yaml(OmegaConf.to_container(cfg, enum_to_str=True)) == OmegaConf.to_yaml(cfg)
            seq = ListConfig(part)
            assert _batch.to_yaml(OmegaConf.to_container(seq)) == OmegaConf.to_yaml(seq)


def test_a_batch_leaves_the_collector_as_it_found_it():
    """``few_collections(freeze_older=True)``, around a batch (``_batch.run_batch``): the
    collector settings (objects from before it frozen, fewer collections) undone after it, also
    when it fails; a process that froze its own objects keeps them frozen."""
    import gc

    from zrp_ga.run import shared

    before = gc.get_threshold()
    assert gc.get_freeze_count() == 0
    with pytest.raises(KeyboardInterrupt), shared.few_collections(freeze_older=True):
        kept = [object()]
        assert gc.get_freeze_count() > 0 and gc.get_threshold()[0] >= 20_000
        raise KeyboardInterrupt
    assert gc.get_freeze_count() == 0 and gc.get_threshold() == before and kept
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        with shared.few_collections(freeze_older=True):
            pass
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()


def test_values_read_from_the_container_are_resolved_as_omegaconf_resolves_them():
    """``_resolved``: a job's value from its unresolved container, or from OmegaConf where it has
    interpolations (a sweep's ``subdir``, an ``env_set`` naming other values) or is missing."""
    cfg = OmegaConf.create({"hydra": {"job": {"num": 3, "env_set": {"A": "${x}/a", "B": "b"}, "plain": {"C": "c"}},
                                      "sweep": {"dir": "/d", "subdir": "${hydra.job.num}", "missing": "???"},
                                      "task": ["x=1", "${x}"]}, "x": "y"})  # fmt: skip
    raw = OmegaConf.to_container(cfg, resolve=False, enum_to_str=True)
    for path in ("hydra.job.env_set", "hydra.job.plain", "hydra.sweep.dir", "hydra.sweep.subdir", "hydra.task", "hydra.sweep.missing"):
        node = raw
        for k in path.split("."):
            node = node[k]
        ours = _batch._resolved(cfg, node, path)
        theirs = OmegaConf.select(cfg, path)
        if isinstance(theirs, (DictConfig, ListConfig)):
            theirs = OmegaConf.to_container(theirs, resolve=True)
        assert ours == theirs and type(ours) is type(theirs), path
    assert _batch._resolved(cfg, raw["hydra"]["sweep"]["subdir"], "hydra.sweep.subdir") == 3


@dataclass
class Typed:
    s: str = "x"
    a: Any = None
    i: int = 3
    f: float = 1.0
    b: bool = True
    e: Color = Color.RED
    n: str | None = None
    m: str = MISSING
    path: str = "/runs/a b"
    inter: str = "${i}"
    to_s: str = ""
    to_a: Any = None


def test_interpolations_read_from_the_values_they_name_are_omegaconfs():
    """``_interpolated`` (from the config's unresolved container) against OmegaConf's resolution
    of the same string in an untyped node, and in a string node (``str()`` of it): the strings it resolves itself (naming numbers, strings, booleans) and
    those it leaves to OmegaConf (enums, None, missing, interpolated values, resolvers, relative
    keys, escapes, quotes)."""
    own = ["${i}", "${f}", "${b}", "${s}", "${path}", "${path}/${s}.log", "${i}${f}", "a${i}b", "${sub.k}", "${sub.k}-${i}"]
    others = ["${e}", "x${e}", "${n}", "${m}", "${inter}", "${oc.env:HOME}", "\\${i}", "${.i}", "'${i}'", "${nope}", "${sub}", "plain",
              "$${i}", "${sub.nope}"]  # fmt: skip
    for text in own + others:
        cfg = OmegaConf.structured(Typed)
        with open_dict(cfg):
            cfg.sub = {"k": "v"}
        ours = _batch._interpolated(text, OmegaConf.to_container(cfg, resolve=False))
        assert (ours is _batch._UNKNOWN) == (text in others), text
        if ours is not _batch._UNKNOWN:
            for field_name, as_node in (("to_s", str), ("to_a", lambda v: v)):  # a string node: str() of it
                cfg[field_name] = text
                theirs = cfg[field_name]
                assert as_node(ours) == theirs and type(as_node(ours)) is type(theirs), (text, field_name)
