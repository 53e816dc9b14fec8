"""Config groups, sweeps and their manifest, checkpoints and resume, one-line config errors."""

import io
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from zrp_ga import config, robots
from zrp_ga.core.errors import one_line
from zrp_ga.core.schema import ConfigError
from zrp_ga.run import build, callbacks, execute
from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS
from zrp_ga.run.directory import read_manifest

GROUPS = ["robot", "problem", "algorithm", "population", "selection", "crossover", "mutation", "inversion",
          "rotation", "refine", "experiment"]


def _options(group):
    import importlib.resources

    files = importlib.resources.files(f"zrp_ga.conf.{group}")
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))


@pytest.mark.parametrize("group", GROUPS)
def test_every_option_of_every_group_composes_and_builds(group, tmp_path):
    options = _options(group)
    assert options, group
    for option in options:
        over = [f"{group}={option}"]
        if option == "file":
            path = tmp_path / "arm.yaml"
            robots.get("ur10").to_yaml(path)
            over.append(f"robot.file={path}")
        if option == "measured":
            over += ["robot=ur10", "problem.format=ur10_ipa", "problem.calibration_file=pkg:ur10_ipa/series_b_joint_configurations.csv"]
        cfg = config.load(over)
        p = build.prepare(cfg, tmp_path / "run")
        p.algorithm.setup(p.task.problem, np.random.default_rng(0))
        assert hasattr(p.algorithm.toolbox, "evaluate") and p.task.layout.size >= 6 * p.task.robot.n  # the parameters (before the restriction to the identified ones)


@pytest.mark.parametrize("preset, target", [("local", "ZrpGaLauncher"), ("zrp_ga", "ZrpGaLauncher"), ("joblib", "Joblib")])
def test_launcher_presets_compose(preset, target):
    if preset == "joblib":
        pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    cfg = config.compose([f"hydra/launcher={preset}"], return_hydra_config=True)
    assert target in cfg.hydra.launcher._target_
    assert preset != "local" or cfg.hydra.launcher.n_jobs == -1


@pytest.mark.parametrize(
    "override, key",
    [("problem.n_pose=30", "problem.n_pose"), ("population.mu=abc", "population.mu"), ("seed=1.5", "seed")],
)
def test_schema_refuses_wrong_keys_and_types_at_composition(override, key):
    with pytest.raises(Exception) as info:
        config.load([override])
    assert f"(key: {key})" in one_line(info.value)


def _zrp_ga(*args, **kw):
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args], capture_output=True, text=True, **kw)


@pytest.mark.parametrize(
    "override, expected",
    [
        ("crossover=teleport", "Could not find 'crossover/teleport'; available options in 'crossover': blend, none"),
        ("crossover.prob=1.5", "crossover.prob: must be a probability in [0, 1], got 1.5"),
        ("population.mu=0", "population.mu: must be at least 1, got 0"),
        # OmegaConf 2.4 adds its suggestion: "... not in 'SimulatedConf'. Did you mean: 'n_poses'? (key: ...)".
        ("problem.n_pose=30", re.compile(r"Key 'n_pose' not in 'SimulatedConf'(\. Did you mean: 'n_poses'\?)? \(key: problem\.n_pose\)")),
    ],
)
def test_bad_config_is_one_line_naming_the_key(tmp_path, override, expected):
    proc = _zrp_ga(override, f"hydra.run.dir={tmp_path / 'run'}")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("zrp-ga: error: ")
    assert expected.search(lines[0]) if isinstance(expected, re.Pattern) else expected in lines[0]
    assert not (tmp_path / "run").exists()


def test_a_run_never_overwrites_another(tmp_path):
    cfg = config.load(["problem.n_validation=5", "population.generations=2"])
    execute.run(cfg, tmp_path)
    before = (tmp_path / "convergence.csv").read_text()
    with pytest.raises(ConfigError, match="already holds a run"):
        execute.run(cfg, tmp_path)
    assert (tmp_path / "convergence.csv").read_text() == before


FAST = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "refine=none", "population.mu=30",
        "population.lambda_=30", "seed=4"]


def _csv(path):
    return pd.read_csv(path / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)


