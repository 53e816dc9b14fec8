import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from hydra.errors import ConfigCompositionException, MissingConfigException

from zrp_ga import config
from zrp_ga.cli import main as cli_main
from zrp_ga.core.errors import one_line
from zrp_ga.core.schema import ConfigError
from zrp_ga.run import build, execute
from zrp_ga.run.callbacks import COLUMNS, WALL_CLOCK_COLUMNS


def _cfg(*overrides):
    return config.load(overrides)


def _run(cfg, path):
    """Run and return what the run wrote into summary.json."""
    objective = execute.run(cfg, path)
    summary = json.loads((path / "summary.json").read_text())
    assert objective == summary["final_cost"]
    return summary


def _zrp_ga(*args, **kw):
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args], capture_output=True, text=True, **kw)


def test_default_run_writes_every_file(tmp_path):
    summary = _run(_cfg("problem.n_validation=20"), tmp_path)
    conv = pd.read_csv(tmp_path / "convergence.csv")
    assert list(conv.columns) == COLUMNS
    assert list(conv["gen"]) == list(range(12))  # initial population and 11 generations
    assert conv["best"].iloc[-1] <= conv["best"].iloc[0]
    best = pd.read_csv(tmp_path / "best_params.csv")
    assert list(best["joint"].astype(str)) == [str(i) for i in range(1, 7)] and "true_du0_x" in best
    init = pd.read_csv(tmp_path / "initial_population.csv")
    assert len(init) == 20 and init["cost"].min() == pytest.approx(conv["best"].iloc[0])
    assert summary["final_cost"] == pytest.approx(conv["best"].iloc[-1])
    assert summary["seed"] == 0 and summary["choices"] == {} and summary["config"]["crossover"]["op"]["_target_"].endswith("two_point")
    assert summary["identifiability"]["rank"] == 12  # one pose: 6 pose rows + 6 unit rows
    assert summary["robot"] == {"name": "puma560", "joints": 6, "joint_types": "RRRRRR"}
    assert summary["instance"] == "puma560-1pose-linear-seed0" and summary["coverage"]["validation_is_extrapolation"]
    assert len(summary["warnings"]) == 1 and "the validation is extrapolation" in summary["warnings"][0]  # one pose covers no region
    assert json.loads((tmp_path / "status.json").read_text()) == {"status": "done"}


