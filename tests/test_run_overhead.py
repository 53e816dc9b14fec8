"""The shortcuts that keep a run's set-up and files cheap in a sweep give what the general
code gives: the resolved config is OmegaConf's, an optimiser built without Hydra is the one
Hydra builds, a file replaced by swapping holds the new text and leaves no temporary file, the
robot files' numbers and rows are what their definitions and PyYAML say, the initial population's
table is write_csv's."""

import dataclasses
import math
import os

import numpy as np
import pytest
import yaml
from omegaconf import OmegaConf

from zrp_ga import config, robots
from zrp_ga.core import fileio
from zrp_ga.io import records, robot_files
from zrp_ga.model import dh
from zrp_ga.run.build import instance_key, task_config

CONFIGS = [[], ["experiment=operator_grid", "hydra.mode=RUN"], ["experiment=methods_baselines", "hydra.mode=RUN"],
           ["algorithm=cmaes"], ["algorithm=lm"], ["algorithm=random_search"], ["problem=ur10_ipa"],
           ["instance=ur10_30poses", "crossover=sbx"]]  # fmt: skip


@pytest.mark.parametrize("overrides", CONFIGS, ids=lambda o: " ".join(o) or "default")
def test_the_resolved_config_is_omegaconfs_and_so_is_the_instance_key(overrides):
    cfg = task_config(config.load(overrides))
    want = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    got = config.resolved(cfg)
    assert got == want and repr(got) == repr(want)  # the same values, types and key order
    assert instance_key(cfg, got) == instance_key(cfg)


def test_interpolations_other_than_node_references_are_left_to_omegaconf():
    cfg = OmegaConf.create({"a": {"x": 1, "y": "${b}"}, "b": {"z": "${c.w}", "v": [1, "${a.x}"]}, "c": {"w": 2.5},
                            "s": "run_${c.w}", "e": "\\${a}", "r": "${.s}", "n": "${c}"})  # fmt: skip
    assert config.resolved(cfg) == OmegaConf.to_container(cfg, resolve=True)
    chained = OmegaConf.create({"p": {"q": "${r}"}, "r": {"t": [1, 2]}, "u": "${p}"})
    assert config.resolved(chained) == OmegaConf.to_container(chained, resolve=True) == {
        "p": {"q": {"t": [1, 2]}}, "r": {"t": [1, 2]}, "u": {"q": {"t": [1, 2]}}}


@pytest.mark.parametrize("algorithm", ["ga", "cmaes", "lm", "random_search", "exchange"])
def test_an_optimiser_built_without_hydra_is_the_one_hydra_builds(algorithm, monkeypatch):
    cfg = task_config(config.load([f"algorithm={algorithm}", "crossover=blend", "population.mu=12"]))
    mine = config.instantiate(cfg.algorithm, "algorithm", root=cfg)
    monkeypatch.setattr(config, "_direct", lambda node, root: None)  # Hydra's instantiate only
    theirs = config.instantiate(cfg.algorithm, "algorithm", root=cfg)
    assert _state(mine) == _state(theirs)


def _state(o, depth: int = 0):
    """What an object holds, as comparable plain values (objects by their type and attributes)."""
    if hasattr(o, "__dict__") and " at 0x" in repr(o) and depth < 3:
        return type(o).__name__, {k: _state(v, depth + 1) for k, v in vars(o).items() if k != "_t0"}  # _t0: a clock
    return repr(o)


def test_replace_leaves_the_new_file_and_no_temporary_one(tmp_path, monkeypatch):
    path, tmp = tmp_path / "state.json", tmp_path / ".state.json.1.tmp"
    for exchange in (fileio._exchange, None):  # Linux's swap, and os.replace where there is none
        monkeypatch.setattr(fileio, "_exchange", exchange)
        path.unlink(missing_ok=True)
        tmp.write_text("first")
        fileio.replace(tmp, path)  # no file there yet
        assert path.read_text() == "first" and not tmp.exists()
        tmp.write_text("second")
        inode = os.stat(tmp).st_ino
        fileio.replace(tmp, path)  # over the old one
        assert path.read_text() == "second" and os.stat(path).st_ino == inode
        assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json"]


def _shortest(v: float) -> float:
    """The definition of robot_files._short for one number: of v + k ulp (k = -8..8), the one
    whose repr is shortest; ties to the smaller |k|, then to the smaller k."""
    ulp = math.copysign(math.ulp(v), v) if v else 5e-324
    candidates = [v + k * ulp for k in range(-8, 9)]
    return min(zip(candidates, range(-8, 9)), key=lambda c: (len(repr(c[0])), abs(c[1]), c[1]))[0] + 0.0


def test_short_numbers_are_the_shortest_within_eight_units_in_the_last_place():
    rng = np.random.default_rng(5)
    values = [0.0, 1.0, -90.00000000000001, 0.020300000000000012, 0.1 + 0.2, 180 / np.pi, 1e-300, -2.5e-7]
    values += (rng.normal(size=300) * 10.0 ** rng.integers(-12, 12, 300)).tolist()
    values += [round(v, k) + e for v in rng.normal(0, 50, 40) for k in (1, 3, 4) for e in (0.0, 1e-15, -4e-14)]
    assert [robot_files._short(v) for v in values] == [_shortest(v) for v in values]
    table = np.array(values[:12]).reshape(3, 4)
    assert robot_files._short(table) == [[_shortest(v) for v in row] for row in table.tolist()]


