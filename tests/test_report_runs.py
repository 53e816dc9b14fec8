"""zrp-ga-report on real runs of every kind the app makes (simulated and measured, with and
without validation, GA, Levenberg-Marquardt and CMA-ES, finished, failed, interrupted and still
running), on damaged copies of them, and on bad command lines."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from zrp_ga import config, report, robots
from zrp_ga.algorithms.ga import GA
from zrp_ga.cli import report as report_cli
from zrp_ga.model import kinematics
from zrp_ga.model.simulation import random_joints
from zrp_ga.run import execute

FINISHED = ["paper-ga", "paper-lm", "paper-cmaes", "multipose-ga", "measured-ga", "measured-lm-no-validation"]
SMALL_GA = ["population.mu=10", "population.lambda_=10", "population.generations=3"]


def _measured_file(path, n, rng):
    """A measured-data CSV of the UR10 (the nominal arm, 0.1 mm noise), in m and rad."""
    arm = robots.get("ur10")
    q = random_joints(arm, n, rng)
    p = kinematics.forward(arm, q)[1] + rng.normal(scale=1e-4, size=(n, 3))
    df = pd.DataFrame(q, columns=[f"q{i}" for i in range(1, 7)])
    df[["x", "y", "z"]] = p
    df.to_csv(path, index=False)
    return str(path)


def _run(where, *overrides):
    execute.run(config.load([*overrides, "progress=false", "problem.n_validation=5"] if "problem=measured" not in overrides
                        else [*overrides, "progress=false"]), where)  # fmt: skip


def _breaking(exc):
    """GA.step that raises ``exc`` in the second generation (the app records the failure)."""
    step = GA.step

    def broken(self):
        if self.gen >= 1:
            raise exc
        step(self)

    return broken


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    root = tmp_path_factory.mktemp("kinds")
    rng = np.random.default_rng(3)
    cal, val = _measured_file(root / "cal.csv", 20, rng), _measured_file(root / "val.csv", 10, rng)
    measured = ["problem=measured", "robot=ur10", f"problem.calibration_file={cal}"]
    runs = root / "runs"
    _run(runs / "paper-ga", *SMALL_GA)
    _run(runs / "paper-lm", "algorithm=lm")
    _run(runs / "paper-cmaes", "algorithm=cmaes", "population.lambda_=10", "population.generations=3")
    _run(runs / "multipose-ga", "problem=multipose", "problem.n_poses=6", "refine=none", *SMALL_GA)
    _run(runs / "measured-ga", *measured, f"problem.validation_file={val}", "problem.if_worse=keep", *SMALL_GA)  # (the nominal arm is the truth)
    _run(runs / "measured-lm-no-validation", *measured, "algorithm=lm", "algorithm.max_evals=30", "problem.if_worse=keep")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(GA, "step", _breaking(ValueError("made to fail")))
        with pytest.raises(ValueError):
            _run(runs / "failed", *SMALL_GA)
        mp.setattr(GA, "step", _breaking(KeyboardInterrupt()))
        with pytest.raises(KeyboardInterrupt):
            _run(runs / "interrupted", *SMALL_GA)
    shutil.copytree(runs / "paper-ga", runs / "running")  # what a run looks like on disk while it runs
    (runs / "running" / "summary.json").unlink()
    (runs / "running" / "status.json").write_text('{"status": "running"}')
    return runs


def test_every_kind_of_run_is_reported_or_named_as_left_out(kinds, tmp_path, capsys):
    report_cli.main([str(kinds), "--out", str(tmp_path / "r"), "--formats", "png"])
    printed = capsys.readouterr().out
    assert printed.startswith(f"{len(FINISHED)} runs of ")
    assert f"left out {kinds / 'failed'}: failed: ValueError('made to fail')" in printed
    assert f"left out {kinds / 'interrupted'}: interrupted (continue it with zrp-ga resume={kinds / 'interrupted'})" in printed
    assert f"left out {kinds / 'running'}: still running" in printed
    runs = pd.read_csv(tmp_path / "r" / "runs.csv")
    assert sorted(runs["run"].str.rsplit("/", n=1).str[-1]) == sorted(FINISHED)
    val = runs.set_index(runs["run"].str.rsplit("/", n=1).str[-1])["val_rms_mm"]  # NaN compares unequal to all: test it by isnan
    assert np.isnan(val["measured-lm-no-validation"]) and np.isfinite(val.drop("measured-lm-no-validation")).all()
    assert "CMA-ES" in set(runs["configuration"])  # LM twice: its evaluation cap tells the configurations apart
    assert {"Levenberg-Marquardt, max_evals None", "Levenberg-Marquardt, max_evals 30"} <= set(runs["configuration"])
    left = pd.read_csv(tmp_path / "r" / "left_out.csv")
    assert len(left) == 3
    floors = pd.read_csv(tmp_path / "r" / "targets.csv").set_index("instance")
    paper = floors.loc["puma560-1pose-linear-seed0"]
    assert paper["runs"] == 3 and paper["round_off"]  # the one-pose problem is solved to round-off
    assert paper["reference"] == pytest.approx(1e-9 * paper["nominal_cost"])
    assert "round-off" in printed and "best known (lowest final cost of 3 runs)" in printed
    for name in ("summary.md", "per_instance.md", "ert.md", "fixed_budget.md", "fig2_convergence.png", "ecdf_evals_to_target.png",
                 "validation_error_boxplot.png", "convergence_by_configuration.png", "table3_best_params.md"):  # fmt: skip
        assert (tmp_path / "r" / name).stat().st_size > 0, name
    _check_ioh(tmp_path / "r" / "ioh", kinds)


def _check_ioh(folder, kinds):
    """Every finished run is one block of the IOH export: from evaluation 1 to its last
    evaluation, its final cost the lowest, under its instance's name and its genome's length."""
    summaries = {name: json.loads((kinds / name / "summary.json").read_text()) for name in FINISHED}
    by_key = {(s["instance"], s["nevals"]): name for name, s in summaries.items()}
    assert len(by_key) == len(FINISHED)  # (instance, evaluations) tells the runs apart
    seen = []
    for meta_file in folder.glob("*/IOHprofiler_f*.json"):
        meta = json.loads(meta_file.read_text())
        (scenario,) = meta["scenarios"]
        blocks = (meta_file.parent / scenario["path"]).read_text().split("evaluations raw_y\n")[1:]
        assert len(blocks) == len(scenario["runs"])
        for block, run in zip(blocks, scenario["runs"]):
            records = np.array([line.split() for line in block.splitlines()], dtype=float)
            name = by_key[(meta["function_name"], run["evals"])]
            s = summaries[name]
            assert records[0, 0] == 1 and records[-1, 0] == s["nevals"] and run["best"]["y"] == s["final_cost"]
            assert records[:, 1].min() == s["final_cost"] and scenario["dimension"] == len(s["best_genome"])
            seen.append(name)
    assert sorted(seen) == sorted(FINISHED)


def test_a_measured_run_without_validation_alone(kinds, tmp_path):
    t = report.write_report([kinds / "measured-lm-no-validation"], tmp_path / "r", formats=("png",))
    assert np.isnan(t["runs"]["val_rms_mm"]).all() and not (tmp_path / "r" / "validation_error_boxplot.png").exists()
    assert (tmp_path / "r" / "fig2_convergence.png").exists() and len(t["summary"]) == 1
    assert t["summary"]["success_1.01"].iloc[0] == 1.0  # its own final cost is the best known floor


def _damaged(kinds, where):
    """Copies of finished runs, each damaged in one way, and the reason the report must give."""
    cases = {}

    def copy(name, source="paper-ga"):
        shutil.copytree(kinds / source, where / name)
        return where / name

    conv = copy("truncated-line") / "convergence.csv"
    conv.write_text(conv.read_text()[:-9])
    cases["truncated-line"] = "convergence.csv line 5 is truncated"
    conv = copy("truncated-at-a-line-end") / "convergence.csv"
    conv.write_text("".join(conv.read_text().splitlines(keepends=True)[:-1]))
    cases["truncated-at-a-line-end"] = "convergence.csv ends at "
    conv = copy("bad-number") / "convergence.csv"
    lines = conv.read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace(lines[2].split(",")[2], "0.0x1", 1)
    conv.write_text("".join(lines))
    cases["bad-number"] = "convergence.csv line 3: best is '0.0x1'"
    summary = copy("summary-cut") / "summary.json"
    summary.write_text(summary.read_text()[:200])
    cases["summary-cut"] = "summary.json is not valid JSON (line "
    summary = copy("summary-bad-field") / "summary.json"
    summary.write_text(json.dumps({**json.loads(summary.read_text()), "final_cost": "low"}))
    cases["summary-bad-field"] = "summary.json: 'final_cost' is 'low'"
    return cases


def test_malformed_runs_are_left_out_by_name_and_the_rest_reported(kinds, tmp_path):
    where = tmp_path / "runs"
    cases = _damaged(kinds, where)
    shutil.copytree(kinds / "paper-lm", where / "intact")
    t = report.write_report([where], tmp_path / "r", formats=())
    assert list(t["runs"]["run"]) == ["../runs/intact"]  # relative to the report
    reasons = dict(pd.read_csv(tmp_path / "r" / "left_out.csv").itertuples(index=False))
    for name, reason in cases.items():
        assert reasons[f"../runs/{name}"].startswith(reason), (name, reasons[f"../runs/{name}"])


def test_bad_paths_are_one_line_errors_and_nothing_is_written(kinds, tmp_path, capsys):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    out = tmp_path / "out"
    for args, message in [
        ((tmp_path / "missing", "--out", out), "no such directory"),
        ((a_file, "--out", out), f"{a_file}: not a directory"),
        ((kinds / "paper-lm", "--out", a_file), f"--out {a_file}: not a directory"),
        ((kinds / "paper-lm", "--out", a_file / "sub"), f"--out {a_file / 'sub'}: {a_file} is not a directory"),
        ((kinds / "paper-lm", "--out", "/proc/zrp-ga-report"), "--out /proc/zrp-ga-report: cannot write in /proc"),
        ((kinds / "paper-lm", "--out", out, "--ioh", a_file), f"--ioh {a_file}: not a directory"),
        ((kinds / "paper-lm", "--out", out, "--levels", "1.1,x"), "argument --levels"),
        ((kinds / "failed", "--out", out), "no finished run under"),
        ((kinds / "paper-lm", "--out", out, "--formats", "png,jpgx"), "--formats: jpgx is not a figure format"),
    ]:  # fmt: skip
        with pytest.raises(SystemExit) as exit_:
            report_cli.main([str(a) for a in args])
        printed = capsys.readouterr()
        assert exit_.value.code == 2 and printed.out == "", args
        assert printed.err.startswith("zrp-ga-report: error: ") and message in printed.err and printed.err.count("\n") == 1, printed.err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli.report", str(tmp_path / "missing")], capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr == f"zrp-ga-report: error: {tmp_path / 'missing'}: no such directory\n"


def test_a_second_report_replaces_the_first(kinds, tmp_path):
    out = tmp_path / "r"
    report.write_report([kinds / "paper-lm", kinds / "measured-ga"], out, formats=("png",))
    assert (out / "validation_error_boxplot.png").exists() and len(list((out / "ioh").iterdir())) == 2
    (out / "notes.txt").write_text("mine")
    report.write_report([kinds / "measured-lm-no-validation"], out, formats=("png",))  # no validation: no box plot
    assert not (out / "validation_error_boxplot.png").exists() and (out / "notes.txt").read_text() == "mine"
    assert [p.name for p in (out / "ioh").iterdir()] == ["Levenberg-Marquardt"]
    (out / "ioh" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="ioh: holds files that are not an IOHprofiler export"):
        report.write_report([kinds / "paper-lm"], out)


def test_an_error_midway_leaves_nothing_half_written(kinds, tmp_path, monkeypatch):
    def fail(*args, **kwargs):
        raise RuntimeError("drawing failed")

    monkeypatch.setattr(report.figures, "convergence_runs", fail)  # after every table and the other figures
    with pytest.raises(RuntimeError):
        report.write_report([kinds / "paper-lm"], tmp_path / "r", formats=("png",))
    assert list(tmp_path.iterdir()) == []


def test_importing_the_report_leaves_the_backend_alone():
    code = ("import sys, matplotlib; matplotlib.use('svg'); import zrp_ga.report, zrp_ga.report.figures; "
            "print(matplotlib.get_backend(), 'matplotlib.pyplot' in sys.modules)")  # fmt: skip
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.stdout.split() == ["svg", "False"], proc.stderr


def test_a_fifo_named_like_a_run_file_is_left_out_in_one_line_not_read(kinds, tmp_path):
    """A FIFO would block the first read forever: the report names it and goes on (the command
    runs in a process of its own with a time limit, so that a hang fails the test)."""
    import os

    where = tmp_path / "runs"
    shutil.copytree(kinds / "paper-lm", where / "intact")
    names = ["convergence.csv", "summary.json", "status.json", "initial_population.csv"]
    for name in names:
        shutil.copytree(kinds / "paper-ga", where / f"fifo-{name}")
        (where / f"fifo-{name}" / name).unlink()
        os.mkfifo(where / f"fifo-{name}" / name)
    done = subprocess.run([sys.executable, "-m", "zrp_ga.cli.report", str(where), "--out", str(tmp_path / "r"), "--formats", "none"],
                          capture_output=True, text=True, timeout=180)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    left = pd.read_csv(tmp_path / "r" / "left_out.csv").set_index("run")["reason"]
    # initial_population.csv is not needed: that run counts, its first generation read from convergence.csv
    assert sorted(left.index) == [f"../runs/fifo-{n}" for n in sorted(names[:3])]
    assert len(pd.read_csv(tmp_path / "r" / "runs.csv")) == 2
    for name in names[:3]:
        reason = left[f"../runs/fifo-{name}"]
        assert reason == f"{where / f'fifo-{name}' / name}: a FIFO (named pipe), not a regular file; expected a run's {name}"
        assert f"left out {where / f'fifo-{name}'}: {reason}" in done.stdout
