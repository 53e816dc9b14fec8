"""More classes of bad input (issue 19): work too big for the machine, files that are no
regular files, inputs that would give wrong results with no warning, messages that missed the
key. Each CLI case: one line on stderr naming what is wrong, exit code 2, before any work, no
run directory. ``python experiments/bad_inputs.py`` runs these cases too and writes their lines
into docs/bad_inputs.md.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from zrp_ga import config, robots
from zrp_ga.core import checks, files, schema
from zrp_ga.io import measurements
from zrp_ga.model import kinematics
from zrp_ga.model.poses import Measurements
from zrp_ga.problems import measured
from zrp_ga.run import budget

TIMEOUT_S = 240  # a FIFO read would hang: the case fails instead


@dataclasses.dataclass(frozen=True)
class Case:
    kind: str  # the class of bad input
    what: str  # the example, in words
    args: tuple[str, ...]  # zrp-ga's arguments; {dir} is the case's folder
    expect: str  # what the one line must say
    files: tuple[tuple[str, str], ...] = ()  # (name, text) written into {dir} first
    setup: Callable[[Path], None] | None = None  # makes what text cannot (FIFOs, symlinks)
    env: tuple[tuple[str, str], ...] = ()  # environment variables set for the run


def _points(n: int = 40, seed: int = 0, scale: float = 1e3) -> list[str]:
    """Rows ``q1..q6 (rad), x, y, z`` (mm with scale 1e3, m with 1) of a UR10 a tracker sees
    3 m away."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.5, 2.5, size=(n, 6))
    _, p = kinematics.forward(robots.get("ur10"), q)
    return [",".join(f"{v:.6f}" for v in (*qi, *(pi + [3.0, 0.5, 0.2]) * scale)) for qi, pi in zip(q, p)]


HEAD = "q1,q2,q3,q4,q5,q6,x,y,z"
ROWS = _points()
MEASURED = ("problem=measured", "robot=ur10", "problem.calibration_file={dir}/cal.csv")
VALIDATED = (*MEASURED, "problem.validation_file={dir}/val.csv")
CAL = ("cal.csv", "\n".join([HEAD, *ROWS]) + "\n")
VAL = ("val.csv", "\n".join([HEAD, *_points(20, seed=1)]) + "\n")
TWICE = "q1,q2,q3,q4,q5,q6,x,y,z,x,y,z"  # a controller's x, y, z, then the tracker's
TWICE_ROWS = [r + "," + ",".join(r.split(",")[6:]) for r in ROWS]


def _arm(n: int) -> str:
    rows = "\n".join(f"  - {{name: j{i}, type: R, a: 0.01, alpha: {90 if i % 2 else -90}, d: 0.01}}" for i in range(n))
    return f"name: arm{n}\nconvention: dh\nunits: {{length: m, angle: deg}}\njoints:\n{rows}\n"


def _fifo(name: str) -> Callable[[Path], None]:
    return lambda d: os.mkfifo(d / name)


def _loop(name: str) -> Callable[[Path], None]:
    def make(d: Path) -> None:
        (d / "a").symlink_to(d / "b")
        (d / "b").symlink_to(d / "a")
        (d / name).symlink_to(d / "a")

    return make


def _checkpoint_fifo(d: Path) -> None:
    os.mkfifo(d / "checkpoint.npz")


