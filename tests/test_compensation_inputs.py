"""Every class of bad input of ``zrp-ga-compensate`` and ``zrp_ga.compensate``: one line naming
what is wrong (the file, line, column or setting), exit code 2, before any work, nothing
written; from Python, a TypeError or ValueError naming the argument.

The cases double as rows of docs/bad_inputs.md (``python experiments/bad_inputs.py`` runs them),
so the table shows what the program prints.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from zrp_ga.io import presets
from zrp_ga.model import kinematics

TIMEOUT_S = 120  # a FIFO or /dev/zero read would hang or fill the memory: the case fails instead
NOMINAL = presets.get("puma560")
CALIBRATED = NOMINAL.replace(b0=NOMINAL.b0 + np.random.default_rng(0).uniform(-1e-3, 1e-3, NOMINAL.b0.shape), name="puma560 calibrated")
Q = np.array([[0.3, -0.6, 0.5, 0.4, 0.8, -0.2], [0.5, -0.4, 0.3, 0.6, 0.9, 0.1], [0.1, -0.7, 0.6, 0.2, 0.7, -0.4]])


def _targets_mm(q: np.ndarray = Q) -> list[list[float]]:
    _, p = kinematics.forward(NOMINAL, q)
    return (p * 1e3).round(4).tolist()


def _csv(head: str, rows) -> str:
    return "\n".join([head, *(",".join(str(v) for v in r) for r in rows)]) + "\n"


def _run_dir(d: Path) -> None:
    """A measured run's directory as zrp-ga writes it: the calibrated arm in its base frame, the
    recorded nominal (puma560), the base transform and a measured tool."""
    run = d / "run"
    run.mkdir()
    CALIBRATED.to_yaml(run / "calibrated_robot.yaml")
    base, tool = np.eye(4), np.eye(4)
    base[:3, 3], tool[:3, 3] = [2.0, -1.0, 0.3], [0.0, 0.0, 0.1]
    summary = {"robot_model": NOMINAL.to_dict(), "calibrated_robot": {"base": base.tolist(), "tools": {"tool": tool.tolist()}},
               "config": {"problem": {"use_orientation": False}}}  # fmt: skip
    (run / "summary.json").write_text(json.dumps(summary))


def _fifo(name: str) -> Callable[[Path], None]:
    return lambda d: os.mkfifo(d / name)


@dataclasses.dataclass(frozen=True)
class Case:
    kind: str  # the class of bad input
    what: str  # the example, in words
    args: tuple[str, ...]  # zrp-ga-compensate's arguments; {dir} is the case's folder
    expect: str  # what the one line must say
    files: tuple[tuple[str, str], ...] = ()  # (name, text) written into {dir} first
    setup: Callable[[Path], None] | None = None  # makes what text cannot (FIFOs, run directories)
    env: tuple[tuple[str, str], ...] = ()  # environment variables set for the run
    isolate: bool = False  # run in a subprocess (a case that would hang if it regressed)


ROBOTS = (("cal.yaml", CALIBRATED.to_yaml()), ("nominal.yaml", NOMINAL.to_yaml()))
WITH = ("{dir}/cal.yaml", "{dir}/prog.csv", "--nominal", "{dir}/nominal.yaml", "-o", "{dir}/out")
PROGRAM_MM = ("prog.csv", _csv("x,y,z", _targets_mm()))
CASES = [
    Case("not a regular file", "a FIFO given as the program", WITH, "prog.csv: a FIFO (named pipe), not a regular file; "
         "expected a program file (.csv)", ROBOTS, _fifo("prog.csv"), isolate=True),
    Case("not a regular file", "/dev/zero given as the program", (*WITH[:1], "/dev/zero", *WITH[2:]),
         "/dev/zero: a character device, not a regular file", ROBOTS, isolate=True),
    Case("contradictory settings", "a program in mm with --length-unit m", (*WITH, "--length-unit", "m"),
         "they cannot be in m; length_unit (--length-unit) mm?", (*ROBOTS, PROGRAM_MM)),
    Case("contradictory settings", "orientations in degrees with --angle-unit rad", (*WITH, "--angle-unit", "rad"),
         "column 'A': 180 rad is beyond any turn; in degrees? angle_unit (--angle-unit) deg",
         (*ROBOTS, ("prog.csv", _csv("x,y,z,A,B,C", [[*p, 180, 0, 180] for p in _targets_mm()])))),
    Case("contradictory settings", "a unit in the column names and another on the command line", (*WITH, "--length-unit", "m"),
         "the column names say mm, length_unit (--length-unit) says m", (*ROBOTS, ("prog.csv", _csv("x_mm,y_mm,z_mm", _targets_mm())))),
    Case("units not found", "targets too near the base in either unit", WITH, "cannot tell metres from millimetres; set "
         "length_unit (--length-unit)", (*ROBOTS, ("prog.csv", _csv("x,y,z", [[0.001, 0.002, 0.001], [0.002, 0.001, 0.001]])))),
    Case("duplicate columns", "x twice in the program", WITH, "prog.csv, line 1: duplicate column names ('x' in columns 1, 4)",
         (*ROBOTS, ("prog.csv", _csv("x,y,z,x", [[*p, 0] for p in _targets_mm()])))),
    Case("duplicate columns", "x and x_mm in the program", WITH, "columns 'x', 'x_mm' both give 'x'",
         (*ROBOTS, ("prog.csv", _csv("x,y,z,x_mm", [[*p, p[0]] for p in _targets_mm()])))),
    Case("output directory", "a file where the output directory should go", (*WITH[:-1], "{dir}/afile/out"),
         "out (-o): cannot create {dir}/afile/out: {dir}/afile is a file, not a directory", (*ROBOTS, PROGRAM_MM, ("afile", "x"))),
    Case("too big", "a 5000-row program with 1 MB to spare", WITH, "program: {dir}/prog.csv: about 5002 rows would need about",
         (*ROBOTS, ("prog.csv", _csv("x,y,z", _targets_mm()[:1] * 5000))), env=(("ZRP_GA_MEMORY", "1M"),)),
    Case("wrong nominal arm", "--nominal naming another arm than the run's", ("{dir}/run", "{dir}/prog.csv", "--nominal", "ur10"),
         "nominal (--nominal): ur10 is not the nominal arm of {dir}/run/calibrated_robot.yaml (puma560, recorded in its "
         "summary.json)", (PROGRAM_MM,), _run_dir),
    Case("not a rotation", "a quaternion of norm 2", (*WITH, "--orientation-convention", "quaternion"),
         "prog.csv, line 2: the quaternion q1, q2, q3, q4 has norm 2, not 1: not a rotation",
         (*ROBOTS, ("prog.csv", _csv("x,y,z,q1,q2,q3,q4", [[*p, 2, 0, 0, 0] for p in _targets_mm()])))),
    Case("missing setting", "rx, ry, rz without their convention", WITH, "columns rx, ry, rz need their orientation convention",
         (*ROBOTS, ("prog.csv", _csv("x,y,z,rx,ry,rz", [[*p, 0, 0, 0] for p in _targets_mm()])))),
    Case("degenerate frame", "a work object of three points on one line", (*WITH, "--work-object", "0,0,0;1,0,0;2,0,0",
         "--work-object-frame", "base"), "the points O, X and Y lie on one line", (*ROBOTS, PROGRAM_MM)),
    Case("no such setup", "a probe transform for a calibration that measured no tool", (*WITH, "--probe-in-flange", "0,0,100"),
         "probe_in_flange: {dir}/cal.yaml measured no tool point on the flange", (*ROBOTS, PROGRAM_MM)),
]


def run_case(case: Case, folder: Path) -> tuple[str, int]:
    """The case run as zrp-ga-compensate: its stderr and exit code (in-process, or in a
    subprocess with a timeout for cases that would hang)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in case.files:
        (folder / name).write_text(text)
    if case.setup is not None:
        case.setup(folder)
    args = [a.replace("{dir}", str(folder)) for a in case.args]
    env = {**os.environ, **dict(case.env)}
    if case.isolate:
        proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli.compensate", *args], capture_output=True, text=True,
                              cwd=folder, env=env, timeout=TIMEOUT_S)  # fmt: skip
        return proc.stderr, proc.returncode
    from zrp_ga.cli.compensate import main

    err, saved = io.StringIO(), dict(os.environ)
    os.environ.update(dict(case.env))
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(args)
    finally:
        os.environ.clear()
        os.environ.update(saved)
    return err.getvalue(), code


