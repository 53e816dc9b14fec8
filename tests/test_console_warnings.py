"""Warnings a person reads (issue 27, item 7): each warning is one line on the console (what, how
bad, what to do), its details in ``summary.json`` and the run's log file; the default run does
not open with a block; a sweep says each warning once per problem instance, not once per job; a
long arm does not print a line per joint.

The numbers are the model's, counted here independently: the paper's one pose gives 6 position
and orientation rows for 36 parameters (test_app.py: 12 of the 31 combinations the model can
identify); an n-joint chain of revolute joints has one slide of the point on each axis along it
that no pose sees (docs/model.md, section 3), named in the details, never on the console."""

import json
import subprocess
import sys

import numpy as np
import pytest


def _zrp_ga(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args], capture_output=True, text=True, cwd=cwd)


def _console(proc: subprocess.CompletedProcess) -> list[str]:
    return [ln for ln in (proc.stdout + proc.stderr).splitlines() if ln.strip()]


def _warnings(lines: list[str]) -> list[str]:
    return [ln for ln in lines if "[WARNING]" in ln]


def test_the_default_run_says_one_line_per_warning_and_keeps_the_details(tmp_path):
    run = tmp_path / "run"
    proc = _zrp_ga("progress=false", f"hydra.run.dir={run}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = _console(proc)
    warned = _warnings(lines)
    ident = [w for w in warned if "calibration poses identify" in w]
    assert len(ident) == 1
    assert "identify 12 of the 31 parameter combinations the model can identify (36 parameters): 19 stay at nominal" in ident[0]
    assert "more (or more varied) poses" in ident[0]  # what to do
    assert not any("unidentifiable:" in ln for ln in lines)  # the list is not on the console
    assert len(lines) <= 4 + len(warned)  # results, cost, validation, uncertainty: the result is not buried
    assert lines.index(ident[0]) < len(lines) - 2  # before the result lines
    summary = json.loads((run / "summary.json").read_text())
    listed = summary["identifiability"]["unidentifiable"]
    assert summary["identifiability"]["rank"] == 12 and len(listed) >= 1
    log = (run / "zrp-ga.log").read_text()
    assert ident[0].split("] - ", 1)[1] in log
    for u in listed:  # every direction in the log, as a line of its own
        assert f"  unidentifiable: {u}" in log


def test_a_sweep_says_each_warning_once_not_per_job(tmp_path):
    """Four seeds of the paper's one-pose problem (four instances: the simulated poses follow the
    seed) warn alike: each text is said once on the console, the identifiability line once, and
    every job's summary.json keeps its own warnings."""
    sweep = tmp_path / "sweep"
    proc = _zrp_ga("-m", "seed=0,1,2,3", "population.generations=2", "problem.n_validation=5", "progress=false",
                   f"hydra.sweep.dir={sweep}")  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    texts = [w.split("] - ", 1)[1] for w in _warnings(_console(proc))]
    assert len(texts) == len(set(texts)), texts
    assert sum("calibration poses identify" in w for w in texts) == 1
    assert sum("the validation is extrapolation" in w for w in texts) == 1
    for k in range(4):
        summary = json.loads((sweep / str(k) / "summary.json").read_text())
        assert any("the validation is extrapolation" in w for w in summary["warnings"])
        assert summary["identifiability"]["rank"] == 12


def _long_arm(n: int) -> str:
    """A DH table of n revolute joints, 5 cm apart, axes alternating by 90 degrees."""
    rows = [f"  - {{name: j{i + 1}, type: R, a: 0.05, alpha: {90 if i % 2 else -90}, d: 0.05, theta: 0, limits: [-170, 170]}}"
            for i in range(n)]  # fmt: skip
    return "\n".join([f"name: chain{n}", "convention: dh", "units: {length: m, angle: deg}", "joints:", *rows]) + "\n"


@pytest.mark.parametrize("n", [40, pytest.param(300, marks=pytest.mark.slow)])
def test_a_long_arm_says_its_identifiability_in_one_line(tmp_path, n):
    arm = tmp_path / "arm.yaml"
    arm.write_text(_long_arm(n))
    run = tmp_path / "run"
    proc = _zrp_ga("robot=file", f"robot.file={arm}", "problem=multipose", "problem.n_poses=3", "problem.n_validation=2",
                   "algorithm=lm", "progress=false", f"hydra.run.dir={run}")  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = _console(proc)
    assert len(lines) <= 12, "\n".join(lines[:20])
    ident = [w for w in _warnings(lines) if "calibration poses identify" in w]
    assert len(ident) == 1
    summary = json.loads((run / "summary.json").read_text())
    listed = summary["identifiability"]["unidentifiable"]
    # 3 poses x 6 rows identify at most 18 + n (unit rows) of the 6n parameters: the details name
    # more directions than the console could hold, at least one per joint's slide
    slides = [u for u in listed if "slide along u0_" in u]
    assert len(slides) >= n - 1
    assert np.isclose(summary["identifiability"]["n_params"], 6 * n)
