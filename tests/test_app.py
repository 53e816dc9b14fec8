import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from hydra.errors import ConfigCompositionException, MissingConfigException

from zrp_ga import app, build, config
from zrp_ga.records import CONVERGENCE_COLUMNS, WALL_CLOCK_COLUMNS


def _cfg(*overrides):
    return config.load(overrides)


def test_default_run_writes_every_file(tmp_path):
    summary = app.run(_cfg("problem.n_validation=20"), tmp_path)
    conv = pd.read_csv(tmp_path / "convergence.csv")
    assert list(conv.columns) == CONVERGENCE_COLUMNS
    assert list(conv["gen"]) == list(range(12))  # initial population and 11 generations
    assert conv["best"].iloc[-1] <= conv["best"].iloc[0]
    best = pd.read_csv(tmp_path / "best_params.csv")
    assert list(best["joint"].astype(str)) == [str(i) for i in range(1, 7)] and "true_du0_x" in best
    init = pd.read_csv(tmp_path / "initial_population.csv")
    assert len(init) == 20 and init["cost"].min() == pytest.approx(conv["best"].iloc[0])
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["final_cost"] == pytest.approx(summary["final_cost"]) == pytest.approx(conv["best"].iloc[-1])
    assert on_disk["seed"] == 0 and on_disk["config"]["crossover"]["name"] == "two_point"
    assert on_disk["identifiability"]["rank"] == 12  # one pose: 6 pose rows + 6 unit rows


def test_same_seed_same_convergence_csv(tmp_path):
    cfg = _cfg("problem=multipose", "problem.n_validation=10", "population.generations=4", "seed=7")
    app.run(cfg, tmp_path / "a")
    app.run(cfg, tmp_path / "b")
    a = pd.read_csv(tmp_path / "a" / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
    b = pd.read_csv(tmp_path / "b" / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
    pd.testing.assert_frame_equal(a, b)
    app.run(_cfg("problem=multipose", "problem.n_validation=10", "population.generations=4", "seed=8"), tmp_path / "c")
    c = pd.read_csv(tmp_path / "c" / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
    assert not a.equals(c)


@pytest.mark.parametrize("algorithm", ["lm", "cmaes"])
def test_baselines_write_the_same_files(tmp_path, algorithm):
    over = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", f"algorithm={algorithm}",
            "population.generations=20"]
    summary = app.run(_cfg(*over), tmp_path)
    conv = pd.read_csv(tmp_path / "convergence.csv")
    assert list(conv.columns) == CONVERGENCE_COLUMNS and len(conv) > 2
    assert summary["final_cost"] < 0.8 * summary["nominal_cost"]
    assert (tmp_path / "best_params.csv").exists() and (tmp_path / "initial_population.csv").exists()


def test_lm_finds_the_floor_and_the_ga_with_pinv_meets_it(tmp_path):
    base = ["problem=multipose", "problem.n_poses=15", "problem.n_validation=10"]
    lm = app.run(_cfg(*base, "algorithm=lm"), tmp_path / "lm")
    ga = app.run(_cfg(*base, "population.generations=10"), tmp_path / "ga")
    assert ga["final_cost"] <= 1.01 * lm["final_cost"]


@pytest.mark.parametrize(
    "override, message",
    [("crossover.prob=1.5", r"crossover.prob: probability 1.5 is outside \[0, 1\]"),
     ("population.mu=0", "population.mu: must be at least 1"),
     ("refine.share=-0.1", "refine.share"),
     ("problem.cost=quadratic", "problem.cost: unknown cost 'quadratic'")],
)
def test_bad_settings_stop_before_any_generation(tmp_path, override, message):
    with pytest.raises(build.ConfigError, match=message):
        app.run(_cfg(override), tmp_path)
    assert not (tmp_path / "convergence.csv").exists()


def test_unknown_operator_fails_at_composition():
    with pytest.raises((MissingConfigException, ConfigCompositionException), match="crossover"):
        _cfg("crossover=teleport")


def test_one_pose_warns_with_the_identifiability_report(tmp_path, caplog):
    app.run(_cfg("problem.n_validation=5", "population.generations=1"), tmp_path)
    assert "cannot identify every parameter" in caplog.text and "rank 12 of 31" in caplog.text
    caplog.clear()
    app.run(_cfg("problem=multipose", "problem.n_validation=5", "population.generations=1"), tmp_path / "b")
    assert "cannot identify" not in caplog.text  # 30 poses carry all the model can identify


def test_command_line_error_is_one_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.app", "crossover.prob=1.5", f"hydra.run.dir={tmp_path}"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "zrp-ga: error: crossover.prob: probability 1.5 is outside [0, 1]" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("family", ["inversion", "rotation"])
def test_configured_segment_operators_cross_blocks_and_block_ones_do_not(family):
    cfg = _cfg(f"{family}=segment")
    prob, _ = build.problem(cfg.problem, build.robot(cfg.robot), 0)
    rng = np.random.default_rng(0)
    alias = "invert" if family == "inversion" else "rotate"
    for choice, crosses in (("segment", True), ("block", False)):
        tb = build.toolbox(_cfg(f"{family}={choice}"), prob, rng)
        G = np.hstack([np.zeros((500, 18)), np.ones((500, 18))])
        getattr(tb, alias)(G)
        assert bool(np.any(G[:, :18] == 1)) is crosses


def test_the_optimiser_never_starts_from_the_truth(tmp_path):
    app.run(_cfg("problem.n_validation=5", "population.generations=1"), tmp_path)
    init = pd.read_csv(tmp_path / "initial_population.csv").drop(columns=["individual", "cost"]).to_numpy()
    cfg = _cfg()
    _, sim = build.problem(cfg.problem, build.robot(cfg.robot), 0)
    assert np.min(np.abs(init[:, :, None] - sim.true_de[None, None, :])) > 1e-12  # no gene equals a true error


def test_unknown_operator_parameter_is_refused_by_name(tmp_path):
    with pytest.raises(build.ConfigError, match=r"crossover.op: .*unknown parameter 'etaa' for zrp_ga.operators.crossover.sbx \(takes: low, up, eta, indpb\)"):
        app.run(_cfg("crossover=sbx", "+crossover.op.etaa=3"), tmp_path)
