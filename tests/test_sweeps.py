"""zrp_ga's launcher and sweeps that survive their own death.

- Job configs composed by ``hydra_plugins.zrp_ga_launcher._compose`` against Hydra's own
  composition of the same job: YAML text, and every node's type, key and flags.
- A sweep on the launcher's workers against the same sweep on Hydra's basic launcher: every
  file a run writes (wall-clock figures aside), the ``.hydra`` records, the manifest.
- Sweeps killed (SIGKILL to every process, as a reboot; SIGINT, as Ctrl-C; SIGTERM, as a job
  limit) at seeded random moments and started again with the same command, against the same
  sweep run uninterrupted:
  every run's convergence.csv (wall-clock columns aside), the manifest's states, and the
  runs ``zrp_ga.report.find_runs`` sees.
"""

from __future__ import annotations

import itertools
import json
import os
import pickle
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from omegaconf import DictConfig, ListConfig, OmegaConf

from zrp_ga.run import directory, execute
from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS
from zrp_ga.run.directory import read_manifest


# --- composition ------------------------------------------------------------------------------------
def _nodes(node, path="") -> list[tuple]:
    """Every node of a config: path, node class, key, reference and object type, own flags."""
    meta = node._metadata
    out = [(path, type(node).__name__, meta.key, str(meta.ref_type), str(getattr(meta, "object_type", None)),
            sorted(meta.flags.items()))]  # fmt: skip
    if isinstance(node, DictConfig) and not (node._is_missing() or node._is_none()):
        for k in node.keys():
            out += _nodes(node._get_node(k), f"{path}.{k}")
    elif isinstance(node, ListConfig) and not (node._is_missing() or node._is_none()):
        for i in range(len(node)):
            out += _nodes(node._get_node(i), f"{path}[{i}]")
    return out


@pytest.fixture
def hydra_loader():
    """Hydra's config loader, initialised for one test (a longer-lived one would leave Hydra
    initialised for the tests after it, which then cannot load configs)."""
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    from zrp_ga import config

    with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
        yield GlobalHydra.instance().hydra.config_loader


def _compare_with_hydra(loader, master_overrides: list[str], jobs: list[list[str]], prefetch: bool = True,
                        hydras: dict | None = None) -> int:  # fmt: skip
    """Compose ``jobs`` with the cached loader and with Hydra's; assert equal; Hydra's count
    (``prefetch``: the variants of the sweep's options composed ahead, in forked processes).
    ``hydras``: Hydra's own compositions kept by job, for another call on the same jobs."""
    from hydra.types import RunMode

    from hydra_plugins.zrp_ga_launcher._compose import ComposingLoader

    master = loader.load_configuration("config", master_overrides + ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    cached = ComposingLoader(loader, prefetch=prefetch)
    hydras = {} if hydras is None else hydras
    for job in jobs:
        ours = cached.load_sweep_config(master, job)
        if tuple(job) not in hydras:
            theirs = loader.load_sweep_config(master, job)
            hydras[tuple(job)] = (OmegaConf.to_yaml(theirs), _nodes(theirs))
        assert (OmegaConf.to_yaml(ours), _nodes(ours)) == hydras[tuple(job)], job
    return cached.hydra_compositions


def test_cached_compositions_equal_hydras_own(hydra_loader):
    """Values, options of groups with schemas and nested defaults (problem, algorithm), an
    experiment writing into a swept group's package, values of two types for one key."""
    # A job's overrides hold the sweep's own (experiment=...): hydra-core 1.4 refuses a job whose
    # experiment changes hydra.sweeper from the sweep's, as a sweep on the command line never does.
    jobs = [[f"problem={p}", f"crossover={c}", f"mutation={m}", f"seed={s}", "experiment=methods_ga"]
            for p, c, m, s in [("paper", "one_point", "polynomial", 0), ("paper", "one_point", "polynomial", 1),
                               ("multipose", "sbx", "gaussian", 2), ("paper", "sbx", "polynomial", 3)]]  # fmt: skip
    # Hydra's compositions: the first job, its three groups changed one at a time (the fourth job
    # needs none of its own): 4 for 4 jobs, but not one per job.
    assert _compare_with_hydra(hydra_loader, ["experiment=methods_ga"], jobs) == 1 + 3
    jobs = [["algorithm=cmaes", "problem.seed=null"], ["algorithm=lm", "problem.seed=3"], ["algorithm=lm", "problem.seed=null"]]
    # the first job, lm as a group changed, and lm again with the other type of value for
    # problem.seed (null or an int): a new shape is Hydra's composition.
    assert _compare_with_hydra(hydra_loader, [], jobs) == 1 + 1 + 1


def test_options_that_write_outside_their_package_are_composed_by_hydra(hydra_loader):
    """An experiment and a suite instance are ``_global_`` packages: each of their options is
    Hydra's composition (options that leave hydra.sweeper alone: hydra-core 1.4 refuses a swept
    option that changes it)."""
    jobs = [[o, f"seed={s}"] for o in ("experiment=paper_case", "instance=stanford_30poses") for s in (0, 1)]
    assert _compare_with_hydra(hydra_loader, [], jobs) == 2


def test_configs_pickled_for_the_workers_equal_hydras_own(hydra_loader):
    """``ComposingLoader.pickled_config`` of jobs not kept from the sweeper's check (one config
    per composition, each job's values set in it before it is pickled): every job's config,
    unpickled, is Hydra's own composition of the job (YAML and nodes), in any order of values,
    with values of two types for one key, and after a value that fails."""
    from hydra.errors import ConfigCompositionException
    from hydra.types import RunMode

    from hydra_plugins.zrp_ga_launcher._compose import ComposingLoader

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    cached = ComposingLoader(hydra_loader, prefetch=False)
    jobs = [[f"crossover={c}", f"seed={s}", f"crossover.prob={p}"] for c, s, p in
            [("sbx", 3, 0.5), ("sbx", 0, 0.9), ("blend", 7, 0.5), ("sbx", 3, 0.7), ("blend", 1, 1.0), ("sbx", 5, 1)]]  # fmt: skip
    jobs += [["algorithm=lm", "problem.seed=3"], ["algorithm=lm", "problem.seed=null"], ["algorithm=lm", "problem.seed=4"]]
    with pytest.raises(ConfigCompositionException):  # a value that fails, half way through a job's values
        cached.pickled_config(master, ["crossover=sbx", "seed=2", "crossover.prob=high"])
    for job in [*jobs, *jobs[::-1]]:
        ours, theirs = pickle.loads(cached.pickled_config(master, job)), hydra_loader.load_sweep_config(master, job)
        assert (OmegaConf.to_yaml(ours), _nodes(ours)) == (OmegaConf.to_yaml(theirs), _nodes(theirs)), job


@pytest.mark.slow
def test_cached_compositions_of_the_whole_operator_grid_equal_hydras_own(hydra_loader):
    grid = itertools.product(["one_point", "two_point", "blend", "sbx"], ["gaussian", "polynomial", "uniform_reset"],
                             ["none", "segment"], ["none", "segment"], range(3))  # fmt: skip
    jobs = [[f"crossover={c}", f"mutation={m}", f"inversion={i}", f"rotation={r}", f"seed={s}", "experiment=operator_grid"]
            for c, m, i, r, s in grid]  # fmt: skip
    assert _compare_with_hydra(hydra_loader, ["experiment=operator_grid"], jobs) == 8


# --- sweeps on the launcher -------------------------------------------------------------------------
SMALL = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "refine=none", "population.mu=30",
         "population.lambda_=30"]  # fmt: skip


