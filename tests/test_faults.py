"""Faults end in one line: a second sweep into a folder holding another, a full disk under
zrp_ga's launcher (runs evolved together) and under a single run. Each names the folder or
the file, sets the runs' status files to ``failed`` and loses nothing else.

The full-disk tests mount a tmpfs of a few hundred kB (root only; skipped elsewhere) and are
``slow`` (``nice python experiments/slow_tests.py`` runs them). A dead worker is tested in
tests/test_sweeps.py (``test_a_worker_that_dies_...``), an edited checkpoint in
tests/test_resume_checks.py.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from zrp_ga.core.schema import ConfigError
from zrp_ga.run import checkpoint, directory

SMALL = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "refine=none", "population.mu=30",
         "population.lambda_=30"]  # fmt: skip


# --- one sweep per folder ----------------------------------------------------------------------------
def _ran_a_job(sweep: Path) -> None:
    directory.record(directory.Sweep(sweep, 0, ("seed=0",), "0"), "running")


def test_a_sweep_folder_holds_one_sweep(tmp_path):
    sweep = tmp_path / "sweep"
    directory.claim(sweep, ["seed=0,1", "crossover=sbx,blend"])
    directory.claim(sweep, ["seed=0,1", "crossover=sbx,blend", "progress=false"])  # the same sweep: goes on
    _ran_a_job(sweep)
    with pytest.raises(ConfigError) as refused:
        directory.claim(sweep, ["seed=0,1,2", "crossover=sbx,blend", "mutation=gaussian"])
    assert str(refused.value) == (f"{sweep} holds another sweep (seed=0,1,2 here, seed=0,1 there; mutation=gaussian here, "
                                  "not there); run this one into another hydra.sweep.dir, or continue that one with its own command")  # fmt: skip
    with pytest.raises(ConfigError, match=r"\(crossover=sbx,blend there, not here\)"):
        directory.claim(sweep, ["seed=0,1"])
    with pytest.raises(ConfigError, match=r"\(the same settings in another order, which numbers the jobs otherwise\)"):
        directory.claim(sweep, ["crossover=sbx,blend", "seed=0,1"])
    with pytest.raises(ConfigError, match=r"\(hydra.sweeper.params differ\)"):  # an experiment's own grid
        directory.claim(sweep, ["seed=0,1", "crossover=sbx,blend"], {"seed": "range(5)"})
    directory.claim(sweep, ["seed=0,1", "crossover=sbx,blend"])  # still the first sweep's folder


def test_a_sweep_that_ran_no_job_gives_its_folder_up_unless_it_still_runs(tmp_path):
    """A sweep refused before its first job (a typo) does not keep the folder from the command
    put right; one still starting (its process alive) does: two sweeps never interleave."""
    sweep = tmp_path / "sweep"
    directory.claim(sweep, ["seed=0,1", "crossover=sbx,blnd"])
    record = sweep / directory.SHARED / directory.SWEEP_RECORD
    data = json.loads(record.read_text())
    data["pid"] = 2**22 + 12345  # a process that does not exist (above Linux's pid_max default)
    record.write_text(json.dumps(data))
    directory.claim(sweep, ["seed=0,1", "crossover=sbx,blend"])
    alive = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], start_new_session=True)
    try:
        data = json.loads(record.read_text())
        data["pid"] = alive.pid
        record.write_text(json.dumps(data))
        with pytest.raises(ConfigError, match="holds another sweep"):
            directory.claim(sweep, ["seed=3"])
    finally:
        os.killpg(alive.pid, signal.SIGKILL)
        alive.wait()


def test_a_sweep_folder_from_before_the_record_is_left_as_it_was(tmp_path):
    """Its jobs ran without a record: no sweep is refused at its start (each job refuses a run
    of another config, as before), and none claims it."""
    sweep = tmp_path / "sweep"
    _ran_a_job(sweep)
    directory.claim(sweep, ["seed=5"])
    directory.claim(sweep, ["seed=6"])
    assert not (sweep / directory.SHARED / directory.SWEEP_RECORD).exists()


# --- a full disk -------------------------------------------------------------------------------------
@pytest.fixture
def tiny_disk(tmp_path):
    """A folder on a tmpfs of 300 kB (root only)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    made = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(disk)], capture_output=True, text=True)
    if made.returncode:
        pytest.skip(f"cannot mount a tmpfs: {made.stderr.strip()}")
    yield disk
    subprocess.run(["umount", "-l", str(disk)], check=False)


def _fill(disk: Path) -> None:
    """Take every free byte of ``disk``."""
    with open(disk / "filler", "wb", buffering=0) as f:
        for size in (65536, 4096, 512, 1):
            try:
                while True:
                    f.write(b"x" * size)
            except OSError as exc:
                assert exc.errno == errno.ENOSPC