def test_interrupted_run_resumes_to_the_same_csv(tmp_path, monkeypatch):
    cfg = config.load(FAST + ["population.generations=40", "checkpoint_every=7"])
    execute.run(cfg, tmp_path / "whole")
    write = callbacks.ConvergenceLog.on_generation

    def ctrl_c_after_gen_23(self, algorithm, row):
        write(self, algorithm, row)
        if row["gen"] == 23:
            raise KeyboardInterrupt

    monkeypatch.setattr(callbacks.ConvergenceLog, "on_generation", ctrl_c_after_gen_23)
    with pytest.raises(KeyboardInterrupt):
        execute.run(cfg, tmp_path / "cut")
    monkeypatch.setattr(callbacks.ConvergenceLog, "on_generation", write)
    assert _csv(tmp_path / "cut")["gen"].max() == 23  # complete up to the last finished generation
    final = execute.run(config.load([f"resume={tmp_path / 'cut'}"]), tmp_path / "ignored")
    pd.testing.assert_frame_equal(_csv(tmp_path / "cut"), _csv(tmp_path / "whole"))
    assert final == pd.read_csv(tmp_path / "whole" / "convergence.csv")["best"].iloc[-1]
    assert not (tmp_path / "ignored").exists()


@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_killed_process_resumes_to_the_same_csv(tmp_path):
    args = FAST + ["population.generations=1500", "checkpoint_every=25", "progress=false"]
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *args, f"hydra.run.dir={tmp_path / 'cut'}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    csv = tmp_path / "cut" / "convergence.csv"
    deadline = time.time() + 60
    while time.time() < deadline and not (csv.exists() and csv.read_text().count("\n") > 60):
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)  # no chance to save anything: the last periodic checkpoint counts
    proc.wait()
    assert len(pd.read_csv(csv)) < 1501, "the run finished before it could be killed"
    done = _zrp_ga(f"resume={tmp_path / 'cut'}", f"hydra.run.dir={tmp_path / 'resume_log'}", "progress=false")
    assert done.returncode == 0, done.stderr
    # the resumed run records the options of its own command line (FAST), not the defaults'
    choices = json.loads((tmp_path / "cut" / "summary.json").read_text())["choices"]
    assert (choices["problem"], choices["refine"]) == ("multipose", "none")
    assert "the paper" not in done.stdout
    whole = _zrp_ga(*args, f"hydra.run.dir={tmp_path / 'whole'}")
    assert whole.returncode == 0, whole.stderr
    pd.testing.assert_frame_equal(_csv(tmp_path / "cut"), _csv(tmp_path / "whole"))


