"""Resume continues the checkpoint it is given, or refuses: a changed robot or data file since
the checkpoint, a second run into a directory in use; and a resumed run continues from the
checkpoint's state (a changed population or random state shows in the resumed curve, which a
run started over could not reproduce)."""

import shutil

import numpy as np
import pandas as pd
import pytest

from zrp_ga import config
from zrp_ga.core.schema import ConfigError
from zrp_ga.run import callbacks, checkpoint, directory, execute
from zrp_ga.run.build import prepare
from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS

FAST = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "refine=none", "population.mu=20",
        "population.lambda_=20", "seed=4", "progress=false"]  # fmt: skip
CUT = 6  # the generation after which the runs below are interrupted


def _csv(path):
    return pd.read_csv(path / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)


def _interrupted(cfg, out, monkeypatch):
    """Run ``cfg`` into ``out`` and press Ctrl-C after generation CUT (its checkpoint saved)."""
    write = callbacks.ConvergenceLog.on_generation

    def ctrl_c(self, algorithm, row):
        write(self, algorithm, row)
        if row["gen"] == CUT:
            raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(callbacks.ConvergenceLog, "on_generation", ctrl_c)
        with pytest.raises(KeyboardInterrupt):
            execute.run(cfg, out)
    return out


@pytest.fixture
def arm_file(tmp_path):
    from zrp_ga import robots

    path = tmp_path / "arm.yaml"
    shutil.copy(robots.path("puma560"), path)
    return path


def test_resume_refuses_a_robot_file_changed_since_the_checkpoint(tmp_path, arm_file, monkeypatch):
    cfg = config.load([*FAST, "robot=file", f"robot.file={arm_file}", "population.generations=12", "checkpoint_every=3"])
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    before = (out / "convergence.csv").read_text()
    arm_file.write_text(arm_file.read_text().replace("a: 0.4318, alpha: 0", "a: 0.5000, alpha: 0"))
    with pytest.raises(ConfigError, match=r"resume: the robot changed since the checkpoint in .*cut"):
        execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    assert (out / "convergence.csv").read_text() == before  # nothing appended from another arm


def test_resume_refuses_a_data_file_changed_since_the_checkpoint(tmp_path, monkeypatch):
    """A checkpoint records the hash of the data files' contents: one whose recorded hash is
    not that of the file now (as after the file was edited) is refused, naming the key and file."""
    cfg = config.load([*FAST, "population.generations=12", "checkpoint_every=3"])
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    state = checkpoint.load(out / directory.CHECKPOINT)
    assert set(state["inputs"]) == {"robot"}  # a simulated problem reads no data file
    state["inputs"]["problem.calibration_file"] = "0" * 64
    checkpoint.save(out / directory.CHECKPOINT, state)
    with pytest.raises(ConfigError, match=r"resume: problem.calibration_file \(None\) changed since the checkpoint"):
        execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")


def test_resume_refuses_a_checkpoint_config_the_schema_refuses(tmp_path, monkeypatch):
    cfg = config.load([*FAST, "population.generations=12", "checkpoint_every=3"])
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    state = checkpoint.load(out / directory.CHECKPOINT)
    state["config"]["checkpoint_every"] = "often"
    checkpoint.save(out / directory.CHECKPOINT, state)
    with pytest.raises(ConfigError, match=r"checkpoint.npz: its config was edited since it was written \(checkpoint_every changed\)"):
        execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    state.pop("config_digests")  # a checkpoint written before the digests: the schema's check
    checkpoint.save(out / directory.CHECKPOINT, state)
    with pytest.raises(ConfigError, match=r"resume: the checkpoint's config is not valid at checkpoint_every"):
        execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")


