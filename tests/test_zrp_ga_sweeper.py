"""zrp_ga's sweeper (``hydra/sweeper=zrp_ga``, hydra_plugins/zrp_ga_sweeper): Hydra's basic
sweeper's jobs in Hydra's order, each job's record as the basic sweeper's sweep writes it, a bad
value or option refused before any job runs, and few compositions to check a big grid."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_module
from hydra._internal.core_plugins.basic_sweeper import BasicSweeper  # the reference (tests only)
from hydra.core.global_hydra import GlobalHydra
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf

from hydra_plugins.zrp_ga_sweeper.sweeper import Checker, _groups, grid
from zrp_ga import config

pytestmark = pytest.mark.hydra_cli


@pytest.mark.parametrize("args", [["a=1,2,3", "b=range(10,40,10)"], ["crossover=sbx,blend", "seed=0", "+x=y,z", "seed=4,5"],
                                  ["mutation=glob(*)", "population.mu=10"], ["k='a,b',c", "~q"]])  # fmt: skip
def test_the_grid_is_the_basic_sweepers(args):
    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        parsed = OverridesParser.create(config_loader=GlobalHydra.instance().config_loader()).parse_overrides(args)
        assert grid(parsed) == BasicSweeper.split_arguments(parsed, None)[0]


def _checked(args: list[str]) -> Checker:
    config.launcher_stored()
    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        master = compose("config", return_hydra_config=True)
        loader = GlobalHydra.instance().config_loader()
        jobs = grid(OverridesParser.create(config_loader=loader).parse_overrides(args))
        checker = Checker(loader, master, _groups(loader, jobs))
        checker.check(jobs)
    return checker


GRID = ["crossover=one_point,two_point,blend,sbx", "mutation=gaussian,polynomial,uniform_reset", "inversion=none,segment",
        "rotation=none,segment", "seed=range(20)", "population.mu=20,30"]  # fmt: skip


class _Keeping:
    """A config loader that hands out Hydra's compositions and keeps them, as zrp_ga's launcher
    keeps the checked configs for the jobs (with their YAML when handed out)."""

    def __init__(self, loader):
        self.loader, self.handed = loader, []

    def get_sources(self):
        return self.loader.get_sources()

    def load_sweep_config(self, master_config, sweep_overrides):
        cfg = self.loader.load_sweep_config(master_config=master_config, sweep_overrides=sweep_overrides)
        self.handed.append((cfg, OmegaConf.to_yaml(cfg)))
        return cfg


def test_checking_leaves_the_configs_it_was_handed_as_they_were():
    config.launcher_stored()
    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        master = compose("config", return_hydra_config=True)
        loader = _Keeping(GlobalHydra.instance().config_loader())
        jobs = grid(OverridesParser.create().parse_overrides(["crossover=sbx,blend", "seed=0,1,2"]))
        Checker(loader, master, {"crossover"}).check(jobs)
    assert len(loader.handed) == 2
    for cfg, text in loader.handed:
        assert OmegaConf.to_yaml(cfg) == text and cfg.seed == 0


def test_a_grid_is_checked_with_one_composition_per_new_option():
    """960 jobs: 1 composition + one per option not chosen by the first job (3 + 2 + 1 + 1)."""
    assert _checked(GRID).compositions == 8


@pytest.mark.parametrize("bad", ["population.mu=20,abc", "crossover=sbx,nope", "population.nu=3", "seed=1.5"])
def test_a_bad_value_or_option_anywhere_in_the_grid_is_hydras_error(bad):
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    with pytest.raises((HydraException, OmegaConfBaseException)):
        _checked([*GRID[:-1], bad])


SMALL = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "refine=none", "population.mu=30",
         "population.lambda_=30", "population.generations=3"]  # fmt: skip


def _sweep(where: Path, *args: str) -> subprocess.CompletedProcess:
    """The sweep on the command line, run from its own folder: from the checkout's root,
    ``python -m`` would import the checkout's zrp_ga (without its configs, which ship as
    zrp_ga.conf) instead of the installed one."""
    where.mkdir(parents=True, exist_ok=True)
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", "-m", "seed=0,1", "crossover=sbx,blend", *SMALL, *args,
                           f"hydra.sweep.dir={where}"], capture_output=True, text=True, cwd=where.parent)  # fmt: skip


def test_the_sweepers_jobs_write_what_the_basic_sweepers_write(tmp_path):
    ours, basic = _sweep(tmp_path / "ours", "hydra/sweeper=zrp_ga"), _sweep(tmp_path / "basic")
    assert ours.returncode == 0 and basic.returncode == 0, ours.stderr[-2000:] + basic.stderr[-2000:]
    assert "Warning" not in ours.stderr, ours.stderr
    assert (tmp_path / "ours" / "multirun.yaml").is_file()
    for job in range(4):
        o, b = tmp_path / "ours" / str(job), tmp_path / "basic" / str(job)
        for name in (".hydra/config.yaml", ".hydra/overrides.yaml", "best_params.csv"):
            assert (o / name).read_text() == (b / name).read_text(), (job, name)
        ho, hb = (OmegaConf.load(x / ".hydra/hydra.yaml").hydra for x in (o, b))
        for h in (ho, hb):  # what differs by design: the sweeper and the sweep directory
            h.sweeper, h.sweep.dir, h.runtime.output_dir, h.overrides.hydra = None, None, None, None
            assert h.runtime.choices.pop("hydra/sweeper") == ("zrp_ga" if h is ho else "basic")
        assert OmegaConf.to_yaml(ho) == OmegaConf.to_yaml(hb)


def test_a_bad_value_stops_the_sweep_before_any_job(tmp_path):
    proc = _sweep(tmp_path / "bad", "hydra/sweeper=zrp_ga", "population.mu=30,x")
    assert proc.returncode == 2 and proc.stderr.startswith("zrp-ga: error: ") and "population.mu" in proc.stderr
    assert not list((tmp_path / "bad").glob("*/.hydra"))
