"""A run's files sized to their use (``outputs``): a sweep's runs write what a study reads and
no robot files nor a finished run's checkpoint (``outputs=auto`` in a sweep, or ``study``); a
single run writes every file (``auto`` alone, or ``full``), and so does a sweep's run with
``outputs=full``. What is written changes no result: the convergence rows and summaries of a
study's runs are those of the same runs written in full. (A sweep through the command line,
with Hydra's records and the report on it: tests/test_sweeps.py.)"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from zrp_ga import config
from zrp_ga.run import directory, execute
from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import Cache
from zrp_ga.run.sweep import SweepJob, sweep_batch, sweep_job

FAST = ["problem=multipose", "problem.n_poses=8", "problem.n_validation=6", "refine=none", "population.mu=8",
        "population.lambda_=8", "population.generations=7", "checkpoint_every=2", "progress=false"]  # fmt: skip

# What a study's run holds (the run layer's files; the command line adds .hydra/ and zrp-ga.log)
STUDY = {".zrp_ga.lock", "best_params.csv", "convergence.csv", "initial_population.csv", "status.json", "summary.json"}
# ... and what a full run adds: the robot files (written by hand here, not from the code), the
# uncertainty and coverage, the final checkpoint
ROBOT = {"calibrated_robot.urdf", "calibrated_robot.yaml", "calibrated_robot_dh.yaml", "calibrated_robot_mdh.yaml",
         "calibrated_robot_dh_corrections.csv", "calibrated_robot_mdh_corrections.csv", "calibrated_robot_frames.yaml"}  # fmt: skip
FULL = STUDY | ROBOT | {"uncertainty.json", "coverage.json", "checkpoint.npz"}


def _files(run: Path) -> set[str]:
    return {str(p.relative_to(run)) for p in run.rglob("*") if p.is_file()}


def _rows(run: Path) -> list[dict]:
    with open(run / directory.CONVERGENCE, newline="") as f:
        return [{k: v for k, v in row.items() if k not in WALL_CLOCK_COLUMNS} for row in csv.DictReader(f)]


def _result(run: Path) -> tuple:
    s = json.loads((run / directory.SUMMARY).read_text())
    return s["final_cost"], s["best_genome"], s["validation_rms_mm"], s["nevals"]


def _jobs(where: Path, seeds: list[int], extra: tuple[str, ...] = ()) -> list[SweepJob]:
    return [SweepJob(config.load([*FAST, f"seed={k}", *extra]), where / str(k), Sweep(where, k, (f"seed={k}", *extra), str(k)))
            for k in seeds]  # fmt: skip


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """The same two seeds as a study's sweep (evolved together and alone), as a sweep with
    outputs=full, as single runs (outputs=auto and outputs=study)."""
    base, cache = tmp_path_factory.mktemp("outputs"), Cache()
    sweep_batch(_jobs(base / "together", [0, 1]), cache)
    for job in _jobs(base / "alone", [0, 1]):
        sweep_job(job, cache)
    sweep_batch(_jobs(base / "full", [0, 1], ("outputs=full",)), cache)
    for k in (0, 1):
        execute.run(config.load([*FAST, f"seed={k}"]), base / "single" / str(k))
        execute.run(config.load([*FAST, f"seed={k}", "outputs=study"]), base / "single_study" / str(k))
    return {name: base / name for name in ("together", "alone", "full", "single", "single_study")}


def test_a_sweeps_runs_write_what_a_study_reads_only(runs):
    for name in ("together", "alone"):
        for k in (0, 1):
            assert _files(runs[name] / str(k)) == STUDY, (name, k)
            assert directory.status(runs[name] / str(k)) == "done"
            assert "calibrated_robot" not in json.loads((runs[name] / str(k) / directory.SUMMARY).read_text())


def test_a_single_run_and_a_full_sweep_write_every_file(runs):
    for name in ("single", "full"):
        for k in (0, 1):
            assert _files(runs[name] / str(k)) == FULL, (name, k)
    assert all(_files(runs["single_study"] / str(k)) == STUDY for k in (0, 1))


def test_what_is_written_changes_no_result(runs):
    for name in ("together", "alone", "full", "single_study"):
        for k in (0, 1):
            assert _rows(runs[name] / str(k)) == _rows(runs["single"] / str(k)), (name, k)
            assert _result(runs[name] / str(k)) == _result(runs["single"] / str(k)), (name, k)


def test_a_study_sweep_run_again_keeps_its_finished_runs(runs, tmp_path):
    """A study's finished runs have no checkpoint: the sweep run again keeps them (their summary
    and convergence say they are done), runs nothing again, writes no file more."""
    import shutil

    sweep = tmp_path / "again"
    shutil.copytree(runs["together"], sweep)
    before = {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file() and p.name != directory.MANIFEST}
    assert sweep_batch(_jobs(sweep, [0, 1]), Cache()) == [_result(sweep / str(k))[0] for k in (0, 1)]
    assert {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file() and p.name != directory.MANIFEST} == before
    # outputs is no setting of the run (it changes no result): the same runs asked with outputs=full are them, kept
    assert sweep_batch(_jobs(sweep, [0, 1], ("outputs=full",)), Cache()) == [_result(sweep / str(k))[0] for k in (0, 1)]
    assert {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file() and p.name != directory.MANIFEST} == before


def test_a_study_run_continued_from_its_checkpoint_removes_it_at_the_end(runs, tmp_path):
    """A study's run killed after a checkpoint (here: a full run's checkpoint after generation 4
    put in place, its rows cut there) continues from it and removes it when done, its rows those
    of the run uninterrupted."""
    from zrp_ga.run import checkpoint

    job = _jobs(tmp_path, [0])[0]
    cut = tmp_path / "cut"
    execute.run(config.load([*FAST, "seed=0", "population.generations=4"]), cut)  # the same run's first 4 generations
    out = tmp_path / "0"
    out.mkdir()
    state = checkpoint.load(cut / directory.CHECKPOINT)
    state["config"] = json.loads((runs["single"] / "0" / directory.SUMMARY).read_text())["config"]
    state.pop("config_digests")
    checkpoint.save(out / directory.CHECKPOINT, state)
    (out / directory.CONVERGENCE).write_bytes((cut / directory.CONVERGENCE).read_bytes())
    directory.write_status(out, "interrupted")
    sweep_job(job, Cache())
    assert _files(out) == STUDY
    assert _rows(out) == _rows(runs["single"] / "0")


def test_loading_a_study_run_says_how_to_get_its_files(runs):
    """zrp_ga.load on a run without robot files because of outputs=study: one line naming the
    setting and the command that writes them (the job's overrides from the sweep's manifest)."""
    import zrp_ga

    with pytest.raises(ValueError) as e:
        zrp_ga.load(runs["alone"] / "0")  # a sweep's job, outputs=auto
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{runs['alone'] / '0'}: written with outputs=auto, which is outputs=study in a sweep")
    assert msg.endswith("run `zrp-ga seed=0` alone, or the sweep with outputs=full")
    with pytest.raises(ValueError, match=r"written with outputs=study .*run it again with outputs=full"):
        zrp_ga.load(runs["single_study"] / "1")
    with pytest.raises(ValueError, match=r"a sweep directory\? give one of its jobs"):
        zrp_ga.load(runs["alone"])
    assert zrp_ga.load(runs["full"] / "1").summary["config"]["outputs"] == "full"  # the same sweep in full loads


def test_loading_a_made_up_study_run_reads_its_setting_and_overrides(tmp_path):
    import yaml

    import zrp_ga

    def run(name: str, summary: dict | None, hydra_config: dict | None = None, overrides: list | None = None) -> Path:
        d = tmp_path / name
        (d / ".hydra").mkdir(parents=True)
        if summary is not None:
            (d / directory.SUMMARY).write_text(json.dumps(summary))
        if hydra_config is not None:
            (d / ".hydra" / "config.yaml").write_text(yaml.safe_dump(hydra_config))
        if overrides is not None:
            (d / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
        return d

    over = ["algorithm=lm", "seed=3", "outputs=study", "problem.name=a b"]
    with pytest.raises(ValueError, match=r"written with outputs=study .*run `zrp-ga algorithm=lm seed=3 'problem.name=a b'` alone"):
        zrp_ga.load(run("study", {"config": {"outputs": "study"}}, overrides=over))
    with pytest.raises(ValueError, match=r"written with outputs=study .*run `zrp-ga seed=3` alone"):
        zrp_ga.load(run("hydra_only", None, {"outputs": "study"}, ["seed=3"]))  # no summary: Hydra's record
    for name, summary, conf in (("full", {"config": {"outputs": "full"}}, None), ("auto_hydra", None, {"outputs": "auto"}),
                                ("written", {"config": {"outputs": "study"}, "calibrated_robot": {}}, None)):  # fmt: skip
        with pytest.raises(ValueError, match=r"not a calibration run directory \(no calibrated_robot.yaml\)$"):
            zrp_ga.load(run(name, summary, conf))


def test_resuming_a_finished_study_run_says_it_is_finished(runs):
    """resume= on a sweep's finished run (no checkpoint kept): one line saying so, not 'no
    checkpoint there'; the command line's path (build.prepare with resume=)."""
    from zrp_ga.core.schema import ConfigError
    from zrp_ga.run import build

    run = runs["alone"] / "0"
    with pytest.raises(ConfigError, match=r"^resume: .* is a finished run written without its final checkpoint .*"
                                          r"nothing to continue; its results are in .*summary\.json$"):  # fmt: skip
        build.prepare(config.load([f"resume={run}"]), None, overrides=[f"resume={run}"])
