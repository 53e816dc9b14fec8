"""The typed config: Hydra's composition turned typed (``config.typed``) is OmegaConf's own
``to_object`` of it, and its plain values (``schema.to_dict``, what the files record) are
OmegaConf's ``to_container``, key order included, for every option of every group; a config
read back from plain values (a checkpoint's) is refused key by key where the schema refuses it;
a problem kind and an optimiser without a schema (plain ``_target_`` configs) run; the schemas
are stored in Hydra's ConfigStore once."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest
from omegaconf import OmegaConf
from test_targets import NEEDS, OPTIONS

from zrp_ga import config
from zrp_ga.core import schema
from zrp_ga.core.schema import ConfigError
from zrp_ga.run import build, directory, execute

CONFIGS = [[], ["experiment=operator_grid", "hydra.mode=RUN"], ["algorithm=cmaes", "problem.fixed=[u0_1,tool]"],
           ["problem=ur10_ipa", "+problem.known_tools={a: [0.1, 0, 0]}"], ["instance=ur10_30poses", "crossover=sbx"],
           ["population.mu=7", "crossover=blend", "crossover.op.alpha=0.25", "problem.search_scale=2"]]  # fmt: skip


@pytest.mark.parametrize("overrides", CONFIGS + [[o, *NEEDS.get(o, [])] for o in OPTIONS], ids=lambda o: " ".join(o) or "default")
def test_the_typed_config_is_omegaconfs_object_and_records_omegaconfs_values(overrides):
    cfg = config.compose(overrides)
    typed = config.typed(cfg)
    assert typed == OmegaConf.to_object(cfg)  # the dataclasses, Enums and plain dicts OmegaConf builds
    want = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    got = schema.to_dict(typed)
    assert got == want and repr(got) == repr(want)  # the same values, types and key order
    assert config.resolved(cfg) == want and schema.from_dict(json.loads(json.dumps(want))) == typed  # a checkpoint's way back
    assert build.instance_key(typed, got) == build.instance_key(typed)


def test_the_hydra_node_is_left_out():
    cfg = config.compose(["seed=3"], return_hydra_config=True)
    assert "hydra" in cfg and "hydra" not in config.resolved(cfg) and config.typed(cfg).seed == 3


def test_interpolations_other_than_node_references_are_left_to_omegaconf():
    cfg = OmegaConf.create({"a": {"x": 1, "y": "${b}"}, "b": {"z": "${c.w}", "v": [1, "${a.x}"]}, "c": {"w": 2.5},
                            "s": "run_${c.w}", "e": "\\${a}", "r": "${.s}", "n": "${c}", "w": "${c.w}", "m": "???"})  # fmt: skip
    assert config.resolved(cfg) == OmegaConf.to_container(cfg, resolve=True)
    chained = OmegaConf.create({"p": {"q": "${r}"}, "r": {"t": [1, 2]}, "u": "${p}"})
    assert config.resolved(chained) == OmegaConf.to_container(chained, resolve=True) == {
        "p": {"q": {"t": [1, 2]}}, "r": {"t": [1, 2]}, "u": {"q": {"t": [1, 2]}}}


def _plain(**changes):
    data = schema.to_dict(config.load([]))
    for key, value in changes.items():
        *path, last = key.split("__")
        node = data
        for part in path:
            node = node[part]
        node[last] = value
    return data


@pytest.mark.parametrize("changes, message", [
    ({"seedd": 1}, r"^seedd: not a setting \(known: algorithm, checkpoint_every,"),
    ({"problem__n_pose": 30}, r"^problem\.n_pose: not a setting \(known: .*n_poses"),
    ({"algorithm__strategy": "steady"}, r"^algorithm\.strategy: 'steady' is not one of mu_plus_lambda, mu_comma_lambda, generational$"),
    ({"objective": "best"}, r"^objective: 'best' is not one of final_cost, over_floor$"),
    ({"checkpoint_every": "often"}, r"^checkpoint_every: must be a whole number, got 'often'$"),
    ({"population__mu": 2.5}, r"^population\.mu: must be a whole number, got 2\.5$"),
    ({"progress": "yes"}, r"^progress: must be true or false, got 'yes'$"),
    ({"problem__fixed": ["u0_1", 3]}, r"^problem\.fixed\[1\]: must be a string, got 3$"),
    ({"algorithm__population": {"mu": 3, "lambda": 3}}, r"^algorithm\.population\.lambda: not a setting"),
    ({"problem": {"n_poses": 3}}, r"^problem: must be the settings of a problem kind, naming it by _target_"),
    ({"robot": [1]}, r"^robot: must be a mapping of settings, got \[1\]$"),
])  # fmt: skip
def test_plain_values_the_schema_refuses_are_named(changes, message):
    with pytest.raises(ConfigError, match=message):
        schema.from_dict(_plain(**changes))


def test_plain_values_take_the_schemas_types():
    cfg = schema.from_dict(_plain(problem__search_scale=2, algorithm__strategy="generational"))
    assert cfg.problem.search_scale == 2.0 and type(cfg.problem.search_scale) is float  # an int for a float, as OmegaConf
    assert cfg.algorithm.strategy is schema.Strategy.generational
    data = _plain(population__mu=9)
    del data["algorithm"]["population"]  # absent: the root's section, as ${population} gives it
    shared = schema.from_dict(data)
    assert shared.algorithm.population == shared.population and shared.algorithm.population.mu == 9
    assert shared.algorithm.population is not shared.population  # a copy, as OmegaConf's to_object makes
    assert all(m.name == m.value for e in (schema.Cost, schema.Strategy, schema.Index, schema.Kernel) for m in e)


TOY = '''
import numpy as np
from zrp_ga.algorithms import Algorithm, Result
from zrp_ga.problems import simulated


def build(robot, run_seed=0, poses=3, **settings):
    """A problem kind of one's own: the simulated one with its own settings' names."""
    return simulated.build(robot, run_seed, n_poses=poses, n_validation=5, name=f"toy-{poses}")


class Halving(Algorithm):
    """An optimiser of one's own: from the middle of the ranges, halve the step while it fails."""

    def __init__(self, population, steps=5):
        super().__init__()
        self.mu, self.steps = int(population["mu"]), int(steps)  # the root's population, a plain dict here

    def initialize(self):
        p = self.problem
        self.X = self.rng.uniform(p.lower, p.upper, size=(self.mu, p.lower.size))
        self.costs = self.toolbox.evaluate(self.X)
        self.nevals = self.mu
        self.offer(self.X, self.costs)
        self.initial = (self.X.copy(), self.costs.copy())

    def step(self):
        self.gen += 1
        self.X = self.best_x + 0.5**self.gen * self.rng.standard_normal(self.X.shape) * (self.problem.upper - self.problem.lower)
        self.costs = self.toolbox.evaluate(self.X)
        self.nevals += self.mu
        self.offer(self.X, self.costs)
        self.stop_reason = "steps" if self.gen >= self.steps else ""

    def result(self):
        return Result(self.best_x, self.best_cost, self.nevals, self.stop_reason, *self.initial)
