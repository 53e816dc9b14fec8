"""zrp_ga's launcher on SLURM and Ray (hydra_plugins/zrp_ga_launcher/_remote.py): a sweep's runs in
batches, one cluster job each. submitit's ``debug`` and ``local`` clusters drive the SLURM path on
this machine; ``ray_local`` starts a Ray here. The runs' files and manifest lines are compared with
a sweep of zrp_ga's local launcher."""

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from omegaconf import OmegaConf
from test_sweeps import _summary  # a run's summary.json without its timing and launcher

from zrp_ga import config
from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS
from zrp_ga.run.directory import read_manifest

SMALL = ["problem.n_validation=5", "population.generations=3"]


def _zrp_ga(*args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args], capture_output=True, text=True, **kw)


def _cluster_jobs(sweep: Path) -> list[Path]:
    """submitit's job folders (named by job id: the process id on the local cluster, DEBUG_... on debug)."""
    return sorted(p for p in (sweep / ".submitit").iterdir() if p.name != "%j")


def _kill_job(job: str) -> None:
    """SIGKILL to a local cluster job (its id is its controlling process's id) and the task it
    started, as a node lost or out of memory takes them."""
    pid = int(job)
    try:
        children = [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        children = []
    for p in [*children, pid]:
        try:
            os.kill(p, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _same_runs(sweep: Path, reference: Path, once: bool = True) -> None:
    """Every run of ``sweep`` has the files and manifest line of the same run in ``reference``
    (``once``: and one line of its own in its log; a sweep run again adds a line for a kept run)."""
    m, r = read_manifest(sweep), read_manifest(reference)
    pd.testing.assert_frame_equal(m.drop(columns="time"), r.drop(columns="time"))
    assert pd.read_csv(sweep / "manifest.csv")["status"].tolist() == list(m["status"])
    for d in m["dir"]:
        a, b = sweep / str(d), reference / str(d)
        assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in b.iterdir())
        pd.testing.assert_frame_equal(pd.read_csv(a / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS),
                                      pd.read_csv(b / "convergence.csv").drop(columns=WALL_CLOCK_COLUMNS))  # fmt: skip
        for name in ("best_params.csv", "initial_population.csv", ".hydra/config.yaml", ".hydra/overrides.yaml"):
            assert (a / name).read_text() == (b / name).read_text(), name
        assert _summary(a) == _summary(b)
        assert not once or (a / "zrp-ga.log").read_text().count("[zrp_ga][INFO] - job ") == 1


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory) -> Path:
    """Five runs with zrp_ga's launcher on this machine: what the cluster sweeps must write."""
    sweep = tmp_path_factory.mktemp("local")
    proc = _zrp_ga("-m", "seed=0,1,2,3,4", *SMALL, "hydra/launcher=local", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return sweep


# --- the batches ------------------------------------------------------------------------------------
@pytest.mark.parametrize("n, per_job, sizes", [(10, 3, [3, 3, 2, 2]), (10, 5, [5, 5]), (1, 300, [1]), (600, 300, [300, 300]),
                                               (601, 300, [201, 200, 200]), (0, 3, [])])  # fmt: skip
def test_batches_are_ceil_of_runs_over_runs_per_job_and_nearly_equal(n, per_job, sizes):
    from hydra_plugins.zrp_ga_launcher._remote import batches

    out = batches([None] * n, per_job)
    assert len(out) == math.ceil(n / per_job) == len(sizes)
    assert [len(b) for b in out] == sizes
    assert [i for b in out for i in b] == list(range(n))


def test_batches_put_the_runs_of_one_key_side_by_side_in_job_order():
    from hydra_plugins.zrp_ga_launcher._remote import batches

    keys = ["ga|mu=30", None, "ga|mu=30", "ga|mu=60", None, "ga|mu=30", "ga|mu=60"]
    assert batches(keys, 3) == [[0, 2, 5], [1, 4], [3, 6]]  # keys in the order they first come: mu=30, None, mu=60; 3 + 2 + 2
    assert batches(keys, 7) == [[0, 2, 5, 1, 4, 3, 6]]


# --- the presets and their settings -------------------------------------------------------------------
@pytest.mark.parametrize("preset, executor, extra", [("slurm", "slurm", {"cluster": "slurm", "runs_per_job": 300}),
                                                     ("ray_local", "ray", {"ray_address": None}),
                                                     ("ray_cluster", "ray", {"ray_address": "auto"})])  # fmt: skip
def test_cluster_presets_are_zrp_ga_launcher_in_batches(preset, executor, extra):
    cfg = config.compose([f"hydra/launcher={preset}"], return_hydra_config=True)
    launcher = cfg.hydra.launcher
    assert launcher._target_ == "hydra_plugins.zrp_ga_launcher.launcher.ZrpGaLauncher"
    assert launcher.executor.value == executor
    for key, value in extra.items():
        assert launcher[key] == value, key


def test_one_slurm_job_per_run_stays_reachable():
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    cfg = config.compose(["hydra/launcher=slurm_per_run"], return_hydra_config=True)
    assert "SlurmLauncher" in cfg.hydra.launcher._target_ and cfg.hydra.launcher.mem_gb == 2


@pytest.mark.parametrize("override, expected", [
    ("hydra.launcher.runs_per_job=0", "hydra.launcher.runs_per_job: must be at least 1, got 0"),
    ("hydra.launcher.executor=pbs", "hydra.launcher.executor"),
])  # fmt: skip
def test_bad_cluster_setting_is_one_line_naming_the_key(tmp_path, override, expected):
    proc = _zrp_ga("-m", "seed=0", *SMALL, "hydra/launcher=slurm", override, f"hydra.sweep.dir={tmp_path}")
    assert proc.returncode == 2
    assert expected in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not list(tmp_path.glob("*/convergence.csv"))


# --- sweeps on the clusters ----------------------------------------------------------------------------
def test_slurm_path_runs_a_batch_per_cluster_job(tmp_path, local_sweep):
    """submitit's debug cluster: the batches run in this process, one after another (no SLURM needed)."""
    pytest.importorskip("submitit")
    sweep = tmp_path / "sweep"
    proc = _zrp_ga("-m", "seed=0,1,2,3,4", *SMALL, "hydra/launcher=slurm", "hydra.launcher.cluster=debug",
                   "hydra.launcher.runs_per_job=2", f"hydra.sweep.dir={sweep}")  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert len(_cluster_jobs(sweep)) == 3  # ceil(5 / 2)
    _same_runs(sweep, local_sweep)


@pytest.mark.slow
def test_slurm_local_cluster_jobs_are_processes_of_their_own(tmp_path, local_sweep):
    """submitit's local cluster: each batch pickled to a process of its own, as SLURM runs it."""
    pytest.importorskip("submitit")
    sweep = tmp_path / "sweep"
    args = ("-m", "seed=0,1,2,3,4", *SMALL, "hydra/launcher=slurm", "hydra.launcher.cluster=local",
            "hydra.launcher.runs_per_job=2", f"hydra.sweep.dir={sweep}")  # fmt: skip
    proc = _zrp_ga(*args, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    jobs = _cluster_jobs(sweep)
    assert len(jobs) == 3 and all(j.name.isdigit() for j in jobs)
    _same_runs(sweep, local_sweep)
    runs = {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")}
    again = _zrp_ga(*args, timeout=900)  # the same command again: every run finished, kept
    assert again.returncode == 0, again.stderr[-2000:]
    assert {p: p.read_bytes() for p in sweep.glob("*/convergence.csv")} == runs


@pytest.mark.slow
def test_a_failed_cluster_job_fails_its_batch_and_the_sweep_continues(tmp_path, local_sweep):
    """One cluster job killed as it starts (a node lost): the runs of its batch fail, recorded in
    the manifest naming the job; the others finish; the same command again runs the failed ones."""
    pytest.importorskip("submitit")
    sweep = tmp_path / "sweep"
    args = ["-m", "seed=0,1,2,3,4", *SMALL, "hydra/launcher=slurm", "hydra.launcher.cluster=local",
            "hydra.launcher.runs_per_job=2", f"hydra.sweep.dir={sweep}"]  # fmt: skip
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, killed = time.monotonic() + 300, None
    while killed is None and time.monotonic() < deadline and proc.poll() is None:
        started = [j for j in _cluster_jobs(sweep) if j.name.isdigit()] if (sweep / ".submitit").exists() else []
        if started:
            killed = started[0].name
            _kill_job(killed)
        time.sleep(0.02)
    _, err = proc.communicate(timeout=900)
    assert killed is not None, err[-2000:]
    assert proc.returncode != 0  # as with any failed job: Hydra's sweeper raises its error at the end
    m = read_manifest(sweep)
    failed = m[m["status"] == "failed"]
    assert set(failed["job"]) in ({0, 1}, {2, 3}, {4}), m  # one batch, as cut: [0, 1], [2, 3], [4]
    assert all(f"cluster job {killed} failed" in e for e in failed["error"])
    assert set(m["status"]) == {"done", "failed"} and len(m) == 5
    again = _zrp_ga(*args, timeout=900)
    assert again.returncode == 0, again.stderr[-2000:]
    _same_runs(sweep, local_sweep, once=False)


@pytest.mark.slow
def test_ray_runs_a_batch_per_task(tmp_path, local_sweep):
    pytest.importorskip("ray")
    sweep = tmp_path / "sweep"
    args = ("-m", "seed=0,1,2,3,4", *SMALL, "hydra/launcher=ray_local", "hydra.launcher.ray_num_cpus=2",
            "hydra.launcher.runs_per_job=2", f"hydra.sweep.dir={sweep}")  # fmt: skip
    proc = _zrp_ga(*args, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "submitted 3 Ray tasks" in proc.stdout + proc.stderr  # ceil(5 / 2)
    _same_runs(sweep, local_sweep)
    assert OmegaConf.load(sweep / "0/.hydra/hydra.yaml").hydra.launcher.executor == "ray"


@pytest.mark.slow
def test_the_runs_a_failed_cluster_job_finished_stay_done(tmp_path):
    """A cluster job killed after the first run of its batch ended: that run stays done, kept
    when the sweep runs again; the others fail, and run again."""
    pytest.importorskip("submitit")
    sweep = tmp_path / "sweep"
    args = ["-m", "seed=0,1,2", "problem.n_validation=5", "population.generations=1500", "hydra/launcher=slurm",
            "hydra.launcher.cluster=local", f"hydra.sweep.dir={sweep}"]  # fmt: skip
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, killed = time.monotonic() + 600, None
    while killed is None and time.monotonic() < deadline and proc.poll() is None:
        if (sweep / "manifest.jsonl").exists() and '"job": 0' in (text := (sweep / "manifest.jsonl").read_text()) and '"done"' in text:
            (job,) = [j for j in _cluster_jobs(sweep) if j.name.isdigit()]
            killed = job.name
            _kill_job(killed)
        time.sleep(0.01)
    _, err = proc.communicate(timeout=900)
    assert killed is not None, err[-2000:]
    m = read_manifest(sweep)
    assert list(m["status"]) == ["done", "failed", "failed"], m
    assert all(f"cluster job {killed} failed" in e for e in m["error"][1:])
    before = (sweep / "0" / "convergence.csv").read_bytes()
    again = _zrp_ga(*args, timeout=900)
    assert again.returncode == 0, again.stderr[-2000:]
    assert list(read_manifest(sweep)["status"]) == ["done"] * 3
    assert "finished before; kept" in (sweep / "0" / "zrp-ga.log").read_text()
    assert (sweep / "0" / "convergence.csv").read_bytes() == before


def _stop_while_running(sweep: Path, args: list[str], stop) -> subprocess.CompletedProcess:
    """Run the sweep; ``stop(driver's process id)`` once run 0 is past its first checkpoint."""
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, stopped = time.monotonic() + 600, False
    while not stopped and time.monotonic() < deadline and proc.poll() is None:
        rows = sweep / "0" / "convergence.csv"
        if rows.exists() and len(rows.read_text().splitlines()) > 60:
            stop(proc.pid)
            stopped = True
        time.sleep(0.05)
    out, err = proc.communicate(timeout=900)
    assert stopped, err[-2000:]
    for _ in range(100):  # the cluster job may still be saving the run
        if json.loads((sweep / "0" / "status.json").read_text())["status"] != "running":
            break
        time.sleep(0.1)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def _resumed_to_the_end(sweep: Path, args: list[str]) -> None:
    """Run 0 stopped with its checkpoint, run 1 not started; the same command again resumes run 0."""
    assert json.loads((sweep / "0" / "status.json").read_text())["status"] == "interrupted"
    assert (sweep / "0" / "checkpoint.npz").exists() and not (sweep / "1" / "convergence.csv").exists()
    again = _zrp_ga(*args, timeout=900)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "continues from its checkpoint" in (sweep / "0" / "zrp-ga.log").read_text()
    assert list(read_manifest(sweep)["status"]) == ["done", "done"]
    for d in ("0", "1"):
        gens = pd.read_csv(sweep / d / "convergence.csv")["gen"]
        assert list(gens) == list(range(3001)), d  # every generation once


LONG = ["-m", "seed=0,1", "problem.n_validation=5", "population.generations=3000", "checkpoint_every=50",
        "hydra/launcher=slurm", "hydra.launcher.cluster=local"]  # fmt: skip


@pytest.mark.slow
def test_a_slurm_job_stopped_by_sigterm_saves_its_run_and_the_sweep_continues(tmp_path):
    """SIGTERM (scancel, the time limit) to a cluster job: its running run saves its checkpoint,
    as at Ctrl-C; the same command again resumes it to the end."""
    pytest.importorskip("submitit")
    sweep = tmp_path / "sweep"
    args = [*LONG, f"hydra.sweep.dir={sweep}"]
    job = []

    def stop(driver: int) -> None:
        (folder,) = [j for j in _cluster_jobs(sweep) if j.name.isdigit()]
        job.append(folder.name)
        os.kill(int(folder.name), signal.SIGTERM)

    _stop_while_running(sweep, args, stop)
    m = read_manifest(sweep)
    assert list(m["status"]) == ["failed", "failed"] and all(f"cluster job {job[0]} failed" in e for e in m["error"])
    _resumed_to_the_end(sweep, args)


@pytest.mark.slow
def test_ctrl_c_cancels_the_cluster_jobs_whose_runs_save_their_checkpoints(tmp_path):
    pytest.importorskip("submitit")
    sweep = tmp_path / "sweep"
    args = [*LONG, f"hydra.sweep.dir={sweep}"]
    proc = _stop_while_running(sweep, args, lambda driver: os.kill(driver, signal.SIGINT))  # the driver alone
    assert proc.returncode == 130 and f"continue with the same command and hydra.sweep.dir={sweep}" in proc.stderr, proc.stderr
    _resumed_to_the_end(sweep, args)
