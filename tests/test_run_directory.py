"""A run directory stays consistent: one run writes into it at a time (a lock), and a failed
write (a full disk) ends with status failed naming the file, leaving no temporary file; the
temporary files of a killed run are removed when the next run starts there."""

import errno
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from zrp_ga import config
from zrp_ga.core.schema import ConfigError
from zrp_ga.run import checkpoint, directory, execute

FAST = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "refine=none", "population.mu=20",
        "population.lambda_=20", "seed=4", "progress=false"]  # fmt: skip


def test_a_second_run_into_a_directory_in_use_is_refused(tmp_path):
    """While one process holds a run directory's lock, a run into it is refused with one line
    naming the directory and that process; the directory is left as it was."""
    out = tmp_path / "run"
    out.mkdir()
    with directory.locked(out):
        with pytest.raises(ConfigError, match=rf"{out}: another run \(process {os.getpid()}\) is writing"):
            execute.run(config.load([*FAST, "population.generations=2"]), out)
        assert not (out / "status.json").exists() and not (out / "convergence.csv").exists()
    execute.run(config.load([*FAST, "population.generations=2"]), out)  # released: the run goes ahead
    assert directory.status(out) == "done"


def test_a_full_disk_while_writing_the_checkpoint_ends_failed_naming_it(tmp_path, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez", full)
    out = tmp_path / "run"
    with pytest.raises(OSError, match=r"No space left on device: .*checkpoint\.npz"):
        execute.run(config.load([*FAST, "population.generations=4", "checkpoint_every=2"]), out)
    st = json.loads((out / "status.json").read_text())
    assert st["status"] == "failed" and "checkpoint.npz" in st["error"] and "No space left" in st["error"]
    assert [p.name for p in out.iterdir() if p.name.endswith(".tmp")] == []
    assert not (out / "checkpoint.npz").exists()


def test_a_checkpoint_write_that_fails_leaves_the_previous_one_and_no_temporary_file(tmp_path, monkeypatch):
    path = tmp_path / "checkpoint.npz"
    checkpoint.save(path, {"gen": 1, "pop": np.arange(3.0)})
    monkeypatch.setattr(np, "savez", lambda *a, **k: (_ for _ in ()).throw(OSError(errno.ENOSPC, "No space left on device")))
    with pytest.raises(OSError, match="checkpoint.npz"):
        checkpoint.save(path, {"gen": 2, "pop": np.arange(4.0)})
    assert checkpoint.load(path)["gen"] == 1 and os.listdir(tmp_path) == ["checkpoint.npz"]


def test_the_temporary_files_of_a_killed_run_are_removed_when_it_resumes(tmp_path):
    out = tmp_path / "run"
    execute.run(config.load([*FAST, "population.generations=4", "checkpoint_every=2"]), out)
    stale = out / f".checkpoint.npz.{os.getpid() + 1}.tmp"  # what a kill inside a checkpoint write leaves
    stale.write_bytes(b"half a checkpoint")
    (out / "summary.json").unlink()  # as killed before the end
    directory.write_status(out, "interrupted")
    execute.run(config.load([f"resume={out}"]), tmp_path / "ignored")
    assert not stale.exists() and directory.status(out) == "done"


def test_calibrate_out_refuses_a_directory_holding_a_run_as_the_cli_does(tmp_path):
    import zrp_ga

    small = dict(population={"mu": 6, "lambda_": 6, "generations": 2}, refine="none",
                 problem={"n_poses": 8, "n_validation": 5})  # fmt: skip
    out = tmp_path / "run"
    zrp_ga.calibrate("puma560", out=out, **small)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    with pytest.raises(ConfigError, match=rf"output directory {out} already holds a run"):
        zrp_ga.calibrate("puma560", out=out, **small)
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    # what is left of an old run (its convergence log and summary gone) still counts: no old file beside new ones
    (out / "convergence.csv").unlink()
    (out / "summary.json").unlink()
    with pytest.raises(ConfigError, match="already holds a run"):
        zrp_ga.calibrate("puma560", out=out, **small)


@pytest.mark.slow
def test_resume_on_the_command_line_leaves_no_stray_output_directory(tmp_path):
    import subprocess
    import sys

    run, here = tmp_path / "run", tmp_path / "here"
    here.mkdir()
    args = [sys.executable, "-m", "zrp_ga.cli"]
    first = subprocess.run([*args, *FAST, "population.generations=3", f"hydra.run.dir={run}"], cwd=here,
                           capture_output=True, text=True)  # fmt: skip
    assert first.returncode == 0, first.stderr
    again = subprocess.run([*args, f"resume={run}"], cwd=here, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert list(here.iterdir()) == []  # no outputs/DATE/TIME
    assert (run / ".hydra" / "config.yaml").exists()  # the run's own config is kept as it was


@pytest.mark.parametrize("damage", ["summary cut short", "convergence deleted", "convergence cut short"])
def test_a_damaged_job_of_a_sweep_is_named_and_run_again(tmp_path, damage, caplog):
    """A sweep run again finds a job whose files were damaged: it names the file, runs the job
    again (to the same files: runs are deterministic), and is not blocked by it."""
    from zrp_ga.run.directory import Sweep
    from zrp_ga.run.sweep import SweepJob, sweep_job

    cfg = config.load([*FAST, "population.generations=3"])
    sweep, out = tmp_path / "sweep", tmp_path / "sweep" / "0"
    job = SweepJob(cfg, out, Sweep(sweep, 0, ("seed=4",), "0"))
    first = sweep_job(job)
    conv, summ = (out / "convergence.csv").read_text(), json.loads((out / "summary.json").read_text())
    name = {"summary cut short": "summary.json"}.get(damage, "convergence.csv")
    if damage == "summary cut short":
        (out / "summary.json").write_text((out / "summary.json").read_text()[:100])
    elif damage == "convergence deleted":
        (out / "convergence.csv").unlink()
    else:
        (out / "convergence.csv").write_text(conv[: conv.rindex("\n", 0, len(conv) - 1) + 5])
    again = sweep_job(job)
    assert any(name in r.getMessage() and "runs again" in r.getMessage() for r in caplog.records)
    assert again == first and directory.status(out) == "done"
    assert (out / "convergence.csv").read_text().count("\n") == conv.count("\n")
    assert json.loads((out / "summary.json").read_text())["final_cost"] == summ["final_cost"]
    assert directory.job_states(sweep)[-1]["status"] == "done"


def test_a_finished_job_recorded_before_a_setting_existed_is_the_same_run(tmp_path):
    """A run recorded by an older zrp_ga holds no key for a setting added since (null by
    default): continuing its sweep keeps it; a setting that really differs is named."""
    from zrp_ga import config
    from zrp_ga.core import schema
    from zrp_ga.core.schema import ConfigError
    from zrp_ga.run import sweep

    cfg = config.load(["problem=multipose"])
    stored = schema.to_dict(cfg)
    nulls = [k for k, v in stored["problem"].items() if v is None]
    assert nulls, "the problem schema has null settings to leave out"
    older = {**stored, "problem": {k: v for k, v in stored["problem"].items() if k not in nulls}}
    sweep._same_run(cfg, older, tmp_path)  # kept: no error
    other = {**stored, "problem": {**stored["problem"], "n_poses": stored["problem"]["n_poses"] + 1}}
    with pytest.raises(ConfigError, match=r"problem\.n_poses differs"):
        sweep._same_run(cfg, other, tmp_path)
    with pytest.raises(ConfigError, match="differs"):
        sweep._same_run(cfg, {**older, "problem": {**older["problem"], nulls[0]: [1]}}, tmp_path)


NO_FCNTL = """
import sys
sys.modules["fcntl"] = None  # as on Windows: `import fcntl` fails
"""


def test_without_fcntl_every_module_imports_and_a_directory_in_use_is_refused(tmp_path):
    """Every module of zrp_ga and of its launcher imports where ``fcntl`` does not exist (Windows),
    and a run directory's lock still refuses a second run, from this process and from another,
    until it is released."""
    out = tmp_path / "run"
    out.mkdir()
    other = NO_FCNTL + textwrap.dedent(f"""
        from pathlib import Path
        from zrp_ga.run import directory
        try:
            with directory.locked(Path({str(out)!r})):
                print("locked")
        except ValueError as exc:
            print(exc)
    """)  # fmt: skip
    code = NO_FCNTL + textwrap.dedent(f"""
        import importlib, os, pkgutil, subprocess
        from pathlib import Path
        import hydra_plugins.zrp_ga_launcher, zrp_ga
        names = [m.name for p in (zrp_ga, hydra_plugins.zrp_ga_launcher) for m in pkgutil.walk_packages(p.__path__, p.__name__ + ".")
                 if not m.name.endswith("__main__")]
        for name in names:
            importlib.import_module(name)
        print(len(names), "modules", os.getpid())
        from zrp_ga import config
        from zrp_ga.run import directory, execute
        out = Path({str(out)!r})
        cfg = config.load({[*FAST, "population.generations=2"]!r})
        with directory.locked(out):
            for refused in (lambda: execute.run(cfg, out), lambda: print(subprocess.run([sys.executable, "-c", {other!r}],
                            capture_output=True, text=True).stdout.strip())):
                try:
                    refused()
                except ValueError as exc:
                    print(exc)
        print(subprocess.run([sys.executable, "-c", {other!r}], capture_output=True, text=True).stdout.strip())
        execute.run(cfg, out)
        print(directory.status(out), "fcntl" in sys.modules and sys.modules["fcntl"] is None)
    """)  # fmt: skip
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    lines = done.stdout.splitlines()
    assert done.returncode == 0 and len(lines) == 5, done.stdout + done.stderr
    count, _, pid = lines[0].split()
    assert int(count) > 100  # every module of both packages
    refused = f"{out}: another run (process {pid}) is writing into this directory; wait for it to end or choose another directory"
    assert lines[1:3] == [refused, refused]  # from this process, then from another
    assert lines[3] == "locked" and lines[4] == "done True"  # released: the lock is taken, and a run goes ahead


@pytest.mark.parametrize("exc, state", [(KeyboardInterrupt(), "interrupted"), (RuntimeError("boom\nmore"), "failed")])
def test_a_stopped_jobs_state_reaches_manifest_csv(tmp_path, exc, state):
    """At Ctrl-C no end-of-job callback rewrites manifest.csv: the stop itself does, so that the
    table does not say "running" for a job the manifest (and its status.json) say interrupted."""
    import csv

    from zrp_ga.run import assembly
    from zrp_ga.run.directory import Sweep

    jobs = [Sweep(tmp_path, k, (f"seed={k}",), str(k)) for k in range(2)]
    directory.record(jobs[0], "done")
    directory.record(jobs[1], "running")
    directory.write_table(tmp_path)
    assembly.stopped(None, jobs[1], exc)
    with open(tmp_path / directory.TABLE, newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["job"], r["status"]) for r in rows] == [("0", "done"), ("1", state)]
    assert state != "failed" or rows[1]["error"] == "RuntimeError: boom"
