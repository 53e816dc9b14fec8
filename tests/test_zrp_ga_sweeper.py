"""zrp_ga's sweeper (``hydra/sweeper=zrp_ga``, the default, hydra_plugins/zrp_ga_sweeper): Hydra's
basic sweeper's jobs in Hydra's order, each job's record as the basic sweeper's sweep writes it, a
bad value or option refused before any job runs, few compositions to check a big grid, and the
launcher's lockstep batches as whole as with Hydra's sweeper."""

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


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_the_sweepers_jobs_write_what_the_basic_sweepers_write(tmp_path):
    ours, basic = _sweep(tmp_path / "ours"), _sweep(tmp_path / "basic", "hydra/sweeper=basic")
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
    proc = _sweep(tmp_path / "bad", "population.mu=30,x")
    assert proc.returncode == 2 and proc.stderr.startswith("zrp-ga: error: ") and "population.mu" in proc.stderr
    assert not list((tmp_path / "bad").glob("*/.hydra"))


@pytest.mark.parametrize("args, sweeper", [([], "ZrpGaSweeper"), (["hydra/sweeper=basic"], "BasicSweeper"),
                                           (["hparams_search=ga_optuna"], "OptunaSweeper")])  # fmt: skip
def test_the_default_sweeper_is_zrp_gas_and_a_search_or_the_command_line_chooses_another(args, sweeper):
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper") if "hparams_search=ga_optuna" in args else None
    config.launcher_stored()
    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        cfg = compose("config", overrides=args, return_hydra_config=True)
    assert cfg.hydra.sweeper._target_.rsplit(".", 1)[1] == sweeper


def _dispatched(proc: subprocess.CompletedProcess) -> list[int]:
    """The jobs in the order the launcher sent them to its workers (its ``#N : ...`` lines)."""
    return [int(line.split("#", 1)[1].split(" ", 1)[0]) for line in (proc.stdout + proc.stderr).splitlines() if "\t#" in line]


def test_the_launcher_sends_the_runs_of_one_instance_together_without_every_job_composed(tmp_path):
    """seed varies fastest and draws the instance: the 16 operator sets of a seed (jobs 0, 3, 6,
    ...) are one batch key. With zrp_ga's sweeper the launcher groups them from the overrides
    (one composition per swept key) and sends each seed's 16 as one batch, as it does from the
    keys noted while Hydra's sweeper composes every job. In order, composing 32 jobs ahead
    (twice the batch of 16 on one worker), it would send the ~11 of each seed it had composed,
    then the rest: the seeds would come back."""
    where = tmp_path / "order"
    where.mkdir()
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "-m", "crossover=sbx,blend", "mutation=gaussian,polynomial",
                           "inversion=none,segment", "rotation=none,segment", "seed=0,1,2", *SMALL,
                           "hydra.launcher.n_jobs=1", f"hydra.sweep.dir={where}"],
                          capture_output=True, text=True, cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    order = _dispatched(proc)
    assert sorted(order) == list(range(48))
    seeds = [job % 3 for job in order]
    assert seeds == sorted(seeds, key=seeds.index), order  # each seed's 16 jobs side by side


def test_a_config_composed_without_the_app_finds_the_default_sweeper(tmp_path):
    """``zrp_ga.config.load`` (which ``zrp_ga.calibrate`` uses) in a fresh process that never
    imported the plugins: hparams_search=none's sweeper (zrp_ga's) must be stored, as the
    launcher's is, or every composition fails ("Could not find 'hydra/sweeper/zrp_ga'")."""
    code = ("import sys; from zrp_ga import config; cfg = config.compose(['seed=3'], return_hydra_config=True); "
            "assert 'hydra_plugins.zrp_ga_sweeper.sweeper' in sys.modules; print(cfg.hydra.sweeper._target_)")  # fmt: skip
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "hydra_plugins.zrp_ga_sweeper.sweeper.ZrpGaSweeper"


def test_a_users_experiment_file_chooses_its_own_sweeper(tmp_path):
    """An experiment in the user's config folder that chooses a sweeper gets it (hparams_search's
    default, which chooses zrp_ga's, comes before experiment in the defaults list); the default
    without one stays zrp_ga's."""
    (tmp_path / "mine" / "experiment").mkdir(parents=True)
    (tmp_path / "mine" / "experiment" / "mybasic.yaml").write_text(
        "# @package _global_\ndefaults:\n  - override /hydra/sweeper: basic\nseed: 4\n")

    def sweeper(*args: str) -> str:
        proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "--config-dir", str(tmp_path / "mine"), *args, "--cfg", "hydra"],
                              capture_output=True, text=True, cwd=tmp_path)  # fmt: skip
        assert proc.returncode == 0, proc.stderr[-2000:]
        return OmegaConf.create(proc.stdout).hydra.sweeper._target_.rsplit(".", 1)[1]

    assert sweeper("experiment=mybasic") == "BasicSweeper"
    assert sweeper("experiment=operator_grid") == "ZrpGaSweeper"


def test_hparams_search_null_is_refused_naming_the_option_to_use(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "hparams_search=null"], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "(hparams_search=null)" in proc.stderr and "hparams_search=none" in proc.stderr