def test_sweep_with_a_failing_job_keeps_the_others_and_names_the_failure(tmp_path):
    sweep = tmp_path / "sweep"
    proc = _zrp_ga("-m", "problem.n_poses=4,0,6", "problem.n_validation=5", "population.generations=3",
                   f"hydra.sweep.dir={sweep}")
    assert proc.returncode != 0  # Hydra reports that not all jobs succeeded
    manifest = read_manifest(sweep)
    assert list(manifest["status"]) == ["done", "failed", "done"]
    assert "problem.n_poses: must be at least 1" in manifest.loc[1, "error"]
    assert manifest.loc[1, "overrides"] == "problem.n_poses=0 problem.n_validation=5 population.generations=3"
    for job in (0, 2):
        run_dir = sweep / manifest.loc[job, "dir"]
        assert len(pd.read_csv(run_dir / "convergence.csv")) == 4
        assert (run_dir / "summary.json").exists() and (run_dir / "best_params.csv").exists()
    assert (sweep / "manifest.csv").exists()


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_joblib_sweep_runs_jobs_in_parallel_processes(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    sweep = tmp_path / "sweep"
    proc = _zrp_ga("-m", "seed=0,1,2,3", "problem.n_validation=5", "population.generations=3",
                   "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep}")
    assert proc.returncode == 0, proc.stderr
    manifest = read_manifest(sweep)
    assert list(manifest["status"]) == ["done"] * 4
    assert "job 3 [seed=3" in proc.stdout + proc.stderr  # one compact line per job


def test_progress_line_shows_generation_evaluations_best_and_time_left():
    class Partway:  # an algorithm part way through its budget, not done
        done = 0.125

        def fraction_done(self):
            return self.done

        def has_next(self):
            return True

    out, algorithm = io.StringIO(), Partway()
    progress = callbacks.Progress(stream=out, every_s=0)
    progress.on_generation(algorithm, {"gen": 1, "nevals": 40, "best": 0.5, "val_rms_mm": 9.0, "wall_s": 1.0})
    algorithm.done = 0.25
    progress.on_generation(algorithm, {"gen": 25, "nevals": 520, "best": 0.0123, "val_rms_mm": 1.5, "wall_s": 2.0})
    first, line = out.getvalue().splitlines(keepends=True)
    assert "time left" not in first  # no pace yet after the first generation
    assert line == "gen    25  evals      520  best 0.0123  val_rms 1.5 mm  time left    6.0 s\n"  # 1 s per 1/8: 6 s to go


def test_progress_line_on_a_terminal_is_rewritten_in_place_and_ends_once():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    out = Tty()
    cfg = config.load(["problem.n_validation=5", "population.generations=3"])
    p = build.prepare(cfg, Path("/nonexistent"))
    p.algorithm.run(p.task.problem, np.random.default_rng(0), [callbacks.Timing(), callbacks.Progress(stream=out, every_s=0)])
    text = out.getvalue()
    assert text.count("\n") == 1 and text.endswith("\n") and text.count("\r") == 4  # generations 0-3, one line
    assert text.count("\x1b[K") == 4  # each rewrite clears what a longer line left


@pytest.mark.slow
@pytest.mark.parametrize("launcher, plugin", [("submitit_local", "hydra_plugins.hydra_submitit_launcher"),
                                              ("ray_local", "hydra_plugins.hydra_ray_launcher")])
def test_cluster_launchers_run_a_sweep_here(tmp_path, launcher, plugin):
    """pip install ".[slurm,ray]", then pytest -m slow. submitit_local is the submitit (SLURM)
    path on this machine; ray_local starts a local Ray cluster."""
    pytest.importorskip(plugin)
    sweep = tmp_path / "sweep"
    args = ("-m", "seed=0,1", "problem.n_validation=5", "population.generations=3", f"hydra/launcher={launcher}",
            f"hydra.sweep.dir={sweep}")  # fmt: skip
    proc = _zrp_ga(*args, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    manifest = read_manifest(sweep)
    assert list(manifest["status"]) == ["done", "done"]
    for d in manifest["dir"]:
        assert len(pd.read_csv(sweep / str(d) / "convergence.csv")) == 4
    runs = {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")}
    again = _zrp_ga(*args, timeout=600)  # the same command again: the sweep is complete, nothing runs
    assert again.returncode == 0, again.stderr[-2000:]
    assert {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")} == runs
    assert list(read_manifest(sweep)["status"]) == ["done", "done"]


def _reference_runs():
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "experiments" / "reference_runs.py"
    spec = importlib.util.spec_from_file_location("reference_runs", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run_files(where: Path, best: list[float], eval_s: list[float], summary: dict) -> Path:
    where.mkdir()
    rows = ["gen,nevals,best,val_rms_mm,eval_s,bookkeeping_s,refine_s,wall_s"]
    rows += [f"{g},50,{b!r},{'nan' if g == 0 else 1.5},{t},0.001,0.0,{t + 0.01}" for g, (b, t) in enumerate(zip(best, eval_s))]
    (where / "convergence.csv").write_text("\n".join(rows) + "\n")
    (where / "summary.json").write_text(json.dumps(summary))
    return where


def test_run_comparison_ignores_timing_and_names_the_first_difference(tmp_path):
    differences = _reference_runs().run_differences
    summary = {"final_cost": 0.25, "nevals": 100, "wall_s": 1.0, "versions": {"numpy": "2.0"}, "param_err": {"calibrated": 0.5}}
    a = _run_files(tmp_path / "a", [0.5, 0.25], [0.01, 0.02], summary)
    # other timings, versions and wall_s: the same run
    b = _run_files(tmp_path / "b", [0.5, 0.25], [0.03, 0.05], {**summary, "wall_s": 9.0, "versions": {"numpy": "2.1"}})
    assert differences(a, b) == []
    # one ulp off in generation 1's best, and a nested summary field changed
    c = _run_files(tmp_path / "c", [0.5, float(np.nextafter(0.25, 1))], [0.01, 0.02], {**summary, "param_err": {"calibrated": 0.4}})
    found = differences(a, c)
    assert len(found) == 2
    assert found[0].startswith("convergence.csv row 1 (gen 1), best: 0.25 against 0.25000000000000006")
    assert found[1] == "summary.json param_err.calibrated: 0.5 against 0.4"
    d = _run_files(tmp_path / "d", [0.5], [0.01], summary)  # a run that stopped a generation earlier
    assert differences(a, d) == [f"convergence.csv: columns {['gen', 'nevals', 'best', 'val_rms_mm']} and 2 rows against "
                                 f"{['gen', 'nevals', 'best', 'val_rms_mm']} and 1 rows"]  # fmt: skip
