"""Write docs/bad_inputs.md: every class of bad input, an example command, and the one line the
program prints for it, by running the cases of tests/test_bad_inputs.py and
tests/test_bad_inputs_more.py (``zrp-ga``), a few of ``zrp-ga-report``, and those of
tests/test_compensation_inputs.py (``zrp-ga-compensate`` and ``zrp_ga.compensate``) and
tests/test_api_inputs.py (``zrp_ga.calibrate``).

    python experiments/bad_inputs.py
"""

from __future__ import annotations

import importlib.util
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _cases(name: str = "test_bad_inputs"):
    spec = importlib.util.spec_from_file_location(name, ROOT / "tests" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _report_rows(folder: Path) -> list[tuple[str, str, str, str]]:
    """zrp-ga-report on a missing folder, on a file, and on a good run beside a truncated one and
    one holding a cost of -inf."""
    (folder / "afile").write_text("x")
    subprocess.run([sys.executable, "-m", "zrp_ga.cli", "problem.n_validation=5", "population.generations=2", "progress=false",
                    f"hydra.run.dir={folder / 'runs' / 'good'}"], check=True, capture_output=True)  # fmt: skip
    import shutil

    fifo = folder / "runs" / "fifo"  # a copy of the good run whose convergence.csv is a FIFO (a named pipe)
    shutil.copytree(folder / "runs" / "good", fifo)
    (fifo / "convergence.csv").unlink()
    os.mkfifo(fifo / "convergence.csv")
    for name, last in (("broken", "0."), ("minus-inf", "-inf\n")):
        run = folder / "runs" / name
        run.mkdir(parents=True)
        (run / "summary.json").write_text('{"instance": "x", "nevals": 10, "final_cost": 0.1}')
        (run / "convergence.csv").write_text(f"gen,nevals,best\n0,5,0.2\n1,10,{last}")
    rows = []
    for kind, what, args in (("missing path", "a report input that does not exist", ["nothere"]),
                             ("wrong kind of path", "a file given as a run folder", ["afile"]),
                             ("corrupted file", "a run whose convergence.csv was cut short (left out, named, the rest go on)",
                              ["runs"])):  # fmt: skip
        proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli.report", *args, "--out", "rep", "--formats", "none"],
                              capture_output=True, text=True, cwd=folder)  # fmt: skip
        out = (proc.stderr.strip() or proc.stdout.strip()).splitlines()
        said = [x for x in out if "error" in x or "left out" in x] or out[:1]
        for line in said:
            k, w = kind, what
            if "minus-inf" in line:  # the run beside the truncated one
                k, w = "non-finite number", "a run whose convergence.csv holds -inf (left out, named, the rest go on)"
            if "FIFO" in line:
                k, w = "report: not a regular file", "a run whose convergence.csv is a FIFO (left out unread, named, the rest go on)"
            rows.append((k, w, "zrp-ga-report " + " ".join(args), line))
    return rows


def _run_directory_rows(folder: Path) -> list[tuple[str, str, str, str]]:
    """zrp-ga resuming a run whose robot file changed since its checkpoint, and a run into a
    directory another run is writing into (its lock held here)."""
    from zrp_ga.io import presets
    from zrp_ga.run import directory

    arm = folder / "arm.yaml"
    arm.write_text(presets.path("puma560").read_text())
    subprocess.run([sys.executable, "-m", "zrp_ga.cli", "robot=file", f"robot.file={arm}", "problem.n_validation=5",
                    "population.generations=2", "progress=false", f"hydra.run.dir={folder / 'run'}"],
                   check=True, capture_output=True)  # fmt: skip
    arm.write_text(arm.read_text().replace("a: 0.4318", "a: 0.4500"))
    cases = [("changed input", "resuming a run whose robot file changed since its checkpoint", ["resume=DIR/run"])]
    rows = []
    for kind, what, args in cases:
        proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", *(a.replace("DIR", str(folder)) for a in args)],
                              capture_output=True, text=True, cwd=folder)  # fmt: skip
        rows.append((kind, what, "zrp-ga " + " ".join(args), f"{proc.stderr.strip()} (exit {proc.returncode})"))
    busy = folder / "busy"
    busy.mkdir()
    with directory.locked(busy):
        proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "problem.n_validation=5", "population.generations=2",
                               f"hydra.run.dir={busy}"], capture_output=True, text=True, cwd=folder)  # fmt: skip
    line = proc.stderr.strip().replace(f"process {os.getpid()}", "process PID")
    rows.append(("directory in use", "a run into a directory another run is writing into",
                 "zrp-ga hydra.run.dir=DIR/busy ...", f"{line} (exit {proc.returncode})"))  # fmt: skip
    return [(k, w, c, line.replace(str(folder), "DIR")) for k, w, c, line in rows]


