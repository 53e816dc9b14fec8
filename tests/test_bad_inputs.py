"""Every class of bad input, over every kind of file the app reads: one line on stderr naming
what is wrong, exit code 2, before any work, and no run directory left behind.

The cases double as the table in docs/bad_inputs.md (``python experiments/bad_inputs.py``
runs them and writes it), so the table shows what the program really prints.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from zrp_ga import robots
from zrp_ga.model import kinematics

GOOD_ARM = robots.path("ur10").read_text()
DH_ROW = "{name: j1, type: R, a: 0, alpha: 90, d: 0.1273, theta: 0}"


@dataclasses.dataclass(frozen=True)
class Case:
    kind: str  # the class of bad input
    what: str  # the example, in words
    args: tuple[str, ...]  # zrp-ga's arguments; {dir} is the case's folder
    expect: str  # what the one line must say
    files: tuple[tuple[str, str], ...] = ()  # (name, text) written into {dir} first


def _arm(**changes: str) -> str:
    text = GOOD_ARM
    for old, new in changes.items():
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


def _points(n: int = 40, seed: int = 0) -> list[str]:
    """Rows ``q1..q6 (rad), x, y, z (mm)`` of a UR10 a tracker sees 3 m away."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.5, 2.5, size=(n, 6))
    _, p = kinematics.forward(robots.get("ur10"), q)
    return [",".join(f"{v:.6f}" for v in (*qi, *(pi + [3.0, 0.5, 0.2]) * 1e3)) for qi, pi in zip(q, p)]


HEAD = "q1,q2,q3,q4,q5,q6,x,y,z"
ROWS = _points()
MEASURED = ("problem=measured", "robot=ur10", "problem.calibration_file={dir}/cal.csv")


def _csv(rows: list[str]) -> tuple[tuple[str, str], ...]:
    return (("cal.csv", "\n".join([HEAD, *rows]) + "\n"),)


CASES = [
    # --- paths --------------------------------------------------------------------------------
    Case("missing path", "a robot file that does not exist", ("robot=file", "robot.file={dir}/nothere.yaml"),
         "nothere.yaml"),
    Case("wrong kind of path", "a directory given as the robot file", ("robot=file", "robot.file={dir}"), "directory"),
    Case("missing path", "resume from a folder with no checkpoint", ("resume={dir}",), "no checkpoint"),
    Case("output directory", "a file where the run directory should go", ("hydra.run.dir={dir}/afile/run",),
         "is a file, not a directory", files=(("afile", "x"),)),
    # --- robot files --------------------------------------------------------------------------
    Case("malformed file", "a robot file that is not YAML", ("robot=file", "robot.file={dir}/arm.yaml"), "arm.yaml",
         files=(("arm.yaml", "joints: [a: b: c\n"),)),
    Case("malformed file", "a URDF that is not XML", ("robot=file", "robot.file={dir}/arm.urdf"), "arm.urdf",
         files=(("arm.urdf", "<robot name='x'><link name='a'></robot>"),)),
    Case("non-finite number", "NaN in a DH table", ("robot=file", "robot.file={dir}/arm.yaml"), "arm.yaml",
         files=(("arm.yaml", _arm(**{"d: 0.1273": "d: .nan"})),)),
    Case("absurd number", "a link length of 1e300 m", ("robot=file", "robot.file={dir}/arm.yaml"), "arm.yaml",
         files=(("arm.yaml", _arm(**{"d: 0.1273": "d: 1.0e+300"})),)),
    # --- config values ------------------------------------------------------------------------
    Case("unknown key", "a typo in a key", ("problem.n_pose=30",), "Key 'n_pose' not in"),
    Case("unknown option", "an option that does not exist", ("crossover=teleport",), "Could not find 'crossover/teleport'"),
    Case("wrong type", "text where a number belongs", ("population.mu=abc",), "population.mu"),
    Case("wrong choice", "a cost that does not exist", ("problem.cost=quadratic",), "expected one of [linear, nonlinear]"),
    Case("absurd value", "a probability above 1", ("crossover.prob=1.5",), "crossover.prob: must be a probability in [0, 1]"),
    Case("absurd value", "a negative mutation sigma", ("mutation.op.sigma=-0.1",), "mutation.op.sigma: must be a number > 0"),
    Case("absurd value", "a tournament of size 0", ("selection.op.size=0",), "selection.op.size: must be a whole number >= 1"),
    Case("absurd value", "negative measurement noise", ("problem.position_noise=-1",), "problem.position_noise: must be a number >= 0"),
    Case("absurd value", "a non-finite gene range", ("problem.axis_error=inf",), "problem.axis_error"),
    Case("meaningless run", "zero generations", ("population.generations=0",), "population.generations: must be at least 1"),
    Case("meaningless run", "no poses", ("problem.n_poses=0",), "problem.n_poses: must be at least 1"),
    Case("meaningless run", "an evaluation budget below the first population", ("population.generations=null",
         "population.max_evals=10"), "population.max_evals: must be more than the initial population"),
    Case("unknown parameter", "a parameter the operator does not take", ("crossover=sbx", "+crossover.op.etaa=3"),
         "crossover.op: unknown parameter 'etaa'"),
    # --- measurement files ----------------------------------------------------------------------
    Case("missing path", "a measurement file that does not exist", MEASURED, "cal.csv"),
    Case("wrong kind of path", "a directory given as the measurement file",
         ("problem=measured", "robot=ur10", "problem.calibration_file={dir}"), "directory"),
    Case("non-finite number", "NaN in a measured position", MEASURED, "line 4, column 'y': 'nan' is not a finite number",
         files=_csv(ROWS[:2] + [ROWS[2].rsplit(",", 2)[0] + ",nan," + ROWS[2].rsplit(",", 1)[1]] + ROWS[3:])),
    Case("absurd number", "a measured coordinate of 1e300 mm", MEASURED, "line 3, column 'x'",
         files=_csv(ROWS[:1] + [",".join(ROWS[1].split(",")[:6] + ["1e300"] + ROWS[1].split(",")[7:])] + ROWS[2:])),
    Case("degenerate data", "rows repeated", MEASURED, "repeat", files=_csv(ROWS + ROWS[:5])),
    Case("too little data", "fewer poses than the parameters need", MEASURED, "need", files=_csv(ROWS[:3])),
    Case("too little data", "a single pose", MEASURED, "pose", files=_csv(ROWS[:1])),
    Case("missing column", "a file without the z column", MEASURED, "'z'",
         files=(("cal.csv", "\n".join([HEAD[:-2], *(r.rsplit(",", 1)[0] for r in ROWS)]) + "\n"),)),
    # --- checkpoints ----------------------------------------------------------------------------
    Case("corrupted file", "a truncated checkpoint", ("resume={dir}",), "not a readable checkpoint",
         files=(("checkpoint.npz", "PK\x03\x04 truncated"),)),
]


def run_case(case: Case, folder: Path) -> subprocess.CompletedProcess:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in case.files:
        (folder / name).write_text(text)
    args = [a.replace("{dir}", str(folder)) for a in case.args]
    if not any(a.startswith("hydra.run.dir=") for a in args):
        args.append(f"hydra.run.dir={folder}/run")
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args, "progress=false"], capture_output=True, text=True,
                          cwd=folder)  # fmt: skip


@pytest.mark.parametrize("case", CASES, ids=[f"{c.kind}: {c.what}" for c in CASES])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(case, tmp_path):
    proc = run_case(case, tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("zrp-ga: error: "), proc.stderr
    assert case.expect in lines[0]
    assert not (tmp_path / "run").exists() and not (tmp_path / "outputs").exists()