@pytest.mark.parametrize("how", ["numpy", "checkpoint module"])
def test_resume_refuses_a_checkpoint_whose_config_was_edited_naming_the_settings(tmp_path, monkeypatch, how):
    """Settings that change the run edited in the checkpoint's config (the population, the
    problem, the budget), as a user would with numpy or with zrp_ga's own reader and writer:
    refused with one line naming them, nothing written; not resumed with the old population
    under a summary of the new settings. The same checkpoint unedited resumes."""
    cfg = config.load([*FAST, "population.generations=9", "checkpoint_every=2"])
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    path = out / directory.CHECKPOINT
    original = path.read_bytes()
    if how == "numpy":
        import json

        arrays = dict(np.load(path, allow_pickle=False))
        text = json.loads(str(arrays["__json__"]))
        text["config"]["population"]["mu"] += 10
        text["config"]["population"]["generations"] = 20
        arrays["__json__"] = np.array(json.dumps(text))
        np.savez(path.with_suffix(""), **arrays)  # numpy adds .npz
    else:
        state = checkpoint.load(path)
        state["config"]["population"]["mu"] += 10
        state["config"]["population"]["generations"] = 20
        checkpoint.save(path, state)
    files = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    with pytest.raises(ConfigError) as refused:
        execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    assert str(refused.value) == (f"{path}: its config was edited since it was written (population.mu, population.generations "
                                  "changed); a run continues with the settings it started with: put them back, or start a new run")  # fmt: skip
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == files
    path.write_bytes(original)
    execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    assert _csv(out)["gen"].max() == 9 and directory.read_summary(out)["config"]["population"]["generations"] == 9


def test_resume_applies_the_checkpoints_config(tmp_path, monkeypatch):
    """The resumed run runs the checkpoint's config, not the command line's defaults: its
    generations, and its summary.json records what ran."""
    cfg = config.load([*FAST, "population.generations=9", "checkpoint_every=2"])
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    assert _csv(out)["gen"].max() == 9
    assert directory.read_summary(out)["config"]["population"]["generations"] == 9


def test_a_resumed_run_continues_from_a_changed_population(tmp_path, monkeypatch):
    """Every genome of the checkpoint's population replaced by the true one (known in
    simulation): the first resumed generation reports the truth's cost or less (the GA keeps its
    best), far below what the uninterrupted run reaches then. A run started over could not."""
    cfg = config.load([*FAST, "population.generations=10", "checkpoint_every=2"])
    execute.run(cfg, tmp_path / "whole")
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    task = prepare(cfg, None).task
    truth = task.problem.layout.restrict(np.asarray(task.truth, dtype=float))  # the genome nearest to the true arm
    cost = float(task.problem.costs(truth[None])[0])
    state = checkpoint.load(out / directory.CHECKPOINT)
    cut = int(state["gen"])  # the last generation the interrupt's checkpoint holds
    state["pop"] = np.repeat(truth[None], len(state["pop"]), axis=0)
    state["costs"] = np.full(len(state["pop"]), cost)
    checkpoint.save(out / directory.CHECKPOINT, state)
    execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    resumed, whole = _csv(out), _csv(tmp_path / "whole")
    pd.testing.assert_frame_equal(resumed[resumed.gen <= cut], whole[whole.gen <= cut])
    after = resumed[resumed.gen == cut + 1]["best"].iloc[0]
    assert after <= cost * (1 + 1e-12)
    assert after < 0.2 * whole[whole.gen == cut + 1]["best"].iloc[0]


def test_a_resumed_run_continues_from_the_checkpoints_random_state(tmp_path, monkeypatch):
    """The checkpoint's random state replaced by another seed's: the resumed generations differ
    from the uninterrupted run's (which a run started over would reproduce exactly)."""
    cfg = config.load([*FAST, "population.generations=10", "checkpoint_every=2"])
    execute.run(cfg, tmp_path / "whole")
    out = _interrupted(cfg, tmp_path / "cut", monkeypatch)
    state = checkpoint.load(out / directory.CHECKPOINT)
    cut = int(state["gen"])
    state["rng"] = np.random.default_rng(12345).bit_generator.state
    checkpoint.save(out / directory.CHECKPOINT, state)
    execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    resumed, whole = _csv(out), _csv(tmp_path / "whole")
    pd.testing.assert_frame_equal(resumed[resumed.gen <= cut], whole[whole.gen <= cut])
    assert not np.array_equal(resumed[resumed.gen > cut]["mean"], whole[whole.gen > cut]["mean"])