def _compensation_rows(folder: Path) -> list[tuple[str, str, str, str]]:
    """zrp-ga-compensate's cases, and zrp_ga.compensate called from Python with bad arguments."""
    module = _cases("test_compensation_inputs")
    rows = []
    for k, case in enumerate(module.CASES):
        where = folder / str(k)
        err, code = module.run_case(case, where)
        args = " ".join([*(f"{a}={b}" for a, b in case.env), "zrp-ga-compensate",
                         *(shlex.quote(a.replace("{dir}", "DIR")) for a in case.args)])  # fmt: skip
        rows.append((case.kind, case.what, args, f"{err.strip().replace(str(where), 'DIR')} (exit {code})"))
    for what, settings, error, _ in module.API_CASES:
        try:
            module.call_api(settings)
            said = "no error"
        except error as exc:
            said = f"{type(exc).__name__}: {exc}"
        shown = ", ".join(f"{k}={_short(v)}" for k, v in settings.items())
        rows.append(("Python argument", what, f"zrp_ga.compensate(..., {shown})", said.replace(str(ROOT), "REPO")))
    return rows


def _api_rows(folder: Path) -> list[tuple[str, str, str, str]]:
    """zrp_ga.calibrate given bad data, seeds or output directories (the cases of
    tests/test_api_inputs.py and tests/test_api_data.py): the exception each raises, on one line."""
    import numpy as np

    import zrp_ga

    api = _cases("test_api_inputs")
    Q, P, R = api.Q, api.P, api.R_TRUE
    (folder / "afile").write_text("x")
    (folder / "held").mkdir()
    (folder / "held" / "summary.json").write_text("{}")
    mirror, sheared = api._bad_rotations(4, "mirror"), api._bad_rotations(17, "sheared")
    cases = [
        ("API: validation alone", "validation data without calibration data", "calibrate(arm, validation=(q, p))",
         dict(validation=(Q, P))),
        ("API: seed", "a string as the seed", 'calibrate(arm, (q, p), seed="abc")', dict(data=(Q, P), seed="abc")),
        ("API: seed", "a float among the seeds", "calibrate(arm, (q, p), seed=[0, 1.5])", dict(data=(Q, P), seed=[0, 1.5])),
        ("API: lossy numbers", "positions in float16 (mm)", "calibrate(arm, (q, p_mm.astype(np.float16)))",
         dict(data=(Q, (1e3 * P).astype(np.float16)))),
        ("API: lossy numbers", "complex positions", "calibrate(arm, (q, p.astype(complex)))", dict(data=(Q, P.astype(complex)))),
        ("API: not a rotation", "a mirrored rotation matrix in row 4", "calibrate(arm, (q, p, R))", dict(data=(Q, P, mirror))),
        ("API: not a rotation", "a rotation matrix sheared by 1e-5 in row 17 of the validation data",
         "calibrate(arm, (q, p, R), validation=(q, p, R_bad))", dict(data=(Q, P, R), validation=(Q, P, sheared))),
        ("API: output directory", "a file where the run directory should go", "calibrate(arm, (q, p), out=DIR/afile/run)",
         dict(data=(Q, P), out=folder / "afile" / "run")),
        ("API: output directory", "a directory that holds a run", "calibrate(arm, (q, p), out=DIR/held)",
         dict(data=(Q, P), out=folder / "held")),
        ("API: output directory", "a list as the output directory", 'calibrate(arm, (q, p), out=["a"])',
         dict(data=(Q, P), out=["a"])),
    ]  # fmt: skip
    rows = []
    for kind, what, call, kwargs in cases:
        try:
            zrp_ga.calibrate(api.ARM, algorithm="lm", **kwargs)
            said = "no error"
        except (TypeError, ValueError) as exc:
            said = f"{type(exc).__name__}: {exc}"
        rows.append((kind, what, f"zrp_ga.{call}", said.replace(str(folder), "DIR")))
    return rows