@pytest.mark.parametrize("case", CASES, ids=[f"{c.kind}: {c.what}" for c in CASES])
def test_bad_input_is_one_line_exit_2_nothing_written(case, tmp_path):
    err, code = run_case(case, tmp_path)
    assert code == 2, err
    assert err.startswith("zrp-ga-compensate: error: ") and err.count("\n") == 1, err
    assert case.expect.replace("{dir}", str(tmp_path)) in err
    assert not (tmp_path / "out").exists() and not any(tmp_path.glob("*_compensated"))


# --- Python callers ---------------------------------------------------------------------------------
def _poses(scale: float = 1.0) -> np.ndarray:
    R, p = kinematics.forward(NOMINAL, Q)
    T = np.tile(np.eye(4), (len(Q), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = R, p
    T[1, :3, :3] *= scale
    return T


MIRROR = np.diag([1.0, 1.0, -1.0, 1.0])
API_CASES = [
    ("calibration None", dict(calibration=None), TypeError, "calibration: expected a zrp-ga run directory or a calibrated robot file"),
    ("calibration a dict", dict(calibration={"u0": 1}), TypeError, "calibration: expected"),
    ("program None", dict(program=None), TypeError, "program: expected a CSV file path, a pandas DataFrame, a dict of columns or an array; got None"),
    ("program a ragged list", dict(program=[[0.1, 0.2, 0.3], [0.1]]), ValueError, "program: not an array of numbers"),
    ("program a ragged dict", dict(program={"x": [0.1, 0.2], "y": [0.1]}), ValueError, "program: a dict that is no table of columns"),
    ("nominal a dict", dict(nominal={"name": "puma560"}), TypeError, "nominal: expected a ZRPRobot, a preset name or a robot file path; got a dict"),
    ("q_seed a dict", dict(q_seed={"q1": 0.0}), TypeError, "q_seed: expected n joint values"),
    ("a pose that is no rotation", dict(program=_poses(1.01), kind="cartesian"), ValueError,
     "program, row 1: not a rotation matrix (R^T R differs from I by"),
    ("a mirrored tool", dict(tool=MIRROR), ValueError, "tool: not a rotation matrix (a mirror (det R = -1))"),
    ("a work object that is no rotation", dict(program=_poses(), kind="cartesian", work_object=np.diag([2.0, 1, 1, 1]),
     work_object_frame="base"), ValueError, "work_object: not a rotation matrix"),
    ("a frame that does not exist", dict(frame="world"), ValueError, "frame: 'world', expected one of 'base', 'instrument', 'work object'"),
    ("an output path that is a file", dict(out=Path(__file__)), ValueError, "out (-o): cannot create"),
]  # fmt: skip


def call_api(settings: dict) -> None:
    """``zrp_ga.compensate`` with a good calibration and program, ``settings`` replacing them."""
    import zrp_ga

    args = {"calibration": CALIBRATED, "program": Q, "nominal": NOMINAL, "kind": "joints", **settings}
    zrp_ga.compensate(args.pop("calibration"), args.pop("program"), **args)


@pytest.mark.parametrize(("what", "settings", "error", "message"), API_CASES, ids=[c[0] for c in API_CASES])
def test_python_callers_get_the_argument_named(what, settings, error, message):
    with pytest.raises(error) as info:
        call_api(settings)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_size_estimate_by_hand_and_said_before_the_work(tmp_path, monkeypatch):
    """200,000 rows of 10 columns, 6 joints: 1.25 x (160 B x 2e6 cells + 3000 B x 2e5 rows) =
    1.15 GB, and 3 ms x 6 joints x 2e5 rows = 1 h (one solve a row) to 2 h (two); a file's rows
    are counted from its size; a long one is announced through ``say`` before any row is solved."""
    from zrp_ga.compensation import size

    s = size.Size(200_000, 10, 6, None)
    assert s.memory() == pytest.approx(1.25 * (160 * 2e6 + 3000 * 2e5))
    assert s.seconds() == pytest.approx((3600.0, 7200.0))
    (tmp_path / "prog.csv").write_text(_csv("q1,q2,q3,q4,q5,q6", Q.tolist() * 100))
    est = size.of_program(tmp_path / "prog.csv", 6)
    assert (est.columns, est.joints) == (6, 6) and abs(est.rows - 301) <= 3
    said = []
    monkeypatch.setattr(size, "LONG_S", 0.0)
    monkeypatch.setattr("zrp_ga.compensation.compensate.read_program", lambda *a, **k: said.append("read") or 1 / 0)
    with pytest.raises(ZeroDivisionError):
        call_api({"program": tmp_path / "prog.csv", "say": said.append})
    assert said[0].startswith(f"{tmp_path / 'prog.csv'}: about {est.rows} rows will take about") and said[1] == "read"