CASES = [
    # --- too big for the machine (zrp_ga.run.budget) ------------------------------------------------
    Case("too big", "ten million simulated poses", ("problem=multipose", "problem.n_poses=10000000"),
         "problem.n_poses: the run would need about"),
    Case("too big", "a population of a billion", ("population.mu=1000000000",), "population: the run would need about"),
    Case("too big", "an arm of 500 joints on a machine with 200 MB to spare", ("robot=file", "robot.file={dir}/arm.yaml"),
         "robot: the run would need about", files=(("arm.yaml", _arm(500)),), env=(("ZRP_GA_MEMORY", "200M"),)),
    Case("too big", "a 20000-row tracker file on a machine with 100 MB to spare", MEASURED,
         "problem.calibration_file: the run would need about",
         files=(("cal.csv", "\n".join([HEAD, *_points(20000)]) + "\n"),), env=(("ZRP_GA_MEMORY", "100M"),)),
    # --- no regular file (zrp_ga.core.files) ---------------------------------------------------------
    Case("not a regular file", "a FIFO given as the robot file", ("robot=file", "robot.file={dir}/arm.yaml"),
         "arm.yaml: a FIFO (named pipe), not a regular file", setup=_fifo("arm.yaml")),
    Case("not a regular file", "a FIFO given as the calibration file", MEASURED, "cal.csv: a FIFO (named pipe)",
         setup=_fifo("cal.csv")),
    Case("not a regular file", "a FIFO given as the validation file", VALIDATED, "val.csv: a FIFO (named pipe)",
         files=(CAL,), setup=_fifo("val.csv")),
    Case("not a regular file", "a FIFO where the checkpoint should be", ("resume={dir}",), "checkpoint.npz: a FIFO",
         setup=_checkpoint_fifo),
    Case("not a regular file", "a symlink loop as the robot file", ("robot=file", "robot.file={dir}/arm.yaml"),
         "arm.yaml: a symlink loop", setup=_loop("arm.yaml")),
    Case("not a regular file", "a symlink loop as the calibration file", MEASURED, "cal.csv: a symlink loop",
         setup=_loop("cal.csv")),
    # --- would be wrong with no warning -------------------------------------------------------------
    Case("duplicate columns", "x, y, z twice in the calibration file (a controller's, then the tracker's)", MEASURED,
         "line 1: duplicate column names ('x' in columns 7, 10;", files=(("cal.csv", "\n".join([TWICE, *TWICE_ROWS]) + "\n"),)),
    Case("duplicate columns", "a column twice in the validation file", VALIDATED, "val.csv, line 1: duplicate column names",
         files=(CAL, ("val.csv", "\n".join([HEAD + ",q2", *(r + ",0" for r in ROWS[:10])]) + "\n"))),
    Case("calibration data again", "the calibration file given again as the validation file",
         (*MEASURED, "problem.validation_file={dir}/cal.csv"), "problem.validation_file: all 40 rows", files=(CAL,)),
    Case("calibration data again", "a copy of the calibration file as the validation file", VALIDATED,
         "problem.validation_file: all 40 rows", files=(CAL, ("val.csv", CAL[1]))),
    Case("contradictory settings", "a validation file beside a validation fraction",
         (*VALIDATED, "problem.validation_fraction=0.25"), "problem.validation_file and problem.validation_fraction",
         files=(CAL, VAL)),
    Case("contradictory settings", "data in metres with length_unit=mm stated", (*MEASURED, "problem.length_unit=mm"),
         "they cannot be in mm (problem.length_unit=m?)", files=(("cal.csv", "\n".join([HEAD, *_points(scale=1)]) + "\n"),)),
    Case("contradictory settings", "data in mm with length_unit=m stated", (*MEASURED, "problem.length_unit=m"),
         "they cannot be in m (problem.length_unit=mm?)", files=(CAL,)),
    Case("missing setting", "rx, ry, rz in the calibration file without their convention", MEASURED,
         "cal.csv has orientation columns rx, ry, rz but no convention is stated: set it",
         files=(("cal.csv", "\n".join([HEAD + ",rx,ry,rz", *(r + ",0.1,0.2,0.3" for r in ROWS)]) + "\n"),)),
    # --- messages that missed the key ---------------------------------------------------------------
    Case("absurd value", "a negative seed", ("seed=-1",), "seed: must be a whole number >= 0, got -1"),
    Case("absurd value", "a negative problem seed", ("problem.seed=-3",), "problem.seed: must be a whole number >= 0"),
    Case("absurd value", "a CMA-ES population too small for its weights", ("algorithm=cmaes", "population.lambda_=1"),
         "population.lambda_: CMA-ES needs a population of at least 2"),
]