def _short(v) -> str:
    """A value as a call shows it: arrays by shape."""
    import numpy as np

    if isinstance(v, np.ndarray):
        return f"<array {v.shape}>"
    return repr(v) if not isinstance(v, Path) else f"Path({v.name!r})"


def main() -> None:
    cases = [(module, case) for module in (_cases(), _cases("test_bad_inputs_more"))
             for case in [*module.CASES, *getattr(module, "TERMS_CASES", ())]]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (module, case) in enumerate(cases):
            folder = Path(tmp) / str(k)
            proc = module.run_case(case, folder)
            line = proc.stderr.strip().replace(str(folder), "DIR")
            args = " ".join([*(f"{k}={v}" for k, v in getattr(case, "env", ())), "zrp-ga",
                             *(a.replace("{dir}", "DIR") for a in case.args)])  # fmt: skip
            rows.append((case.kind, case.what, args, f"{line} (exit {proc.returncode})"))
        report = Path(tmp) / "report"
        report.mkdir()
        rows += [(k, w, c, line.replace(str(report), "DIR")) for k, w, c, line in _report_rows(report)]
        runs = Path(tmp) / "runs"
        runs.mkdir()
        rows += _run_directory_rows(runs)
        comp = Path(tmp) / "compensation"
        comp.mkdir()
        rows += _compensation_rows(comp)
        api = Path(tmp) / "api"
        api.mkdir()
        rows += _api_rows(api)
    lines = ["# Bad input and what the program says", "",
             "Every input the programs read is checked before any work: a bad one stops `zrp-ga` with one line "
             "on stderr, exit code 2, and no run directory (a report leaves out a damaged run by name and goes on). "
             "Every file read must be a regular file (a FIFO, device or socket is refused, a symlink loop named as "
             "one). A run, or a sweep's largest job (once, before any job starts), that would not fit the memory "
             "this process may use (the least of the machine's available memory, `ulimit -v` and `-d`, and the "
             "cgroup's memory limit of a container or cluster job) is refused with the estimate, the limit that "
             "binds and the setting to lower (`zrp_ga.run.budget`; the environment variable `ZRP_GA_MEMORY`, e.g. "
             "`8G`, replaces the limits); one estimated to take more than ten minutes is announced. `zrp_ga.calibrate` checks "
             "data given in memory as a file is checked (and rotation matrices against R^T R = I, det R = +1 within 1e-6; "
             "float16 refused), its seeds and its output directory before any work, raising one ValueError or TypeError line. "
             "`DIR` stands for the folder of the example. Written by `python experiments/bad_inputs.py` from the "
             "cases of `tests/test_bad_inputs.py`, `tests/test_bad_inputs_more.py`, `tests/test_compensation_inputs.py` and "
             "`tests/test_api_inputs.py`, which "
             "check each of them. `zrp-ga-compensate` checks its inputs as `zrp-ga` does (regular files, units from the data, "
             "duplicate columns, rotations, the output directory and the size before any work); `zrp_ga.compensate` called "
             "with a wrong kind of argument raises a TypeError or ValueError naming it.", "",
             "| class | example | command | what it prints |", "| --- | --- | --- | --- |"]  # fmt: skip
    for kind, what, command, line in rows:
        cell = lambda t: t.replace("|", "\\|")
        lines.append(f"| {kind} | {what} | `{cell(command)}` | {cell(line)} |")
    (ROOT / "docs" / "bad_inputs.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