def test_same_seed_same_convergence_csv(tmp_path):
    over = ["problem=multipose", "problem.n_validation=10", "population.generations=4"]
    execute.run(_cfg(*over, "seed=7"), tmp_path / "a")
    execute.run(_cfg(*over, "seed=7"), tmp_path / "b")
    a = pd.read_csv(tmp_path / "a" / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
    b = pd.read_csv(tmp_path / "b" / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
    pd.testing.assert_frame_equal(a, b)
    execute.run(_cfg(*over, "seed=8"), tmp_path / "c")
    c = pd.read_csv(tmp_path / "c" / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
    assert not a.equals(c)


@pytest.mark.parametrize("algorithm", ["lm", "cmaes"])
def test_baselines_write_the_same_files(tmp_path, algorithm):
    over = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", f"algorithm={algorithm}",
            "population.generations=20"]  # fmt: skip
    summary = _run(_cfg(*over), tmp_path)
    conv = pd.read_csv(tmp_path / "convergence.csv")
    assert list(conv.columns) == COLUMNS and len(conv) > 2
    assert summary["final_cost"] < 0.8 * summary["nominal_cost"] and summary["algorithm"] == algorithm
    assert (tmp_path / "best_params.csv").exists() and (tmp_path / "initial_population.csv").exists()


def test_lm_finds_the_floor_and_the_ga_with_pinv_meets_it(tmp_path):
    base = ["problem=multipose", "problem.n_poses=15", "problem.n_validation=10"]
    lm = _run(_cfg(*base, "algorithm=lm"), tmp_path / "lm")
    ga = _run(_cfg(*base, "population.generations=10"), tmp_path / "ga")
    assert ga["final_cost"] <= 1.01 * lm["final_cost"]


@pytest.mark.parametrize(
    "override, message",
    [("crossover.prob=1.5", r"crossover.prob: must be a probability in \[0, 1\], got 1.5"),
     ("population.mu=0", "population.mu: must be at least 1"),
     ("refine.share=-0.1", r"refine.share: must be a share in \[0, 1\]"),
     ("problem.n_poses=0", "problem.n_poses: must be at least 1, got 0"),
     ("problem.position_noise=-1", "problem.position_noise: must be a number >= 0, got -1")],
)
def test_bad_settings_stop_before_any_work(tmp_path, override, message):
    with pytest.raises(ConfigError, match=message):
        execute.run(_cfg(override), tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_string_choice_outside_its_enum_fails_at_composition():
    with pytest.raises(ConfigCompositionException) as info:
        _cfg("problem.cost=quadratic")
    assert "Invalid value 'quadratic', expected one of [linear, nonlinear]" in one_line(info.value)


def test_unknown_operator_fails_at_composition():
    with pytest.raises((MissingConfigException, ConfigCompositionException), match="crossover"):
        _cfg("crossover=teleport")


def test_one_pose_warns_once_with_one_consistent_rank(tmp_path, caplog):
    execute.run(_cfg("problem.n_validation=5", "population.generations=1"), tmp_path / "a")
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING" and "extrapolation" not in r.getMessage()]
    assert len(warnings) == 1
    assert warnings[0].startswith("the calibration poses identify 12 of the 31 parameter combinations the model can identify (36 parameters)")
    caplog.clear()
    execute.run(_cfg("problem=multipose", "problem.n_validation=5", "population.generations=1"), tmp_path / "b")
    assert "calibration poses identify" not in caplog.text  # 30 poses carry all the model can identify


def test_command_line_error_is_one_line_and_leaves_no_directory(tmp_path):
    proc = _zrp_ga("crossover.prob=1.5", f"hydra.run.dir={tmp_path / 'run'}")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["zrp-ga: error: crossover.prob: must be a probability in [0, 1], got 1.5"]
    assert not (tmp_path / "run").exists()


def test_the_optimiser_never_starts_from_the_truth(tmp_path):
    execute.run(_cfg("problem.n_validation=5", "population.generations=1"), tmp_path)
    init = pd.read_csv(tmp_path / "initial_population.csv").drop(columns=["individual", "cost"]).to_numpy()
    truth = build.prepare(_cfg(), tmp_path / "other").task.truth
    assert np.min(np.abs(init[:, :, None] - truth[None, None, :])) > 1e-12  # no gene equals a true error


def test_unknown_operator_parameter_is_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match=r"crossover.op: unknown parameter 'etaa' for zrp_ga.operators.crossover.sbx \(takes: low, up, eta, indpb\)"):
        execute.run(_cfg("crossover=sbx", "+crossover.op.etaa=3"), tmp_path)


# --- Hydra's own flags ----------------------------------------------------------------------------
def test_cfg_job_prints_the_config_without_running(tmp_path):
    for args in (["--cfg", "job"], ["-c", "job"], ["--cfg", "job", "--resolve"]):
        proc = _zrp_ga(*args, "crossover=sbx", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        cfg = __import__("yaml").safe_load(proc.stdout)
        assert cfg["crossover"]["op"]["_target_"] == "zrp_ga.operators.crossover.sbx"
        assert cfg["algorithm"]["crossover"] == (cfg["crossover"] if "--resolve" in args else "${crossover}")
    assert not (tmp_path / "outputs").exists()


def test_info_defaults_and_help(tmp_path):
    proc = _zrp_ga("--info", "defaults", cwd=tmp_path)
    assert proc.returncode == 0 and "problem/paper" in proc.stdout and "algorithm/ga" in proc.stdout
    proc = _zrp_ga("--help", cwd=tmp_path)
    assert proc.returncode == 0
    assert proc.stdout.startswith("zrp-ga: calibrate the kinematic parameters")
    for group in ("crossover: blend, none, one_point, sbx, subset, two_point, uniform", "robot: file, puma560, stanford, ur10"):
        assert group in proc.stdout
    assert "convergence.csv" in proc.stdout and "app" not in proc.stdout.split()
    # zrp-ga lists the groups from one copy of Hydra's repository: the same text as Hydra's own
    plain = "import sys; sys.argv = ['zrp-ga', '--help']; from zrp_ga.cli.main import main; main()"
    hydras = subprocess.run([sys.executable, "-c", plain], capture_output=True, text=True, cwd=tmp_path)
    assert hydras.stdout == proc.stdout


def test_help_into_a_closed_pipe_ends_quietly(tmp_path):
    """``zrp-ga --help | head -1``: the reader gone, no error line and no traceback."""
    import os

    read, write = os.pipe()
    os.close(read)  # every write to the pipe fails (EPIPE), as after head has read its lines
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "--help"], stdout=write, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    os.close(write)
    assert proc.returncode == 1 and proc.stderr == ""


def test_a_users_own_config_directory(tmp_path):
    """A robot option of the user's own, from --config-dir or from hydra.searchpath."""
    from zrp_ga import robots

    arm = tmp_path / "myarm.yaml"
    robots.get("ur10").replace(name="myarm").to_yaml(arm)
    (tmp_path / "mine" / "robot").mkdir(parents=True)
    (tmp_path / "mine" / "robot" / "myarm.yaml").write_text(f"name: null\nfile: {arm}\n")
    common = ["problem.n_validation=5", "population.generations=1", "progress=false"]
    for way in (["--config-dir", str(tmp_path / "mine")], [f"hydra.searchpath=[file://{tmp_path / 'mine'}]"]):
        run_dir = tmp_path / f"run{len(way)}"
        proc = _zrp_ga(*way, "robot=myarm", *common, f"hydra.run.dir={run_dir}")
        assert proc.returncode == 0, proc.stderr
        assert json.loads((run_dir / "summary.json").read_text())["robot"]["name"] == "myarm"


def test_objective_over_floor_divides_by_an_independent_least_squares_floor(tmp_path):
    """objective=over_floor: the run returns its final cost over the instance's floor, which is
    the minimum of the cost; checked with scipy's least_squares on the residual, started from
    the nominal model, with a numeric Jacobian (not the package's LM, whose Jacobian is analytic)."""
    from scipy.optimize import least_squares

    over = ["instance=puma560_6poses", "refine=none", "population.generations=5", "objective=over_floor"]
    value = execute.run(config.load(over), tmp_path / "ga", progress=False)
    s = json.loads((tmp_path / "ga" / "summary.json").read_text())
    p = build.prepare(config.load(over), None).task.problem
    fit = least_squares(p.residual, np.zeros(p.lower.size), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert s["floor"]["cost"] == pytest.approx(float(p.costs(fit.x[None])[0]), rel=1e-6)
    assert value == pytest.approx(s["final_cost"] / s["floor"]["reference"]) and value > 1.0
    assert s["objective"] == value


def test_exact_data_take_the_round_off_reference():
    """Without noise the floor is round-off: the objective divides by 1e-9 x the nominal cost."""
    from zrp_ga.run import summary

    task = build.prepare(config.load(["instance=puma560_30poses_exact"]), None).task
    f = summary.floor(task)
    nominal = float(task.problem.costs(np.zeros(task.problem.lower.size))[0])
    assert f["cost"] < 1e-12 * nominal and f["reference"] == pytest.approx(1e-9 * nominal)


def test_hparams_search_composes_with_optuna():
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    cfg = config.compose(["hparams_search=ga_optuna"], return_hydra_config=True)
    assert "OptunaSweeper" in cfg.hydra.sweeper._target_ and cfg.objective.value == "over_floor"
    assert "population.mu" in cfg.hydra.sweeper.params and cfg.refine.op is None


def test_a_tuning_studys_running_trials_settled_only_where_its_folders_say(tmp_path):
    """zrp_ga.cli.study.settle on trials left RUNNING (the finished run's case: the slow
    test_a_tuning_study_stopped_settles_its_trials_and_continues): a trial without a folder FAILs
    when the storage is the sweep folder's own optuna.db and is left RUNNING on another storage
    (it may be another sweep's); a folder of other settings leaves its trial RUNNING; a folder of
    the trial's settings whose run did not finish FAILs it."""
    optuna = pytest.importorskip("optuna")
    from zrp_ga.cli import study

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sweep = tmp_path / "tune"
    sweep.mkdir()

    def running(url: str, n: int) -> list:
        s = optuna.create_study(study_name="s", storage=url)
        return [s.ask().suggest_float("mutation.prob", 0.05, 1.0) for _ in range(n)]

    own = f"sqlite:///{sweep / 'optuna.db'}"
    probs = running(own, 3)
    (sweep / "1" / ".hydra").mkdir(parents=True)
    (sweep / "1" / ".hydra" / "overrides.yaml").write_text(f"- mutation.prob={probs[1] / 2!r}\n- hparams_search=ga_optuna\n")
    (sweep / "2" / ".hydra").mkdir(parents=True)
    (sweep / "2" / ".hydra" / "overrides.yaml").write_text(f"- mutation.prob={probs[2]!r}\n- hparams_search=ga_optuna\n")
    (sweep / "2" / "status.json").write_text('{"status": "interrupted"}')
    assert study.settle(study.Study(own, "s", sweep)) == [(0, "FAIL"), (2, "FAIL")]
    assert [t.state.name for t in optuna.load_study(study_name="s", storage=own).get_trials()] == ["FAIL", "RUNNING", "FAIL"]
    shared = f"sqlite:///{tmp_path / 'shared.db'}"
    running(shared, 1)
    assert study.settle(study.Study(shared, "s", sweep)) == []
    assert optuna.load_study(study_name="s", storage=shared).get_trials()[0].state.name == "RUNNING"


def test_a_named_instance_is_the_same_whatever_the_runs_seed():
    """problem.seed fixes the simulated instance; the run's seed only varies the optimiser
    (before, the run's seed replaced problem.seed and every seed drew another instance under
    the same instance name)."""
    def data(*over):
        p = build.prepare(config.load(list(over)), None).task.problem
        return p.data.q, p.data.p

    a, b = data("instance=puma560_30poses", "seed=0"), data("instance=puma560_30poses", "seed=7")
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    c = data("problem=multipose", "seed=0")  # no problem.seed: the run's seed draws the instance
    d = data("problem=multipose", "seed=7")
    assert not np.array_equal(c[0], d[0])
    e = data("problem=multipose", "seed=7", "problem.seed=0")
    np.testing.assert_array_equal(c[0], e[0])


def test_over_floor_is_refused_where_there_is_no_floor(tmp_path):
    with pytest.raises(ConfigError, match="objective: over_floor"):
        build.prepare(config.load(["experiment=pose_selection", "objective=over_floor"]), tmp_path / "run")


def test_the_command_line_builds_a_run_once(tmp_path, monkeypatch, capsys):
    """Prepare (the callback that checks before Hydra makes the directory) builds the run and
    main runs that very run: one prepare and one build per run, with the group options the
    command line chose and the directory Hydra made (absolute, as it prints)."""
    from hydra.core.global_hydra import GlobalHydra

    from zrp_ga.cli import callbacks
    from zrp_ga.run import build

    calls = {"prepare": 0, "build": 0}
    for name in calls:
        real = getattr(build, name)
        monkeypatch.setattr(build, name, lambda *a, _f=real, _n=name, **k: calls.__setitem__(_n, calls[_n] + 1) or _f(*a, **k))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["zrp-ga", "hydra.run.dir=run", "crossover=sbx", "problem.n_validation=5",
                                      "population.generations=2", "progress=false"])  # fmt: skip
    GlobalHydra.instance().clear()
    cli_main.main()
    assert calls == {"prepare": 1, "build": 1}
    assert callbacks._PREPARED == {}  # handed over, nothing kept for the next run
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["choices"]["crossover"] == "sbx" and summary["choices"]["problem"] == "paper"
    assert f"results in {tmp_path / 'run'}\n" in capsys.readouterr().out


@pytest.mark.parametrize("argv, said", [(["-m", "seed=0,1"], "continue with the same command"),
                                        (["hydra.mode=MULTIRUN", "seed=0,1"], "continue with the same command"),
                                        (["seed=3"], "stopped before the run started: nothing to continue")])  # fmt: skip
def test_ctrl_c_before_hydra_knows_the_run_says_what_to_do(monkeypatch, argv, said):
    """Ctrl-C in a sweep's own process (its jobs run in workers) or before Hydra set the run up:
    no placeholder for a run directory there is none of ("continue with  zrp-ga resume=the run
    directory", as a sweep stopped at its start printed)."""
    from hydra.core.hydra_config import HydraConfig

    from zrp_ga.cli import main

    monkeypatch.setattr(HydraConfig, "initialized", staticmethod(lambda: False))
    monkeypatch.setattr(sys, "argv", ["zrp-ga", *argv])
    text = main._continue_with()
    assert said in text and "resume=" not in text and "  " not in text