def test_on_a_full_disk_a_run_still_says_it_failed_and_the_writes_name_their_files(tiny_disk):
    """Not a byte free: the status file is set ``failed`` in place, a failure's manifest line
    that cannot be written does not hide the failure, and every write that fails names its
    file and leaves no temporary file (the previous checkpoint kept)."""
    import numpy as np

    from zrp_ga.run import assembly, callbacks
    from zrp_ga.run.directory import Sweep

    run = tiny_disk / "run"
    run.mkdir()
    directory.write_status(run, "running")
    checkpoint.save(run / directory.CHECKPOINT, {"gen": 1, "pop": np.arange(3.0)})
    log = callbacks.ConvergenceLog(run / directory.CONVERGENCE)
    log.on_start(None)
    _fill(tiny_disk)
    error = OSError(errno.ENOSPC, "No space left on device", str(run / directory.CONVERGENCE))
    assembly.stopped(None, Sweep(tiny_disk, 0, ("seed=0",), "run"), error)  # the manifest cannot be appended: no error
    directory.write_status(run, "failed", f"OSError: {error}")
    assert json.loads((run / directory.STATUS).read_text()) == {"status": "failed", "error": f"OSError: {error}"}
    with pytest.raises(OSError) as failed:
        checkpoint.save(run / directory.CHECKPOINT, {"gen": 2, "pop": np.arange(3000.0)})
    assert failed.value.filename == str(run / directory.CHECKPOINT)
    assert int(checkpoint.load(run / directory.CHECKPOINT)["gen"]) == 1
    with pytest.raises(OSError) as failed:
        for gen in range(3000):
            log.on_generation(None, {"gen": gen, "nevals": 10 * gen})
    assert failed.value.filename == str(run / directory.CONVERGENCE)
    with pytest.raises(OSError) as failed:
        directory.write_table(tiny_disk)
    with pytest.raises(OSError) as failed:
        directory.record(Sweep(tiny_disk, 1, (), "1"), "running")
    assert failed.value.filename == str(tiny_disk / directory.MANIFEST)
    assert not list(tiny_disk.rglob(".*.tmp")) and not list(tiny_disk.glob(".manifest.*"))