def _zrp_ga(*args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args], capture_output=True, text=True, **kw)


def _runs(sweep: Path) -> dict[str, pd.DataFrame]:
    """Each job's convergence.csv without the wall-clock columns, by overrides."""
    m = read_manifest(sweep)
    return {o: pd.read_csv(sweep / str(d) / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS)
            for o, d in zip(m["overrides"], m["dir"])}  # fmt: skip


def _summary(run: Path) -> dict:
    s = json.loads((run / "summary.json").read_text())
    for key in ("wall_s", "versions"):
        s.pop(key)
    s["choices"].pop("hydra/launcher")
    return s


ARGS = ["-m", "seed=0,1", "crossover=sbx,blend", *SMALL, "population.generations=8", "checkpoint_every=3"]
OURS = ["hydra/launcher=zrp_ga", "hydra.launcher.n_jobs=2"]


@pytest.fixture(scope="module")
def ours(tmp_path_factory) -> Path:
    sweep = tmp_path_factory.mktemp("ours")
    proc = _zrp_ga(*ARGS, *OURS, f"hydra.sweep.dir={sweep}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return sweep


def test_launcher_writes_what_hydras_basic_launcher_writes(tmp_path, ours):
    basic = _zrp_ga(*ARGS, f"hydra.sweep.dir={tmp_path / 'basic'}")
    assert basic.returncode == 0, basic.stderr[-2000:]
    mb, mo = read_manifest(tmp_path / "basic"), read_manifest(ours)
    assert list(mo["status"]) == ["done"] * 4
    pd.testing.assert_frame_equal(mb.drop(columns="time"), mo.drop(columns="time"))
    assert pd.read_csv(ours / "manifest.csv")["status"].tolist() == ["done"] * 4
    for d in mo["dir"]:
        b, o = tmp_path / "basic" / str(d), ours / str(d)
        for name in ("convergence.csv",):
            pd.testing.assert_frame_equal(pd.read_csv(o / name).drop(columns=WALL_CLOCK_COLUMNS),
                                          pd.read_csv(b / name).drop(columns=WALL_CLOCK_COLUMNS))  # fmt: skip
        for name in ("best_params.csv", "initial_population.csv", ".hydra/config.yaml", ".hydra/overrides.yaml"):
            assert (o / name).read_text() == (b / name).read_text(), name
        assert _summary(o) == _summary(b)
        hb, ho = (OmegaConf.load(x / ".hydra/hydra.yaml").hydra for x in (b, o))
        for h in (hb, ho):  # what differs by design: the launcher and the sweep directory
            h.launcher, h.sweep.dir, h.runtime.output_dir, h.overrides.hydra = None, None, None, None
            h.runtime.choices.pop("hydra/launcher")
        assert OmegaConf.to_yaml(ho) == OmegaConf.to_yaml(hb)
        assert (o / "zrp-ga.log").read_text().count("job ") == 1
        assert {str(p.relative_to(b)) for p in b.rglob("*") if p.is_file()} == STUDY_FILES  # Hydra's basic launcher: a study's too
        assert _log_lines(o) == _log_lines(b)  # each job's own lines, in its own file (runs of a batch evolved together)


# What a sweep's run holds (outputs=auto: what a study reads; tests/test_outputs.py for the rest)
STUDY_FILES = {".hydra/config.yaml", ".hydra/hydra.yaml", ".hydra/overrides.yaml", ".zrp_ga.lock", "zrp-ga.log",
               "best_params.csv", "convergence.csv", "initial_population.csv", "status.json", "summary.json"}  # fmt: skip


def test_a_sweeps_runs_hold_what_a_study_reads_and_the_report_reads_them(tmp_path, ours):
    from zrp_ga.report import write_report

    for d in read_manifest(ours)["dir"]:
        assert {str(p.relative_to(ours / str(d))) for p in (ours / str(d)).rglob("*") if p.is_file()} == STUDY_FILES
    t = write_report([ours], tmp_path / "report", formats=())
    assert len(t["runs"]) == 4 and not len(t["left_out"]) and not t["notes"]
    assert (tmp_path / "report" / "table2_initial_population.md").exists() and (tmp_path / "report" / "table3_best_params.md").exists()


def _log_lines(run: Path) -> list[str]:
    """A job's log file without the time stamps and the figures that are timings."""
    import re

    text = (run / "zrp-ga.log").read_text()
    return [re.sub(r"\d+\.\d s$", "", line.split("]", 1)[-1]) for line in text.splitlines()]


def test_sweep_jobs_equal_single_runs_built_afresh(tmp_path, ours):
    """A sweep's workers reuse problem instances and their diagnostics (kept beside the sweep):
    each job's files against a single run of its config, built from nothing in this process."""
    from zrp_ga import config

    m = read_manifest(ours)
    for overrides, d in zip(m["overrides"], m["dir"]):
        single = tmp_path / str(d)
        execute.run(config.load(overrides.split()), single)
        pd.testing.assert_frame_equal(pd.read_csv(ours / str(d) / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS),
                                      pd.read_csv(single / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS))  # fmt: skip
        swept, alone = (json.loads((x / "summary.json").read_text()) for x in (ours / str(d), single))
        assert swept["identifiability"] == alone["identifiability"] and swept["best_genome"] == alone["best_genome"]
    assert len(list((ours / ".zrp_ga").glob("diagnostics-*.json"))) == 2  # one per problem instance (seed)


def test_warm_up_builds_the_base_instance_and_writes_nothing(tmp_path, monkeypatch):
    from zrp_ga import config
    from zrp_ga.run import execute
    from zrp_ga.run.shared import Cache

    monkeypatch.chdir(tmp_path)
    cache = Cache()
    execute.warm_up(config.load(SMALL + ["seed=5"]), cache)
    assert [json.loads(k)["seed"] for k in cache.instances] == [5]
    assert not list(tmp_path.iterdir())


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_a_sweep_run_again_keeps_its_finished_jobs_and_refuses_another_config(tmp_path, ours):
    sweep = tmp_path / "sweep"
    shutil.copytree(ours, sweep)
    args = [*ARGS, *OURS, f"hydra.sweep.dir={sweep}"]
    before = {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")}
    again = _zrp_ga(*args)
    assert again.returncode == 0, again.stderr[-2000:]
    assert {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")} == before  # kept, not run again
    assert (again.stdout + again.stderr).count("finished before; kept") == 4
    manifest = (sweep / "manifest.jsonl").read_bytes()
    other = _zrp_ga(*args[:-1], "population.generations=6", args[-1])  # another sweep: refused at its start
    assert other.returncode == 2 and other.stderr.strip().splitlines() == [
        f"zrp-ga: error: {sweep} holds another sweep (population.generations=6 here, population.generations=8 there); "
        "run this one into another hydra.sweep.dir, or continue that one with its own command"], other.stderr  # fmt: skip
    assert (sweep / "manifest.jsonl").read_bytes() == manifest
    assert {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")} == before
    # a sweep folder from before the record: each job refuses a run of another config, as it did
    (sweep / directory.SHARED / directory.SWEEP_RECORD).unlink()
    other = _zrp_ga(*args[:-1], "population.generations=6", args[-1])
    assert other.returncode != 0
    m = read_manifest(sweep)
    assert list(m["status"]) == ["failed"] * 4
    assert "holds a run of another config (population.generations differs)" in m.loc[0, "error"]
    assert {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")} == before


def test_manifest_survives_a_line_cut_by_a_crash(tmp_path):
    (tmp_path / "manifest.jsonl").write_text('{"job": 0, "status": "done", "dir": "0"}\n{"job": 1, "sta')
    directory.repair(tmp_path)
    directory.record(directory.Sweep(tmp_path, 2, (), "2"), "done")
    assert [s["job"] for s in directory.job_states(tmp_path)] == [0, 2]


# --- killed and started again -----------------------------------------------------------------------
# Two problem instances (seeds), two jobs on each: two batches whose runs are evolved together,
# one per worker; the sweep they are compared with runs its jobs one at a time.
KILLABLE = ["-m", "seed=0,1", "crossover=sbx,blend", *SMALL, "population.generations=150", "checkpoint_every=2",
            "hydra/launcher=zrp_ga", "hydra.launcher.n_jobs=2"]  # fmt: skip
N_KILLABLE = 4


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    sweep = tmp_path_factory.mktemp("whole")
    proc = _zrp_ga(*KILLABLE, "hydra.launcher.lockstep=false", f"hydra.sweep.dir={sweep}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return sweep


def _kill_at_random(sweep: Path, sig: int, rng: random.Random) -> subprocess.Popen:
    """Start the sweep and send ``sig`` to all its processes (its own session) once a random
    number of generations has been logged over its jobs, plus a random delay."""
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *KILLABLE, f"hydra.sweep.dir={sweep}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)  # fmt: skip
    target, deadline = rng.randrange(1, N_KILLABLE * 151), time.time() + 120
    while proc.poll() is None and time.time() < deadline:
        if sum(p.read_bytes().count(b"\n") - 1 for p in sweep.glob("*/convergence.csv")) >= target:
            break
        time.sleep(0.002)
    time.sleep(rng.uniform(0, 0.05))
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
    proc.wait(timeout=120)
    return proc


def _check_same_as(sweep: Path, whole: Path) -> None:
    from zrp_ga import report

    ours, theirs = _runs(sweep), _runs(whole)
    assert sorted(ours) == sorted(theirs)
    for overrides, frame in theirs.items():
        pd.testing.assert_frame_equal(ours[overrides], frame, obj=overrides)
    m, w = read_manifest(sweep), read_manifest(whole)
    pd.testing.assert_frame_equal(m[["job", "overrides", "dir", "status"]], w[["job", "overrides", "dir", "status"]])
    assert pd.read_csv(sweep / "manifest.csv")["status"].tolist() == ["done"] * len(w)
    runs, skipped = report.find_runs([sweep])
    assert len(runs) == len(w) and not skipped
    assert not list(sweep.glob("*/checkpoint.npz"))  # a study's finished runs keep none (outputs=auto in a sweep)


def _kill_and_continue(tmp_path: Path, whole: Path, sig: int, seed: int) -> None:
    sweep = tmp_path / f"cut-{seed}"
    proc = _kill_at_random(sweep, sig, random.Random(seed))
    assert proc.returncode != 0, "the sweep ended before it was interrupted"
    if sig != signal.SIGKILL:  # Ctrl-C, or a job limit's SIGTERM: a one-line hint, no traceback
        err = proc.stderr.read().decode()
        assert proc.returncode == 130 and "continue with the same command" in err and "Traceback" not in err, err
    again = _zrp_ga(*KILLABLE, f"hydra.sweep.dir={sweep}")
    assert again.returncode == 0, again.stderr[-3000:]
    _check_same_as(sweep, whole)


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_a_killed_sweep_started_again_ends_as_an_uninterrupted_one(tmp_path, uninterrupted):
    _kill_and_continue(tmp_path, uninterrupted, signal.SIGKILL, seed=1)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT, signal.SIGTERM], ids=["SIGKILL", "SIGINT", "SIGTERM"])
def test_sweeps_killed_at_random_moments_end_as_an_uninterrupted_one(tmp_path, uninterrupted, sig, seed):
    _kill_and_continue(tmp_path, uninterrupted, sig, seed)


@pytest.mark.slow
def test_a_worker_that_dies_fails_its_jobs_and_the_sweep_goes_on(tmp_path, uninterrupted):
    """One worker process killed mid-batch (as by the out-of-memory killer): its jobs are failed
    and recorded (manifest and status files), another worker runs the rest, the sweep ends with
    one line naming a lost job; the same command then completes the sweep."""
    sweep = tmp_path / "sweep"
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *KILLABLE, f"hydra.sweep.dir={sweep}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip
    deadline = time.time() + 120
    while time.time() < deadline and not any(p.stat().st_size > 2000 for p in sweep.glob("*/convergence.csv")):
        time.sleep(0.01)
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
    os.kill(int(children[0]), signal.SIGKILL)
    try:
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 2, err  # Hydra's sweeper reports the first failed job; the console script says it in one line
    m = read_manifest(sweep)
    failed = m[m["status"] == "failed"]
    assert len(failed) >= 1 and failed["error"].str.contains("worker process running this job died [(]killed by SIGKILL[)]").all()
    assert set(m["status"]) == {"done", "failed"} and len(m) == N_KILLABLE
    last = err.strip().splitlines()[-1]
    assert "Traceback" not in err and re.fullmatch(rf"zrp-ga: error: job ({'|'.join(map(str, failed['job']))}) [(]seed=.*[)]: "
                                                    r"the worker process running this job died [(]killed by SIGKILL[)].*", last), err  # fmt: skip
    assert len(err.strip().splitlines()) == 1, err  # that line alone (Hydra's "Error executing job with overrides" held back)
    for d in failed["dir"]:  # its run's status file as the manifest says (the worker could not set it)
        status = json.loads((sweep / str(d) / "status.json").read_text())
        assert status["status"] == "failed" and "worker process running this job died" in status["error"], status
    again = _zrp_ga(*KILLABLE, f"hydra.sweep.dir={sweep}")
    assert again.returncode == 0, again.stderr[-3000:]
    _check_same_as(sweep, uninterrupted)


@pytest.mark.slow
def test_spawned_workers_write_what_forked_ones_write(tmp_path, ours):
    """start_method=spawn (the default where fork is unsafe: macOS, Windows)."""
    proc = _zrp_ga(*ARGS, *OURS, "hydra.launcher.start_method=spawn", f"hydra.sweep.dir={tmp_path}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    spawned, forked = _runs(tmp_path), _runs(ours)
    assert sorted(spawned) == sorted(forked)
    for overrides, frame in forked.items():
        pd.testing.assert_frame_equal(spawned[overrides], frame)


@pytest.mark.slow  # 15 s of Hydra's own compositions
def test_a_suite_sweep_composes_once_per_instance_not_per_job(hydra_loader):
    """``instance=...`` options are ``_global_`` (not separable): each is Hydra's composition
    once, and the jobs that share it take the other groups' subtrees as usual."""
    grid = itertools.product(["puma560_6poses", "ur10_30poses", "stanford_30poses"], ["one_point", "blend"],
                             ["gaussian", "polynomial"], range(2))  # fmt: skip
    jobs = [[f"instance={i}", f"crossover={c}", f"mutation={m}", f"seed={s}", "experiment=operator_suite"]
            for i, c, m, s in grid]  # fmt: skip
    # the first job; the two other instances; for each instance, crossover and mutation changed
    # (without composing ahead the variants of the options the experiment sweeps and these jobs do not)
    hydras: dict = {}  # Hydra's compositions of the jobs, made once for both ways
    assert _compare_with_hydra(hydra_loader, ["experiment=operator_suite"], jobs, prefetch=False, hydras=hydras) == 1 + 2 + 3 * 2
    assert _compare_with_hydra(hydra_loader, ["experiment=operator_suite"], jobs, hydras=hydras) > 9  # composed ahead: the same configs


# --- jobs run together --------------------------------------------------------------------------------
def _single_run_equal(sweep: Path, d: str, overrides: str, tmp_path: Path) -> None:
    """The job in ``sweep / d`` against a single run of its config, built afresh in this process."""
    from zrp_ga import config

    single = tmp_path / f"single-{d}"
    execute.run(config.load(overrides.split()), single)
    pd.testing.assert_frame_equal(pd.read_csv(sweep / d / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS),
                                  pd.read_csv(single / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS), obj=overrides)  # fmt: skip
    swept, alone = (json.loads((x / "summary.json").read_text()) for x in (sweep / d, single))
    assert swept["best_genome"] == alone["best_genome"], overrides


def _own_log_line(sweep: Path, job: int) -> None:
    """The job's log file holds its own console line and no other job's."""
    text = (sweep / str(job) / "zrp-ga.log").read_text()
    assert text.count("job ") == 1 and f"job {job} [" in text, text


def test_a_job_of_a_batch_that_fails_fails_alone(tmp_path):
    """Four jobs on one problem instance (one batch); two have a bad value: they fail with it,
    recorded, and the two others end as single runs of their configs."""
    sweep = tmp_path / "sweep"
    proc = _zrp_ga("-m", "crossover=sbx,blend", "algorithm.elite=1,999", "seed=0", *SMALL, "population.generations=5",
                   *OURS, f"hydra.sweep.dir={sweep}")  # fmt: skip
    assert proc.returncode == 2 and "zrp-ga: error: algorithm.elite: must be in [0, population.mu = 30], got 999" in proc.stderr
    m = read_manifest(sweep)
    assert list(m["status"]) == ["done", "failed", "done", "failed"]
    assert m.loc[1, "error"] == m.loc[3, "error"] == "ConfigError: algorithm.elite: must be in [0, population.mu = 30], got 999"
    for job in (0, 2):
        _single_run_equal(sweep, str(job), m.loc[job, "overrides"], tmp_path)
        _own_log_line(sweep, job)
    assert pd.read_csv(sweep / "manifest.csv")["status"].tolist() == list(m["status"])


@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_a_sweep_mixing_ga_and_lm_jobs(tmp_path):
    """GA jobs on one instance run together, Levenberg-Marquardt jobs (no batch key) alone; every
    job ends as a single run of its config, with its own records."""
    sweep = tmp_path / "sweep"
    proc = _zrp_ga("-m", "algorithm=ga,lm", "crossover=sbx,blend", "seed=0", *SMALL, "population.generations=5", *OURS,
                   f"hydra.sweep.dir={sweep}")  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    m = read_manifest(sweep)
    assert list(m["status"]) == ["done"] * 4
    # LM's steps differ in the last bits from one process to another (its run stops one step
    # earlier or later; seen with lockstep=false too): its reference is a zrp-ga run, to round-off
    single = tmp_path / "lm"
    lm = _zrp_ga(*m.loc[2, "overrides"].split(), f"hydra.run.dir={single}")
    assert lm.returncode == 0, lm.stderr[-2000:]
    for job, overrides in zip(m["job"], m["overrides"]):
        if overrides.startswith("algorithm=ga"):
            _single_run_equal(sweep, str(job), overrides, tmp_path)
        else:  # crossover is no setting of LM's: both LM jobs are that run
            swept, alone = (json.loads((x / "summary.json").read_text()) for x in (sweep / str(job), single))
            assert swept["final_cost"] == pytest.approx(alone["final_cost"], rel=1e-9)
            assert swept["choices"]["algorithm"] == "lm"
        _own_log_line(sweep, job)
        assert OmegaConf.load(sweep / str(job) / ".hydra/overrides.yaml") == overrides.split()
        assert OmegaConf.load(sweep / str(job) / ".hydra/hydra.yaml").hydra.job.num == job


def test_the_driver_groups_jobs_by_batch_key(hydra_loader, tmp_path):
    """The jobs handed to the workers: those of one batch key together, ``batch_size`` of them
    (both workers busy), jobs without a key alone, every job once."""
    import collections
    import pickle
    import types

    from hydra.types import HydraContext, RunMode

    from hydra_plugins.zrp_ga_launcher import _compose, _workers
    from hydra_plugins.zrp_ga_launcher.config import ZrpGaLauncherConf
    from zrp_ga import config
    from zrp_ga.cli import main as cli_main
    from zrp_ga.run.sweep import batch_key

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN", f"hydra.sweep.dir={tmp_path}"], RunMode.MULTIRUN)
    jobs = [[f"algorithm={a}", f"crossover={c}", f"seed={s}"] for a in ("ga", "lm") for c in ("sbx", "blend") for s in range(12)]
    launcher = types.SimpleNamespace(config=master, settings=ZrpGaLauncherConf(),
                                     hydra_context=HydraContext(config_loader=_compose.ComposingLoader.wrap(hydra_loader), callbacks=None),
                                     task_function=cli_main.main.__wrapped__)  # fmt: skip
    pool = types.SimpleNamespace(workers=[None, None])
    dispatcher = _workers._Dispatcher(launcher, pool, collections.deque(enumerate(jobs)), tmp_path)
    assert dispatcher.size == _workers.MIN_BATCH == 8  # 48 jobs, 2 workers, 3 rounds: 8
    batches = []
    while (batch := dispatcher.next_batch())[1]:
        batches.append(batch)
    sent = sorted(idx for _, b in batches for idx, _, _ in b)
    assert sent == list(range(len(jobs)))
    for together, batch in batches:
        keys = {batch_key(config.typed(pickle.loads(data))) for _, _, data in batch}
        if together:  # GA jobs: one seed (problem instance) each, two of them
            assert len(keys) == 1 and None not in keys and len(batch) == 2
        else:
            assert keys == {None} and len(batch) == 1 and jobs[batch[0][0]][0] == "algorithm=lm"
    assert sum(together for together, _ in batches) == 12
    assert _workers.batch_size(144, 2) == 24 and _workers.batch_size(10, 2) == 8 and _workers.batch_size(10**5, 2) == _workers.MAX_BATCH


@pytest.mark.slow  # 10-30 s: kept out of the default run (under ten minutes); pytest -m slow
def test_the_driver_sends_whole_batch_keys_of_a_big_sweep(hydra_loader, tmp_path, monkeypatch):
    """A sweep whose jobs of one batch key lie far apart (``seed`` varying fastest: one problem
    instance per seed) and more jobs than the driver composes ahead: the keys the loader noted
    as the sweeper checked the jobs put each key's jobs in one batch, all of them; so does,
    without the notes (a loader that notes nothing, or jobs not checked before the launch: zrp_ga's
    sweeper), the grouping by the values of the swept keys that change the batch key.
    Every job's config as sent (kept from the check, pickled, beyond the few kept as they are)
    is Hydra's own composition of the job."""
    import collections
    import pickle
    import types

    from hydra.types import HydraContext, RunMode

    from hydra_plugins.zrp_ga_launcher import _compose, _workers
    from hydra_plugins.zrp_ga_launcher.config import ZrpGaLauncherConf
    from zrp_ga import config
    from zrp_ga.cli import main as cli_main
    from zrp_ga.run.sweep import batch_key

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN", f"hydra.sweep.dir={tmp_path}"], RunMode.MULTIRUN)
    jobs = [[f"crossover={c}", f"seed={s}"] for c in ("sbx", "blend", "one_point", "two_point") for s in range(6)]
    jobs.insert(5, ["algorithm=lm", "seed=0"])  # a job without a key, among them
    hydras: dict[int, str] = {}

    def sent(noting: bool, checked: bool = True) -> list[tuple[bool, list[int]]]:
        loader = _compose.ComposingLoader(hydra_loader)
        if noting:
            loader.note = _workers._Dispatcher.key
        for overrides in jobs if checked else []:  # as Hydra's sweeper checks every job before the launch
            loader.load_sweep_config(master, overrides)
        if noting and checked:  # the first jobs' configs kept pickled, up to the bytes allowed
            assert 0 < len(loader._pickled) < len(jobs) and not loader._asked
        launcher = types.SimpleNamespace(config=master, settings=ZrpGaLauncherConf(),
                                         hydra_context=HydraContext(config_loader=loader, callbacks=None),
                                         task_function=cli_main.main.__wrapped__)  # fmt: skip
        dispatcher = _workers._Dispatcher(launcher, types.SimpleNamespace(workers=[None, None]),
                                          collections.deque(enumerate(jobs)), tmp_path)  # fmt: skip
        dispatcher.limit = 4  # composed ahead at most: fewer than a key's jobs lie apart
        out = []
        while (batch := dispatcher.next_batch())[1]:
            together, got = batch
            assert together or len(got) == 1
            if together:
                assert len({batch_key(config.typed(pickle.loads(data))) for _, _, data in got}) == 1
            out.append((together, sorted(idx for idx, _, _ in got)))
            for idx, _, data in got:
                if idx not in hydras:  # Hydra's own composition of the job, once for the three ways of sending
                    hydras[idx] = OmegaConf.to_yaml(hydra_loader.load_sweep_config(master, jobs[idx]))
                assert OmegaConf.to_yaml(pickle.loads(data)) == hydras[idx]
        assert not loader._pickled and not loader._asked  # each kept config taken once
        assert sorted(i for _, b in out for i in b) == list(range(len(jobs)))
        return out

    monkeypatch.setattr(_compose, "KEEP_PICKLED_BYTES", 4 * 6000)  # about 4 configs kept pickled, the others composed again
    seeds = [int(o[-1].split("=")[1]) for o in jobs]
    noted = sent(True)
    together = [b for t, b in noted if t]
    assert len(together) == 6 and all(len(b) == 4 and len({seeds[i] for i in b}) == 1 for b in together)
    assert [b for t, b in noted if not t] == [[5]]
    # without the notes (zrp_ga's sweeper composes a few jobs): grouped by the swept keys that change the batch key
    for unnoted in (sent(False), sent(True, checked=False)):
        together = [b for t, b in unnoted if t]
        assert len(together) == 6 and all(len(b) == 4 and len({seeds[i] for i in b}) == 1 for b in together)
        assert [b for t, b in unnoted if not t] == [[5]]


def test_yaml_records_are_omegaconfs_text(hydra_loader):
    """``_batch.to_yaml``, with its kept texts, against ``OmegaConf.to_yaml`` on whole configs
    and values it quotes or folds."""
    from hydra.types import RunMode

    from hydra_plugins.zrp_ga_launcher import _batch

    master = hydra_loader.load_configuration("config", ["hydra.mode=MULTIRUN"], RunMode.MULTIRUN)
    for overrides in (["seed=1", "crossover=sbx"], ["seed=2", "crossover=sbx"], ["algorithm=lm"], ["instance=ur10_30poses"]):
        cfg = hydra_loader.load_sweep_config(master, overrides)
        for node in (cfg, OmegaConf.masked_copy(cfg, "hydra"), cfg.hydra.overrides.task, cfg.problem):
            assert _batch.to_yaml(OmegaConf.to_container(node, enum_to_str=True)) == OmegaConf.to_yaml(node)
    odd = OmegaConf.create({"a": {"b": "yes", "c": "1.5", "d": "10", "e": "nan", "f": "x: y", "g": "", "h": {}, "i": []},
                            "j": [{"k": "off"}, "1e3"], "l": "a long text " * 20 + "\n with lines\n", "m": None, 3: 4.0})  # fmt: skip
    for _ in range(2):  # the second time from the kept texts
        assert _batch.to_yaml(OmegaConf.to_container(odd)) == OmegaConf.to_yaml(odd)


RUN_BATCH = r"""
import json, pickle, sys
from pathlib import Path
from hydra import initialize_config_module
from hydra.core.global_hydra import GlobalHydra
from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import run_job
from hydra.types import HydraContext, RunMode
from zrp_ga.cli import main as cli_main
from zrp_ga import config
from hydra_plugins.zrp_ga_launcher import _batch

calls = []


class Recorder:
    def on_job_start(self, config, task_function, **kw):
        calls.append(["start", config.hydra.job.num, HydraConfig.get().job.num, task_function.__name__])

    def on_job_end(self, config, job_return, **kw):
        calls.append(["end", config.hydra.job.num, HydraConfig.get().job.num, job_return.status.name])


jobs = [sys.argv[3:] + o for o in (["crossover=sbx"], ["crossover=blend"], ["algorithm.elite=999"])]
base = sys.argv[3:] + ["hydra.mode=MULTIRUN"]
config.launcher_stored()  # the default launcher's settings, as Hydra's plugin discovery stores them (hydra-core 1.3 misses an editable install)
with initialize_config_module("zrp_ga.conf", **config.hydra_options()):
    loader = GlobalHydra.instance().hydra.config_loader
    ours, theirs = (loader.load_configuration("config", base + [f"hydra.sweep.dir={d}"], RunMode.MULTIRUN) for d in sys.argv[1:3])
    configs = [(k, loader.load_sweep_config(ours, o)) for k, o in enumerate(jobs)]
    alone = loader.load_sweep_config(theirs, jobs[0])
context = HydraContext(config_loader=None, callbacks=Recorder())
returns = _batch.run_batch(configs, context, cli_main.main.__wrapped__)
with_hydra = run_job(hydra_context=context, task_function=cli_main.main.__wrapped__, config=_batch._numbered(alone, 0),
                     job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir")
print(json.dumps({"calls": calls, "returns": [[r.status.name, r.overrides, repr(r._return_value), r.task_name, r.working_dir]
                                              for r in returns], "run_job": with_hydra.status.name}))
"""


def test_run_batch_in_a_fresh_process_does_what_run_job_does(tmp_path):
    """``_batch.run_batch`` with configs composed in a process that ran no Hydra app (as a
    cluster's job gets them): each job's return (status, return value, overrides), callbacks
    seeing the job, and ``.hydra`` records with the text Hydra's ``run_job`` writes."""
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    common = ["seed=3", *SMALL, "population.generations=4"]
    proc = subprocess.run([sys.executable, "-c", RUN_BATCH, str(ours), str(theirs), *common], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["run_job"] == "COMPLETED"
    assert out["calls"] == [["start", k, k, "main"] for k in range(3)] + [["end", 0, 0, "COMPLETED"], ["end", 1, 1, "COMPLETED"],
                                                                           ["end", 2, 2, "FAILED"], ["start", 0, 0, "main"],
                                                                           ["end", 0, 0, "COMPLETED"]]  # fmt: skip
    for k, (status, overrides, value, task_name, working_dir) in enumerate(out["returns"][:2]):
        objective = json.loads((ours / str(k) / "summary.json").read_text())["objective"]
        assert status == "COMPLETED" and value == repr(objective) and working_dir == str(tmp_path)
        assert overrides == [*common, ["crossover=sbx", "crossover=blend"][k]]
    assert out["returns"][2][0] == "FAILED" and "algorithm.elite: must be in [0, population.mu = 30], got 999" in out["returns"][2][2]
    assert read_manifest(ours)["status"].tolist() == ["done", "done", "failed"]
    for name in ("config.yaml", "overrides.yaml"):
        assert (ours / "0/.hydra" / name).read_text() == (theirs / "0/.hydra" / name).read_text(), name
    assert (ours / "0/.hydra/hydra.yaml").read_text().replace(str(ours), str(theirs)) == (theirs / "0/.hydra/hydra.yaml").read_text()
    assert _log_lines(ours / "0") == _log_lines(theirs / "0") and (ours / "2" / "zrp-ga.log").exists()


def test_a_batch_runs_its_jobs_without_a_batch_key_as_run_job_runs_them(tmp_path):
    """A batch holding a job whose runs cannot be evolved together (Levenberg-Marquardt: no
    batch key; the driver sends a group of jobs without computing each one's key): that job runs
    alone through Hydra's ``run_job`` (``_batch.run_alone``), as the driver sends such a job,
    and ends as its single run; the GA jobs run together, and each job's callbacks are called
    once around it."""
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    common = ["seed=3", *SMALL, "population.generations=4"]
    script = RUN_BATCH.replace('(["crossover=sbx"], ["crossover=blend"], ["algorithm.elite=999"])',
                               '(["crossover=sbx"], ["algorithm=lm"], ["crossover=blend"])')
    script = script.replace("returns = _batch.run_batch(", "alone_jobs = []\nreal = _batch.run_alone\n"
                            "_batch.run_alone = lambda idx, *a: alone_jobs.append(idx) or real(idx, *a)\nreturns = _batch.run_batch(")
    script = script.replace('"run_job": with_hydra.status.name', '"run_job": with_hydra.status.name, "alone": alone_jobs')
    assert script.count("alone_jobs") == 3
    proc = subprocess.run([sys.executable, "-c", script, str(ours), str(theirs), *common], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["alone"] == [1]  # the LM job
    assert [r[0] for r in out["returns"]] == ["COMPLETED"] * 3
    assert sorted(c[:2] for c in out["calls"][:6]) == sorted([["start", k] for k in range(3)] + [["end", k] for k in range(3)])
    assert read_manifest(ours)["status"].tolist() == ["done"] * 3
    assert json.loads((ours / "1" / "summary.json").read_text())["choices"]["algorithm"] == "lm"
    for k in (0, 2):  # the GA jobs, together
        assert not (ours / str(k) / "checkpoint.npz").exists() and (ours / str(k) / "convergence.csv").exists()