# --- the model's terms beyond geometry (problem.terms, zrp_ga.model.terms) --------------------------
# Run on the command line by the slow test below (and into docs/bad_inputs.md); the same settings are
# checked in-process, fast, by tests/test_terms.py::test_bad_terms_settings_are_one_line_naming_the_key.
TERMS_CASES = [
    Case("unknown key", "an unknown kind of model term", ("problem.terms={stiffness:[2]}",),
         "problem.terms: unknown key 'stiffness'; valid: compliance, harmonics, payload"),
    Case("absurd value", "joint 0 given compliance (joints count from 1)", ("problem.terms={compliance:[0]}",),
         "problem.terms.compliance: joint 0 is not a joint of puma560 (1..6)"),
    Case("absurd value", "harmonics of joint 7 of a six-joint arm", ("problem.terms={harmonics:[7]}",),
         "problem.terms.harmonics: joint 7 is not a joint of puma560 (1..6)"),
    Case("absurd value", "a negative harmonic order", ("problem.terms={harmonics:{order:-1,joints:[1]}}",),
         "problem.terms.harmonics.order: must be an integer 1..10, got -1"),
    Case("absurd value", "a negative payload mass", ("problem.terms={compliance:[2,3],payload:{mass:-5,com:[0,0,0.1]}}",),
         "problem.terms.payload: mass must be >= 0 kg"),
    Case("wrong type", "a joint number that is no whole number", ("problem.terms={compliance:[2.5]}",),
         "problem.terms.compliance: expected joint numbers (1-based integers), got 2.5"),
    Case("wrong type", "a mapping where the list of joints belongs", ("problem.terms={compliance:{joint:2}}",),
         "problem.terms.compliance: expected a list of joint numbers (1-based), got {'joint': 2}"),
    Case("wrong type", "a list where the mapping of terms belongs", ("problem.terms=[2,3]",),
         "problem.terms: expected a mapping such as"),
    Case("duplicate entry", "a joint named twice (two genes of one effect)", ("problem.terms={compliance:[2,2]}",),
         "problem.terms.compliance: joint 2 named twice"),
    Case("contradictory settings", "a payload without compliance", ("problem.terms={payload:{mass:5,com:[0,0,0.1]}}",),
         "problem.terms.payload: a payload acts through joint compliance; name the joints in problem.terms.compliance"),
    Case("missing setting", "a harmonic order without joints (fits nothing)", ("problem.terms={harmonics:{order:2}}",),
         "problem.terms.harmonics.joints: no joint named"),
]  # fmt: skip

def run_case(case: Case, folder: Path) -> subprocess.CompletedProcess:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in case.files:
        (folder / name).write_text(text)
    if case.setup is not None:
        case.setup(folder)
    args = [a.replace("{dir}", str(folder)) for a in case.args]
    if not any(a.startswith("hydra.run.dir=") for a in args):
        args.append(f"hydra.run.dir={folder}/run")
    env = {**os.environ, **dict(case.env)}
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args, "progress=false"], capture_output=True, text=True,
                          cwd=folder, env=env, timeout=TIMEOUT_S)  # fmt: skip