def _zrp_ga(*args: str) -> subprocess.CompletedProcess:
    proc = subprocess.Popen([sys.executable, "-m", "zrp_ga.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)  # fmt: skip
    try:
        out, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def _lines(err: str) -> list[str]:
    """stderr's lines but numba's notice that it compiles again (a checkout at another path)."""
    return [line for line in err.strip().splitlines() if not line.startswith("compiling the kernels")]


def _ends_in_one_line_naming_a_file(proc: subprocess.CompletedProcess, disk: Path) -> str:
    err = proc.stderr
    assert proc.returncode == 2, err[-3000:]
    assert "Traceback" not in err and "Logging error" not in err, err[-3000:]
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"zrp-ga: error: {disk}/") and last.endswith(": No space left on device"), err[-3000:]
    named = Path(last[len("zrp-ga: error: "): -len(": No space left on device")])
    # the file; or the run's directory, for the files written at its end (summary, robot files)
    assert named.name in (directory.CONVERGENCE, directory.CHECKPOINT, directory.STATUS, directory.MANIFEST) or named == disk \
        or named.parent == disk, last
    return last


def _nothing_lost(run: Path) -> None:
    """The run's files as a killed run leaves them: status failed naming a file of the disk,
    convergence.csv whole rows from generation 0 on, the checkpoint (if any) readable and
    holding a generation the log has."""
    status = json.loads((run / directory.STATUS).read_text())
    assert status["status"] == "failed" and "No space left on device" in status["error"] and str(run.parent) in status["error"], status
    rows = pd.read_csv(run / directory.CONVERGENCE)
    assert list(rows["gen"]) == list(range(len(rows)))
    if (run / directory.CHECKPOINT).exists():
        assert int(checkpoint.load(run / directory.CHECKPOINT)["gen"]) <= rows["gen"].max()
    assert not list(run.glob(".*.tmp"))


@pytest.mark.slow
def test_a_full_disk_under_the_lockstep_launcher_ends_in_one_line(tiny_disk):
    """Four jobs, two batches evolved together on two workers, their logs filling 300 kB: the
    sweep ends with one line naming a file, every run failed in its status file and the
    manifest, no logging traceback; with room again the same command completes the sweep."""
    sweep = tiny_disk / "sweep"
    args = ["-m", "seed=0,1", "crossover=sbx,blend", *SMALL, "population.generations=300", "checkpoint_every=2",
            "hydra/launcher=zrp_ga", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep}"]  # fmt: skip
    proc = _zrp_ga(*args)
    _ends_in_one_line_naming_a_file(proc, sweep)
    assert len(_lines(proc.stderr)) == 1, proc.stderr  # ours: not Hydra's "Error executing job with overrides" too
    m = directory.read_manifest(sweep)
    assert list(m["status"]) == ["failed"] * 4 and m["error"].str.contains("No space left on device").all(), m
    for d in m["dir"]:
        _nothing_lost(sweep / str(d))
    subprocess.run(["mount", "-o", "remount,size=20m", str(tiny_disk)], check=True)
    again = _zrp_ga(*args)
    assert again.returncode == 0, again.stderr[-3000:]
    assert list(directory.read_manifest(sweep)["status"]) == ["done"] * 4
    for d in m["dir"]:
        rows = pd.read_csv(sweep / str(d) / directory.CONVERGENCE)
        assert list(rows["gen"]) == list(range(301))


@pytest.mark.slow
def test_a_full_disk_under_a_single_run_ends_in_one_line(tiny_disk):
    out = tiny_disk / "run"
    proc = _zrp_ga(*SMALL, "population.generations=2000", "checkpoint_every=2", "progress=false", f"hydra.run.dir={out}")
    _ends_in_one_line_naming_a_file(proc, out)
    assert len(_lines(proc.stderr)) == 1, proc.stderr
    _nothing_lost(out)


def _cli_with_a_job_failing_with(error: Exception, monkeypatch) -> int:
    """``zrp-ga``'s console script whose Hydra job failed with ``error``: Hydra's
    ``JobReturn.return_value`` writes its line and raises it, as after a run or a sweep's batch."""
    from hydra.core.utils import JobReturn, JobStatus

    from zrp_ga.cli import main as cli_main

    def failed_job() -> None:
        ret = JobReturn(overrides=["seed=1"], status=JobStatus.FAILED)
        ret.return_value = error
        ret.return_value  # noqa: B018

    monkeypatch.setattr(cli_main, "main", failed_job)
    monkeypatch.setattr(sys, "argv", ["zrp-ga"])
    monkeypatch.setenv("HYDRA_FULL_ERROR", "0")  # cli() sets it to 1: restored (unset) after the test
    monkeypatch.setattr("logging.raiseExceptions", True)
    sigterm = signal.getsignal(signal.SIGTERM)
    try:
        with pytest.raises(SystemExit) as stopped:
            cli_main.cli()
    finally:
        signal.signal(signal.SIGTERM, sigterm)
    return int(stopped.value.code)


def test_a_jobs_error_is_our_one_line_without_hydras(monkeypatch, capsys):
    error = OSError(errno.ENOSPC, "No space left on device", "/disk/run/checkpoint.npz")
    assert _cli_with_a_job_failing_with(error, monkeypatch) == 2
    assert capsys.readouterr().err.splitlines() == ["zrp-ga: error: /disk/run/checkpoint.npz: No space left on device"]


def test_hydras_line_is_kept_for_an_error_that_is_not_one_line(monkeypatch, capsys):
    """An error cli() does not turn into a line (a defect: its traceback follows) keeps Hydra's
    line naming the job's overrides."""
    with pytest.raises(ZeroDivisionError):
        _cli_with_a_job_failing_with(ZeroDivisionError("x"), monkeypatch)
    assert capsys.readouterr().err.splitlines() == ["Error executing job with overrides: ['seed=1']"]


def test_a_run_whose_process_died_is_set_failed_unless_it_ended_or_is_held(tmp_path):
    """What the launcher does for the runs of a dead worker or cluster job
    (``directory.fail_lost``): ``running`` becomes ``failed`` with the error; a finished run,
    a directory without a run and one whose lock another process holds are left alone."""
    runs = {name: tmp_path / name for name in ("running", "done", "empty", "held")}
    for name, run in runs.items():
        run.mkdir()
        if name != "empty":
            directory.write_status(run, "done" if name == "done" else "running")
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from filelock import FileLock; "
                               f"lock = FileLock({str(runs['held'] / directory.LOCK)!r}); lock.acquire(); print(1, flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "1"
        for run in runs.values():
            directory.fail_lost(run, "ChildProcessError: the worker process running this job died (killed by SIGKILL)")
    finally:
        os.killpg(holder.pid, signal.SIGKILL)
        holder.wait()
    assert json.loads((runs["running"] / directory.STATUS).read_text()) == {
        "status": "failed", "error": "ChildProcessError: the worker process running this job died (killed by SIGKILL)"}
    assert directory.status(runs["done"]) == "done" and directory.status(runs["held"]) == "running"
    assert not (runs["empty"] / directory.STATUS).exists()