'''


def test_a_problem_kind_and_an_optimiser_without_a_schema_run(tmp_path, monkeypatch):
    """Plain ``_target_`` configs of one's own (no dataclass in the schema): composed by Hydra
    from a config directory of one's own, typed as plain dicts, built and run through the run
    layer, recorded as given."""
    (tmp_path / "toy_kinds.py").write_text(TOY)
    monkeypatch.syspath_prepend(str(tmp_path))
    for group, text in (("problem", "_target_: toy_kinds.build\nposes: 4\n"),
                        ("algorithm", "_target_: toy_kinds.Halving\npopulation: ${population}\nsteps: 3\n")):  # fmt: skip
        (tmp_path / "conf" / group).mkdir(parents=True)
        (tmp_path / "conf" / group / "toy.yaml").write_text(text)
    over = [f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "problem=toy", "algorithm=toy", "population.mu=6", "progress=false"]
    cfg = config.load(over)
    assert cfg.problem == {"_target_": "toy_kinds.build", "poses": 4}
    assert cfg.algorithm["population"] == schema.to_dict(cfg.population)
    execute.run(cfg, tmp_path / "run")
    written = directory.read_summary(tmp_path / "run")
    assert written["instance"] == "toy-4" and written["nevals"] == 6 * 4 and written["algorithm"] == "halving"
    assert written["config"]["problem"] == {"_target_": "toy_kinds.build", "poses": 4}


def test_the_schemas_are_stored_in_hydras_config_store_once():
    """zrp_ga's schemas stored once however often configs are composed (hydra-core 1.4 warns about
    a name stored twice, 1.5 refuses), the launcher's and the sweeper's settings each time their module runs (1.3's
    plugin scan runs it again: with its class of then, which a composed config is pickled with)."""
    code = textwrap.dedent("""
        import collections, pickle
        from hydra.core.config_store import ConfigStore
        from hydra.core.plugins import Plugins
        stored = collections.Counter()
        store = ConfigStore.store
        ConfigStore.store = lambda self, name, node, group=None, **kw: (stored.update([(group, name)]), store(self, name, node, group, **kw))[1]
        from zrp_ga import config
        from zrp_ga.cli import main
        main._register_launcher()  # as zrp-ga does, before Hydra's plugin scan
        Plugins.instance()
        cfg = config.compose(["hydra/launcher=local"], return_hydra_config=True); config.load([]); config.load(["algorithm=cmaes"])
        pickle.dumps(cfg)  # the launcher's settings are the class its module holds now
        twice = [key for key, count in stored.items() if count > 1 and key[0] not in ("hydra/launcher", "hydra/sweeper")]
        print(twice or "once", (None, "config_schema") in stored, ("hydra/launcher", "zrp_ga") in stored)
    """)  # fmt: skip
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout.split() == ["once", "True", "True"], done.stdout + done.stderr