@pytest.mark.parametrize("case", CASES, ids=[f"{c.kind}: {c.what}" for c in CASES])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(case, tmp_path):
    proc = run_case(case, tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("zrp-ga: error: "), proc.stderr
    assert case.expect in lines[0], lines[0]
    assert not (tmp_path / "run").exists() and not (tmp_path / "outputs").exists()



@pytest.mark.slow
@pytest.mark.parametrize("case", TERMS_CASES, ids=[f"{c.kind}: {c.what}" for c in TERMS_CASES])
def test_bad_terms_are_one_line_exit_2_and_leave_nothing(case, tmp_path):
    test_bad_input_is_one_line_exit_2_and_leaves_nothing(case, tmp_path)

# --- the size budget ---------------------------------------------------------------------------------
@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_memory_estimate_bounds_the_measured_peak(tmp_path, monkeypatch):
    """The estimate is at least what the run allocates (tracemalloc's peak while the problem is
    built, diagnosed and optimised), and not wildly more."""
    import tracemalloc

    import zrp_ga

    (tmp_path / "arm.yaml").write_text(_arm(60))
    # The imports and compilations of a first run are not its data: the kernels compiled from the
    # start (left to themselves they run in numpy until they have spent 3 s there, and the run
    # that crosses that line imports numba and compiles, some 30 MB of Python objects, inside
    # the measurement; when depends on the machine's load).
    monkeypatch.setenv("ZRP_GA_KERNELS", "compiled")
    zrp_ga.calibrate("puma560", population={"generations": 1})
    for robot, settings in (("puma560", {"problem": {"n_poses": 1500}, "population": {"generations": 2}}),
                            (tmp_path / "arm.yaml", {"problem": {"n_validation": 20}, "population": {"generations": 1}})):  # fmt: skip
        over = [f"robot.{'name' if robot == 'puma560' else 'file'}={robot}"]
        over += [f"{k}.{key}={value}" for k, d in settings.items() for key, value in d.items()]
        need = budget.of_config(config.load(over), robots.load(**({"name": robot} if robot == "puma560" else {"file": str(robot)}))).bytes
        tracemalloc.start()
        try:
            zrp_ga.calibrate(robot, **settings)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak <= need <= 4 * peak, (robot, peak, need)


def test_a_refusal_names_the_largest_part_and_its_setting():
    from zrp_ga.algorithms import AlgorithmSize, genomes_bytes
    from zrp_ga.problems.size import calibration

    problem = calibration(n=6, genes=36, poses=10, validation=0, rows_per_pose=6)
    e = budget.estimate(problem, AlgorithmSize(10**7, None, genomes_bytes(10**7, 36)))
    # 10^7 genomes, each two residuals of 6 * 10 + 6 rows, its 36 genes twice and 600 bytes of
    # objects, and the margin of 25%
    need = 1.25 * 10**7 * (8 * (2 * 66 + 2 * 36) + 600)
    with pytest.raises(ValueError, match=r"^population: the run would need about 27\.9 GB .* lower population\.mu"):
        budget.check(e, available=need - 1)
    budget.check(e, available=need * 1.1)  # poses and genes add less than 10%


def test_available_memory_and_its_override(monkeypatch):
    assert budget.parse_bytes("8G") == 8 * 2**30 and budget.parse_bytes("500M") == 500 * 2**20
    assert budget.parse_bytes("1234") == 1234.0
    with pytest.raises(ValueError, match="ZRP_GA_MEMORY"):
        budget.parse_bytes("lots")
    assert budget.available_bytes({"ZRP_GA_MEMORY": "2G"}) == 2 * 2**30
    meminfo = Path("/proc/meminfo")
    if meminfo.exists():
        kb = next(int(line.split()[1]) for line in meminfo.read_text().splitlines() if line.startswith("MemAvailable:"))
        assert budget.available_bytes({}) <= kb * 1024 * 1.2  # it moves while we look; a process limit may be less


def test_file_rows_are_estimated_from_the_size(tmp_path):
    from zrp_ga.problems.size import file_rows

    path = tmp_path / "cal.csv"
    path.write_text("\n".join([HEAD, *_points(3000)]) + "\n")
    assert abs(file_rows(path) - 3001) <= 0.02 * 3001
    size = measured.size(robots.get("ur10"), calibration_file=str(path))
    # 3 rows per pose of the about 3001 rows, the 6 unit-length rows; 6 x 6 + 3 genes (the base point)
    assert abs(size.rows - (3 * 3001 + 6)) <= 3 * 60 and size.genes == 6 * 6 + 3
    assert size.lower["poses"][0] == "problem.calibration_file"


# --- regular files -----------------------------------------------------------------------------------
def test_regular_file_says_what_is_there(tmp_path):
    (tmp_path / "f").write_text("x")
    assert files.regular_file(tmp_path / "f", "a file") == tmp_path / "f"
    (tmp_path / "to_f").symlink_to(tmp_path / "f")
    assert files.regular_file(tmp_path / "to_f", "a file") == tmp_path / "to_f"  # a symlink to a file is one
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "dangling").symlink_to(tmp_path / "nothing")
    _loop("loop")(tmp_path)
    for name, message in (("pipe", "a FIFO (named pipe), not a regular file; expected a file"),
                          ("loop", "a symlink loop"), ("dangling", "a broken symlink"), ("nothing", "no such file"),
                          (".", "is a directory, expected a file")):  # fmt: skip
        with pytest.raises(ValueError, match=re.escape(message)):
            files.regular_file(tmp_path / name, "a file")
    with pytest.raises(ValueError, match="no checkpoint there"):
        files.regular_file(tmp_path / "nothing", "a checkpoint", missing="no checkpoint there")


@pytest.mark.parametrize("data", [[[0.0] * 9], pd.DataFrame({"x": [1.0]}), np.zeros((3, 9))], ids=["list", "DataFrame", "array"])
def test_data_that_is_no_path_is_a_clear_type_error(data):
    fmt = measurements.zrp_format(6)
    with pytest.raises(TypeError, match=r"^measurement data: expected a file path .* or, for data in memory, "
                                        r"zrp_ga.model.poses.Measurements\(q, p\)"):  # fmt: skip
        measurements.read(data, fmt, robots.get("ur10"))


# --- calibration rows again ------------------------------------------------------------------------
def _read(rows: list[str], name: str, folder: Path) -> Measurements:
    path = folder / name
    path.write_text("\n".join([HEAD, *rows]) + "\n")
    return measurements.read(path, measurements.zrp_format(6, "mm"), robots.get("ur10"))