def test_the_small_vector_helpers_of_to_dh_are_numpys_to_the_last_bit():
    rng = np.random.default_rng(8)
    for _ in range(300):
        u, v = rng.normal(size=3) * 10.0 ** rng.integers(-6, 3), rng.normal(size=3)
        assert np.array_equal(dh._cross(u, v), np.cross(u, v))
        assert dh._norm(u) == np.linalg.norm(u)
    M = rng.normal(size=(4, 4))
    assert dh._norm(M[:3, 2]) == np.linalg.norm(M[:3, 2])  # a strided column
    assert np.array_equal(dh._eyes(3), np.tile(np.eye(4), (3, 1, 1)))


@pytest.mark.parametrize("names", [("yes", "a,b", "x: y", "j\u00e9", "1.5", "null"), ("[x]", "#c", "- d", "'q'", '"r"', "on")])
def test_dh_table_rows_are_what_pyyaml_writes(names):
    """Each joint row of a DH file is PyYAML's flow mapping of the row (names that YAML would
    read otherwise quoted), Hayati rows (beta) included."""
    arm = robots.get("ur10")
    u0 = arm.u0 + np.random.default_rng(1).normal(0, 1e-3, arm.u0.shape)  # nearly parallel axes: Hayati rows
    table, _ = dh.to_dh(dataclasses.replace(arm, u0=u0 / np.linalg.norm(u0, axis=1)[:, None]), "mdh")
    table = robot_files.DHTable(table.convention, table.a, table.alpha, table.d, table.theta, table.joint_types,
                                base=table.base, tool=table.tool, name="arm", joint_names=names, limits=table.limits,
                                beta=table.beta)  # fmt: skip
    assert table.beta.any()
    rows = [line for line in robot_files.dh_to_yaml(table, length="mm").splitlines() if line.startswith("  - ")]
    for i, line in enumerate(rows):
        mm, deg = 1e-3, np.pi / 180  # the file's units, in m and rad
        row = {"name": names[i], "type": table.joint_types[i], "a": robot_files._short(table.a[i] / mm),
               "alpha": robot_files._short(table.alpha[i] / deg), "d": robot_files._short(table.d[i] / mm),
               "theta": robot_files._short(table.theta[i] / deg)}  # fmt: skip
        if table.beta[i]:
            row["beta"] = robot_files._short(table.beta[i] / deg)
        row["limits"] = robot_files._short(np.asarray(table.limits[i]) / deg)
        text = yaml.safe_dump(row, default_flow_style=True, sort_keys=False, width=10**9).strip()
        assert line == "  - " + text + ("  # Hayati row" if table.beta[i] else "")
        assert yaml.safe_load(line[4:].split("  #")[0])["name"] == names[i]


@pytest.mark.parametrize("value", [0.0, -0.0, 1e17, 1e-5, -1e22, 1.5, math.nan, math.inf, -math.inf, 5e-324, 0.1])
def test_a_float_is_written_as_pyyaml_writes_it(value):
    assert robot_files._yaml_float(value) == yaml.safe_dump([value], default_flow_style=True).strip()[1:-1]


def test_the_initial_population_table_is_write_csvs(tmp_path):
    rng = np.random.default_rng(2)
    X, costs = rng.normal(size=(7, 3)), rng.normal(size=7)
    X[1, 2], costs[3], costs[4] = -0.0, np.inf, np.nan
    for names in (["u0_1x", "b0_2,y", 'q"'], ["a", "cost", "c"]):  # a name like a column of its own: the general path
        records.write_csv(tmp_path / "general.csv", records.population_table(names, X, costs))
        records.write_population(tmp_path / "fast.csv", names, X, costs)
        assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "general.csv").read_bytes()
        if names[1] == "b0_2,y":
            lines = (tmp_path / "fast.csv").read_text().splitlines()
            assert lines[0] == 'individual,u0_1x,"b0_2,y","q""",cost' and lines[4].endswith(",inf") and ",-0.0," in lines[2]


def test_the_robot_files_report_each_tables_own_mismatch(tmp_path):
    arm = robots.get("stanford")
    paths, mismatch = robot_files.write_all(arm, tmp_path)
    like = dh.nominal_tables(arm)  # a preset: its own DH file's table is the nominal
    for convention, title in (("dh", "Standard DH"), ("mdh", "Modified DH")):
        table, want = dh.to_dh(arm, convention, like=like[convention])
        assert mismatch[convention] == want
        header = [f"{title} table of {arm.name} (zrp_ga.io.robot_files.to_dh): {want}", *want.notes,
                  f"In the nominal table's conventions (row = nominal + correction; calibrated_robot_{convention}_corrections.csv)"]  # fmt: skip
        assert paths[convention].read_text() == robot_files.dh_to_yaml(table, comment="\n".join(header), near=like[convention])