def test_some_calibration_rows_in_the_validation_file_are_a_warning_naming_them(tmp_path):
    calib = _read(ROWS, "cal.csv", tmp_path)
    val = _read(_points(20, seed=1)[:17] + [ROWS[4], ROWS[9], ROWS[14]], "val.csv", tmp_path)
    # lines count from the header (line 1): ROWS[4] is line 6 of cal.csv, ROWS[9] line 11
    assert measurements.shared_rows(calib, val) == [(19, 6), (20, 11), (21, 16)]
    conf = schema.section(schema.MeasuredConf, {"calibration_file": "x"}, "problem")
    task = measured.from_measurements(robots.get("ur10"), calib, val, conf)
    assert any(w.startswith("3 of the 20 rows of the validation data") and "19 = 6, 20 = 11, 21 = 16" in w for w in task.warnings)
    with pytest.raises(ValueError, match="problem.validation_file: all 40 rows"):
        measured.from_measurements(robots.get("ur10"), calib, calib, conf)
    assert measurements.shared_rows(calib, _read(_points(20, seed=1), "v2.csv", tmp_path)) == []


def test_checks_name_their_keys():
    with pytest.raises(ValueError, match="^seed: must be a whole number >= 0, got -1$"):
        checks.seed(-1, "seed")
    checks.seed(0, "seed")
    checks.seed(None, "problem.seed")
    with pytest.raises(ValueError, match="^population.lambda_: CMA-ES needs a population of at least 2"):
        checks.cmaes_population(1)
    checks.cmaes_population(2)
    with pytest.raises(ValueError, match="^problem.validation_file and problem.validation_fraction"):
        schema.section(schema.MeasuredConf, {"calibration_file": "a", "validation_file": "b", "validation_fraction": 0.2}, "problem")


# --- the report: values that are no cost ----------------------------------------------------------------
def _fake_run(run: Path, best: str, final: float | None = 0.1, first: str = "0.2") -> None:
    run.mkdir()
    (run / "summary.json").write_text(json.dumps({"instance": "x", "nevals": 10, "final_cost": final}))
    (run / "convergence.csv").write_text(f"gen,nevals,best\n0,5,{first}\n1,10,{best}\n")


@pytest.mark.parametrize("value", ["-inf", "nan", "-0.5"])
def test_a_run_with_a_cost_that_is_none_is_left_out_by_name(tmp_path, value):
    """-inf would reach every target, NaN none, and neither nor a negative number is a cost (a
    norm); the app never writes them (its best starts at +inf and takes finite costs only)."""
    from zrp_ga.report import runs

    _fake_run(tmp_path / "good", "0.1")
    _fake_run(tmp_path / "bad", value)
    found, left = runs.find_runs([tmp_path])
    assert [r.path.name for r in found] == ["good"]
    why = f"convergence.csv line 3: best is '{value}', not a cost (a cost is >= 0, or inf when diverged)"
    assert left == [(str(tmp_path / "bad"), why)]


def test_a_diverged_run_is_kept_as_reaching_nothing_and_a_nan_final_cost_left_out(tmp_path):
    """+inf is what a diverged run writes (no finite cost seen): it counts, reaching no target
    (tests/test_report_benchmark.py ranks it); a final cost of NaN is left out by name."""
    from zrp_ga.report import runs, targets

    _fake_run(tmp_path / "diverged", "inf", final=None, first="inf")
    _fake_run(tmp_path / "nan", "0.1", final=float("nan"))
    found, left = runs.find_runs([tmp_path])
    assert [r.path.name for r in found] == ["diverged"] and math.isinf(targets.first_hit(found[0].evals, found[0].best, 1e9))
    assert left == [(str(tmp_path / "nan"), "summary.json: 'final_cost' is nan")]


@pytest.mark.slow
def test_out_of_memory_while_preparing_is_one_line_and_not_done_twice(tmp_path):
    """When the estimate is overridden (``ZRP_GA_MEMORY``) and memory runs out while the run is
    prepared, the MemoryError is one line, exit code 2, no run directory: not a Hydra warning
    followed by the same work again (4 GB of address space for ten-fold the poses it holds)."""
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))

    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "problem=multipose", "problem.n_poses=3000000", "progress=false",
                           f"hydra.run.dir={tmp_path}/run"], capture_output=True, text=True, cwd=tmp_path, preexec_fn=limit,
                          env={**os.environ, "ZRP_GA_MEMORY": "100G"}, timeout=1200)  # fmt: skip
    # numba's notice that it compiles the kernels again (a first run at this path) is not the error
    lines = [line for line in proc.stderr.strip().splitlines() if not line.startswith("compiling the kernels")]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith("zrp-ga: error: out of memory before the run started (Unable to allocate")
    assert not (tmp_path / "run").exists()
