"""Sweeps at the speed of the kernel: what a sweep costs beyond its pose evaluations, and whether
its results stay the same.

    python experiments/bench_sweep.py [--repeats 3] [--big-seeds 210] [--studies [NAME ...]]
                                      [--before REV] [--hydra-launchers] [--sweeper basic] [--out DIR]

One command, on this machine's cores, writing results/bench_sweep.md:

- **The 144-run operator grid** (``zrp-ga -m experiment=operator_grid hydra/launcher=local``: 4
  crossovers x 3 mutations x 2 inversions x 2 rotations x 3 seeds of the 30-pose problem at 5,000
  evaluations): wall time, CPU time of all its processes (medians of ``--repeats``, with the
  range; the load average before and after), and its ratio to the **kernel-only time** of the
  same pose evaluations, measured in the same run of this script: the sweep's pose evaluations
  (the sum over its runs of ``nevals`` in summary.json times the instance's poses) at the speed
  of the problem's vectorised cost (``task.problem.costs``, the instance built as a run builds
  it), called on random genomes on one core (one BLAS thread), in batches of one run's offspring
  (50) and of a lockstep batch (the 48 runs of an instance x 50 offspring). Both ratios: wall
  time on all cores over the single-core kernel time, and over that time shared by the cores.
  From the runs' convergence.csv (``eval_s``, ``bookkeeping_s``, ``refine_s``): the
  generations' time, and the per-run overhead (wall x cores - generations' time) / runs, what
  a run costs outside its generations (composition, building, diagnostics, files).
- **One grid job as a process of its own** (as a launcher with a process per job runs it).
- **Identical curves**: the grid again with ``hydra.launcher.lockstep=false`` (every job alone),
  each run's convergence.csv (without the timing columns) and summary.json (without timing and
  versions) compared with the same run of the first timed sweep
  (``reference_runs.run_differences``).
- **A study of ``--big-seeds`` x 48 runs** (the grid's 48 operator sets with that many seeds;
  default 210: 10,080 runs; 0 skips it): wall time, CPU time, every manifest job done.
- **A default run** (``zrp-ga``, the paper's case study): the command's wall and CPU time, the
  run's own compute (``wall_s`` in its summary.json) and the difference, its fixed cost; the
  import time of the modules a run loads (``python -X importtime``).
- ``--studies [NAME ...]``: committed studies run again (their sweeps with zrp_ga's launcher,
  their reports with the committed options, without figures) and their tables' medians and
  quartiles compared with the committed ones (see :data:`STUDIES`; without names the cheap ones,
  :data:`CHEAP`).
- ``--sweeper basic``: the current code's sweeps (the grid, its lockstep=false twin, the big study)
  with Hydra's basic sweeper (``hydra/sweeper=basic``) instead of zrp_ga's, ``-m``'s default.
- ``--before REV``: the default run and the grid with the code of git revision ``REV`` too,
  from a copy of that tree on ``PYTHONPATH``. ``--hydra-launchers``: the grid with Hydra's
  joblib launcher too (and its basic one with ``--before``); they take minutes.

Variants are run in turn, ``--repeats`` times, so that the load of a shared machine falls on all
of them. Files of the sweeps stay in ``--out`` (default: a new temporary directory), with the
numbers in its raw.json, written as they come; ``--from-raw DIR`` writes the report again from
them.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
import reference_runs

RESULTS = Path(__file__).parent / "results"
ROOT = Path(__file__).resolve().parents[1]
GRID = ["experiment=operator_grid"]
LAUNCHERS = {"basic": [], "joblib": ["hydra/launcher=joblib"], "zrp_ga": ["hydra/launcher=local"]}
LOCAL = LAUNCHERS["zrp_ga"]
SWEEPERS = {"basic": ["hydra/sweeper=basic"], "zrp_ga": []}  # zrp_ga's: -m's default since ea076e7 (hparams_search=none)
RUN_MODULES = ("zrp_ga.cli.main zrp_ga.io.presets zrp_ga.problems.simulated zrp_ga.algorithms.ga zrp_ga.operators "
               "zrp_ga.run.callbacks zrp_ga.run.summary zrp_ga.io.records zrp_ga.run.checkpoint threadpoolctl")  # fmt: skip
OFFSPRING = 50  # lambda of the grid's runs
# The committed studies (experiments/README.md): their sweeps (experiment configs), and per report
# the options that made the committed tables and those tables (a committed name: the report's file
# of that name; "committed=report's": a report's file kept under another name).
STUDIES = {
    "paper_study": (["paper_study"], [(["--target", "0.0027"], ["paper_study/summary.md"])]),
    "operator_study": (["operator_study"], [(["--only", "refine=none"], ["operator_study/summary.md"]),
                                            ([], ["operator_study/summary_with_and_without_the_step.md=summary.md"])]),
    "population_sweep": (["population_sweep"], [([], ["population_sweep/summary.md"])]),
    "methods": (["methods_ga", "methods_baselines"], [([], ["methods/summary.md"])]),
    "heldout": (["heldout", "heldout_blend", "heldout_tuned"], [([], ["heldout/summary.md", "heldout/per_instance.md"])]),
    "suite_factors": (["suite_factors"], [([], ["suite_factors/summary.md"])]),
    "operator_suite": (["operator_suite"], [([], ["operator_suite/summary.md"])]),
}  # fmt: skip
# What --studies runs without names: 60 + 480 + 50 runs. On the code before lockstep (3befbdd),
# with the machine's load average at 5 - 8 on its 2 cores: 52 s, about 12 min and 3 min. The others
# take longer (methods: 50,000-evaluation GA and CMA-ES runs; heldout: 150 runs and suite_factors
# 180 runs of 20,000 evaluations; operator_suite: 864 runs, 617 - 1,548 s in experiments/README.md).
CHEAP = ["paper_study", "operator_study", "population_sweep"]
LEFT_OUT = ("Not re-run by this script: the pose-selection studies (their own script, experiments/pose_selection.py, and "
            "50,000-evaluation runs on the UR10's 1,495 rows: the operators study alone took 2,198 s, experiments/README.md "
            "section h), the Optuna tuning (an extra install, `.[tune]`) and the peers (other packages, `.[peers]`).")  # fmt: skip


def tree(rev: str, where: Path) -> Path:
    """The code of git revision ``rev`` in ``where``, importable from ``PYTHONPATH``."""
    where.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
    if not (where / "zrp_ga" / "conf").exists():
        (where / "zrp_ga" / "conf").symlink_to(where / "conf")  # as the installed package ships it
    return where


def command(args: list[str], code: Path | None, cwd: Path,
            module: str = "zrp_ga.cli") -> tuple[float, float, subprocess.CompletedProcess]:  # fmt: skip
    """Wall and CPU seconds (all processes) of ``python -m MODULE ARGS``."""
    env = dict(os.environ, PYTHONPATH=str(code)) if code else dict(os.environ)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise RuntimeError(f"{module} {' '.join(args)}: {proc.stderr[-2000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), proc


def manifest(sweep: Path) -> list[dict]:
    last = {}
    for line in (sweep / "manifest.jsonl").read_text().splitlines():
        if line.strip():
            record = json.loads(line)
            last[record["job"]] = record
    return list(last.values())


def default_run(code: Path | None, work: Path, k: int) -> dict:
    out = work / f"run-{k}"
    wall, cpu, _ = command([f"hydra.run.dir={out}"], code, work)
    compute = json.loads((out / "summary.json").read_text())["wall_s"]
    return {"wall_s": wall, "cpu_s": cpu, "compute_s": compute, "fixed_s": wall - compute, "fixed_cpu_s": cpu - compute}


def grid_job(code: Path | None, work: Path, k: int) -> dict:
    """One job of the grid as a process of its own, as a launcher that starts one per job
    (submitit on SLURM) runs it."""
    out = work / f"grid-job-{k}"
    job = ["crossover=sbx", "mutation=gaussian", "inversion=segment", "rotation=segment", f"seed={k % 3}"]
    wall, cpu, _ = command([*GRID, "hydra.mode=RUN", *job, f"hydra.run.dir={out}"], code, work)
    compute = json.loads((out / "summary.json").read_text())["wall_s"]
    return {"wall_s": wall, "cpu_s": cpu, "compute_s": compute, "fixed_s": wall - compute}


def sweep(args: list[str], code: Path | None, work: Path, name: str, poses: int | None = None) -> dict:
    """Wall and CPU time of a sweep, its jobs done, and from its runs' files: their compute (sum of
    ``wall_s``), their evaluations, pose evaluations (``poses`` per evaluation) and generations'
    time (sum of convergence.csv's ``eval_s``, ``bookkeeping_s``, ``refine_s``)."""
    where = work / name
    started = time.time()
    wall, cpu, proc = command([*args, f"hydra.sweep.dir={where}"], code, work)
    jobs = manifest(where)
    done = [j for j in jobs if j["status"] == "done"]
    compute = nevals = generations = 0.0
    for j in done:
        run = where / str(j["dir"])
        summary = json.loads((run / "summary.json").read_text())
        compute += summary["wall_s"]
        nevals += summary["nevals"]
        curve = pd.read_csv(run / "convergence.csv", usecols=["eval_s", "bookkeeping_s", "refine_s"])
        generations += float(curve.to_numpy().sum())
    return {"wall_s": wall, "cpu_s": cpu, "compute_s": compute, "runs": len(jobs), "done": len(done),
            "nevals": nevals, "pose_evals": nevals * poses if poses else None, "generations_s": generations,
            "dir": str(where), "launch_s": launched(proc.stdout + proc.stderr, started)}  # fmt: skip


def launched(log: str, started: float) -> float | None:
    """Seconds from ``started`` (epoch) to the sweep's log line ``Launching N jobs`` (Hydra's
    sweeper has checked every job, the launcher's workers are ready); None without one."""
    found = re.search(r"^\[(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3})\]\[HYDRA\] Launching \d+ jobs", log, re.M)
    if not found:
        return None
    return datetime.datetime.strptime(found.group(1), "%Y-%m-%d %H:%M:%S,%f").timestamp() - started


def grid_problem():
    """The grid's problem instance (seed 0; the seeds' instances differ in values only), built as
    a run builds it."""
    from zrp_ga import config
    from zrp_ga.run.build import prepare

    return prepare(config.load(GRID), None).task.problem


def kernel_rates(problem, batches: list[int], seconds: float = 0.5) -> dict[str, float]:
    """Pose evaluations per second of ``problem.costs`` on one core (one BLAS thread, the
    kernel's one thread), per batch size (genomes per call): random genomes within the gene
    ranges, the median of 5 timings of about ``seconds`` each; by wall time (key ``B``) and by
    the process's CPU time (key ``B cpu``), which a loaded machine slows less."""
    from unittest import mock

    from threadpoolctl import threadpool_limits

    rng = np.random.default_rng(0)
    rates = {}
    with threadpool_limits(limits=1), mock.patch.dict(os.environ, ZRP_GA_KERNELS="compiled"):  # not the numpy twins
        for b in batches:
            X = rng.uniform(problem.lower, problem.upper, (b, problem.lower.size))
            problem.costs(X)  # compiled and cached outside the timing
            t0 = time.perf_counter()
            problem.costs(X)
            calls = max(1, int(seconds / max(time.perf_counter() - t0, 1e-6)))
            walls, cpus = [], []
            for _ in range(5):
                t0, c0 = time.perf_counter(), time.process_time()
                for _ in range(calls):
                    problem.costs(X)
                walls.append((time.perf_counter() - t0) / calls)
                cpus.append((time.process_time() - c0) / calls)
            rates[str(b)] = b * problem.data.M / statistics.median(walls)
            rates[f"{b} cpu"] = b * problem.data.M / max(statistics.median(cpus), 1e-9)
    return rates


def identical(a: Path, b: Path) -> tuple[int, int, list[str]]:
    """Runs of sweep ``b`` equal to the same job's run in sweep ``a``: (equal, jobs, the first
    differences named)."""
    ja, jb = ({j["job"]: j for j in manifest(s)} for s in (a, b))
    same, named = 0, []
    for job in sorted(set(ja) | set(jb), key=str):
        if job not in ja or job not in jb:
            named.append(f"job {job}: only in the {'first' if job in ja else 'second'} sweep")
            continue
        diffs = reference_runs.run_differences(a / str(ja[job]["dir"]), b / str(jb[job]["dir"]))
        same += not diffs
        if diffs and len(named) < 10:
            named.append(f"job {job} ({ja[job]['dir']}): " + "; ".join(diffs))
    return same, len(set(ja) | set(jb)), named


def table(path: Path) -> dict[tuple, dict[str, str]]:
    """A Markdown table's rows by their key (the cells before ``runs``; the first cell if there is
    none), each its medians, quartiles and runs as written."""
    lines = [line for line in path.read_text().splitlines() if line.startswith("|")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    n_key = head.index("runs") if "runs" in head else 1
    kept = [c for c in head if c == "runs" or c.endswith(("_median", "_q1", "_q3"))]
    rows = {}
    for line in lines[2:]:
        cells = dict(zip(head, (c.strip() for c in line.strip("|").split("|"))))
        rows[tuple(cells[c] for c in head[:n_key])] = {c: cells[c] for c in kept}
    return rows


def table_differences(committed: Path, new: Path) -> list[str]:
    """The medians, quartiles and run counts of ``new`` that differ from ``committed``'s."""
    a, b = table(committed), table(new)
    out = [f"row {' / '.join(k)}: only in the {'committed' if k in a else 'new'} table" for k in a.keys() ^ b.keys()]
    for key in a.keys() & b.keys():
        out += [f"{' / '.join(key)}, {c}: {a[key][c]} committed, {b[key].get(c)} now"
                for c in a[key] if a[key][c] != b[key].get(c)]  # fmt: skip
    return out


def study(name: str, work: Path) -> dict:
    """Run the committed study ``name`` again (zrp_ga's launcher), report it as committed
    (no figures) and compare its tables with the committed ones."""
    experiments, reports = STUDIES[name]
    where = work / "studies" / name
    wall = cpu = 0.0
    runs = done = 0
    for e in experiments:
        w, c, _ = command([f"experiment={e}", *LOCAL, f"hydra.sweep.dir={where / e}"], None, work)
        jobs = manifest(where / e)
        wall, cpu, runs, done = wall + w, cpu + c, runs + len(jobs), done + sum(j["status"] == "done" for j in jobs)
    differences = {}
    for k, (options, files) in enumerate(reports):
        out = work / "studies" / f"{name}-report-{k}"
        w, c, _ = command([str(where), "--out", str(out), "--formats", "none", *options], None, work, "zrp_ga.report")
        wall, cpu = wall + w, cpu + c
        for f in files:
            committed, _, made = f.partition("=")
            differences[committed] = table_differences(RESULTS / committed, out / (made or Path(committed).name))
    return {"wall_s": wall, "cpu_s": cpu, "runs": runs, "done": done, "differences": differences}


def import_s(code: Path | None, work: Path) -> float:
    """Seconds to import the modules a run loads (``-X importtime``, cumulative, top level)."""
    env = dict(os.environ, PYTHONPATH=str(code)) if code else dict(os.environ)
    mods = ", ".join(RUN_MODULES.split())
    proc = subprocess.run([sys.executable, "-X", "importtime", "-c", f"import {mods}"], capture_output=True, text=True,
                          env=env, cwd=work)  # fmt: skip
    tops = [int(m.group(1)) for m in re.finditer(r"import time:\s+\d+ \|\s+(\d+) \| (?! )", proc.stderr)]
    return sum(tops) / 1e6


def load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def med(rows: list[dict], key: str, fmt: str = ".2f") -> str:
    values = [r[key] for r in rows]
    return f"{statistics.median(values):{fmt}} ({min(values):{fmt}} - {max(values):{fmt}})"


def cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--big-seeds", type=int, default=210,
                        help="seeds of the big study: 48 runs each (210: 10,080 runs; 0: none)")  # fmt: skip
    parser.add_argument("--studies", nargs="*", default=None, metavar="NAME",
                        help=f"committed studies to run again and compare ({', '.join(STUDIES)}, or all; "
                             f"no name: {', '.join(CHEAP)})")  # fmt: skip
    parser.add_argument("--before", default=None, help="git revision to compare with (e.g. 3befbdd)")
    parser.add_argument("--hydra-launchers", action="store_true", help="the grid with Hydra's launchers too (minutes)")
    parser.add_argument("--sweeper", choices=list(SWEEPERS), default="zrp_ga",
                        help="the sweeper of the current code's sweeps (basic: hydra/sweeper=basic, Hydra's)")  # fmt: skip
    parser.add_argument("--kernel-batches", default=f"{OFFSPRING},{48 * OFFSPRING}",
                        help="genomes per kernel call of the kernel-only timing (one run's offspring; a lockstep batch)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--from-raw", type=Path, default=None, metavar="DIR",
                        help="write the report again from DIR/raw.json (a finished run's numbers), measuring nothing")  # fmt: skip
    args = parser.parse_args()
    if args.from_raw:
        if not (args.from_raw / "raw.json").is_file():
            parser.error(f"--from-raw: no raw.json in {args.from_raw}")
        raw = json.loads((args.from_raw / "raw.json").read_text())
        write(report(raw))
        return
    studies = CHEAP if args.studies == [] else list(STUDIES) if args.studies == ["all"] else args.studies or []
    unknown = [s for s in studies if s not in STUDIES]
    if unknown:
        parser.error(f"--studies: no study {', '.join(unknown)} (choose from {', '.join(STUDIES)}, or all)")
    try:
        batches = [int(b) for b in args.kernel_batches.split(",")]
    except ValueError:
        parser.error(f"--kernel-batches: whole numbers separated by commas, got {args.kernel_batches!r}")
    work = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    codes = {"after": None}
    if args.before:
        codes[f"before ({args.before})"] = tree(args.before, work / "before-tree")
    problem = grid_problem()
    poses = problem.data.M
    raw: dict = {"runs": {c: [] for c in codes}, "grids": {}, "jobs": [], "kernel": [], "load_before": load(), "poses": poses,
                 "args": {"repeats": args.repeats, "big_seeds": args.big_seeds, "before": args.before, "studies": studies,
                          "hydra_launchers": args.hydra_launchers, "batches": batches, "sweeper": args.sweeper}}  # fmt: skip
    mine = SWEEPERS[args.sweeper]  # the current code's sweeps only: a --before tree may not have the sweeper

    def keep() -> None:
        (work / "raw.json").write_text(json.dumps(raw, indent=1, default=str))  # what a crash would not take away

    for i, code in enumerate(codes.values()):  # compile and cache what each tree runs, outside the timings
        default_run(code, work, 1000 + i)
    for k in range(args.repeats):
        raw["jobs"].append(grid_job(None, work, k))
        for i, (c, code) in enumerate(codes.items()):
            raw["runs"][c].append(default_run(code, work, 100 * i + k))
            names = ["zrp_ga"] + (["joblib"] if code is None else ["basic", "joblib"]) * args.hydra_launchers
            for name in names:
                key = f"{c} / {name}"
                try:
                    ran = sweep(GRID + LAUNCHERS[name] + (mine if code is None else []), code, work, f"{c.split()[0]}-{name}-{k}", poses)  # fmt: skip
                    raw["grids"].setdefault(key, []).append(ran)
                except RuntimeError as exc:
                    if code is None:
                        raise
                    print(f"{key}: failed, left out ({str(exc).splitlines()[-1] if str(exc) else ''})", flush=True)
                    raw["grids"].pop(key)
            keep()
        raw["kernel"].append(kernel_rates(problem, batches))
        keep()
        print(f"round {k + 1} of {args.repeats} done, load {load()}", flush=True)
    alone = sweep(GRID + LOCAL + mine + ["hydra.launcher.lockstep=false"], None, work, "alone", poses)
    raw["alone"] = {**alone, "compared": identical(Path(raw["grids"]["after / zrp_ga"][0]["dir"]), Path(alone["dir"]))}
    keep()
    print(f"identical curves: {raw['alone']['compared'][0]} of {raw['alone']['compared'][1]} runs", flush=True)
    if args.big_seeds:
        raw["big"] = sweep(GRID + LOCAL + mine + [f"seed=range({args.big_seeds})"], None, work, "big", poses)
        keep()
        print(f"big study done, load {load()}", flush=True)
    raw["studies"] = {}
    for name in studies:
        raw["studies"][name] = study(name, work)
        keep()
        print(f"study {name} done", flush=True)
    raw["imports"] = {c: import_s(code, work) for c, code in codes.items()}
    raw["load_after"] = load()
    keep()
    write(report(raw))
    print(f"files in {work}")


def write(text: str) -> None:
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "bench_sweep.md").write_text(text)
    print(text)


def report(raw: dict) -> str:
    """results/bench_sweep.md from the numbers :func:`main` keeps in raw.json."""
    args = argparse.Namespace(**raw["args"])
    studies, batches, poses, n = args.studies, args.batches, raw["poses"], cores()
    cmd = "python experiments/bench_sweep.py" + (f" --before {args.before}" if args.before else "")
    cmd += f" --repeats {args.repeats} --big-seeds {args.big_seeds}"
    cmd += (" --studies " + " ".join(studies) if studies else "") + (" --hydra-launchers" if args.hydra_launchers else "")
    sweeper = getattr(args, "sweeper", "basic")  # raw.json of earlier runs: no sweeper kept (Hydra's was the default)
    cmd += f" --sweeper {sweeper}" if sweeper != "zrp_ga" else ""
    lines = [
        "# Sweeps at the speed of the kernel: what runs and sweeps cost beyond their pose evaluations", "",
        f"Command: `{cmd}`, on {n} cores (Python {sys.version.split()[0]}). Machine load average "
        f"(1, 5, 15 min) before: {raw['load_before']}; after: {raw['load_after']}. Medians of {args.repeats} "
        "rounds, range in brackets.", "",
        "## The 144-run operator grid (`zrp-ga -m experiment=operator_grid`)", "",
        "| code | launcher | wall, s | CPU, s (all processes) | the runs' compute, s (sum of wall_s) | CPU per run, s |",
        "|---|---|---|---|---|---|",
    ]  # fmt: skip
    for key, rows in raw["grids"].items():
        c, name = key.split(" / ")
        per_run = [dict(x=r["cpu_s"] / r["runs"]) for r in rows]
        lines.append(f"| {c} | {name} (`{' '.join(LAUNCHERS[name]) or 'default'}`) | {med(rows, 'wall_s')} | "
                     f"{med(rows, 'cpu_s')} | {med(rows, 'compute_s')} | {med(per_run, 'x', '.3f')} |")  # fmt: skip
    ours = raw["grids"]["after / zrp_ga"]
    wall, cpu = (statistics.median(r[k] for r in ours) for k in ("wall_s", "cpu_s"))
    for key, rows in raw["grids"].items():
        if key != "after / zrp_ga":
            ratio = {k: statistics.median(r[k] for r in rows) / statistics.median(r[k] for r in ours) for k in ("wall_s", "cpu_s")}
            c, name = key.split(" / ")
            lines.append(f"\n{c}, {name} launcher / after, zrp_ga's launcher: wall time x {ratio['wall_s']:.2f}, CPU time x {ratio['cpu_s']:.2f} (medians).")
    g = ours[0]
    done = f"{g['done']} of {g['runs']} manifest jobs done" + ("" if all(r["done"] == r["runs"] for r in ours) else " (NOT every job done in every round)")  # fmt: skip
    lines += ["", f"The sweep's pose evaluations: {g['nevals']:,.0f} evaluations (summary.json's `nevals`, summed over "
              f"its runs) x {poses} poses = {g['pose_evals'] / 1e6:.2f} M; {done}.", "",
              "**Against the kernel alone** (`task.problem.costs` of the grid's instance, built as a run builds it, on "
              "random genomes within the gene ranges, one core, one BLAS thread, timed in each round between the "
              "sweeps):", "",
              f"| genomes per kernel call | M pose evaluations/s | kernel-only time, s | grid wall / kernel-only time | "
              f"grid wall / (kernel-only time / {n} cores) | M pose evaluations per CPU-s | grid CPU / kernel-only CPU |",
              "|---|---|---|---|---|---|---|"]  # fmt: skip
    for b in batches:
        rates, cpu_rates = [r[str(b)] for r in raw["kernel"]], [r[f"{b} cpu"] for r in raw["kernel"]]
        rate, cpu_rate = statistics.median(rates), statistics.median(cpu_rates)
        kernel = g["pose_evals"] / rate
        what = "one run's offspring" if b == OFFSPRING else f"{b // OFFSPRING} runs x {OFFSPRING} offspring" if b % OFFSPRING == 0 else ""  # fmt: skip
        lines.append(f"| {b} ({what}) | {rate / 1e6:.2f} ({min(rates) / 1e6:.2f} - {max(rates) / 1e6:.2f}) | {kernel:.2f} | "
                     f"{wall / kernel:.1f} | {wall * n / kernel:.1f} | {cpu_rate / 1e6:.2f} | "
                     f"{cpu / (g['pose_evals'] / cpu_rate):.1f} |")  # fmt: skip
    lines += ["", "(The last two columns time the same calls by CPU time, which waiting for a busy core does not "
              "inflate: on a loaded machine the CPU ratio is the steadier one.)"]
    kernel_big = g["pose_evals"] / statistics.median(r[str(max(batches))] for r in raw["kernel"])
    gens = statistics.median(r["generations_s"] for r in ours)
    lines += ["", f"**Per-run overhead**: the runs' generations (convergence.csv's `eval_s` + `bookkeeping_s` + "
              f"`refine_s`, summed over the {g['runs']} runs; their cost evaluations included) took {gens:.1f} s, of which "
              f"the kernel alone would take {kernel_big:.2f} s (at {max(batches)} genomes a call). (wall x cores - "
              f"generations' time) / runs = ({wall:.1f} x {n} - {gens:.1f}) / {g['runs']} = "
              f"**{(wall * n - gens) / g['runs'] * 1000:.0f} ms per run outside its generations** (composition, building, "
              f"diagnostics, files, idle cores); the GA's own work in the generations beyond the kernel: "
              f"{(gens - kernel_big) / g['runs'] * 1000:.0f} ms per run; CPU: {cpu / g['runs'] * 1000:.0f} ms per run in all. "
              "(The runs' timings are wall-clock: on a loaded machine they include waiting for a core. If the runs of "
              "a batch each record the batch's whole generation time, the sum counts it once per run and the "
              "overhead comes out too low, even negative.)"]  # fmt: skip
    jobs = raw["jobs"]
    lines += ["", f"One job of the grid as a process of its own (`zrp-ga experiment=operator_grid hydra.mode=RUN "
              f"crossover=sbx mutation=gaussian inversion=segment rotation=segment seed=K`, as a launcher that starts "
              f"a process per job runs it): {med(jobs, 'wall_s')} s wall, {med(jobs, 'cpu_s')} s CPU, of which the "
              f"run's compute {med(jobs, 'compute_s')} s."]  # fmt: skip
    a = raw["alone"]
    same, total, named = a["compared"]
    verdict = f"**{same} of {total} runs identical**" + ("." if same == total else ". First differences:")
    lines += ["", "## Identical curves: every run of the grid against the same run alone", "",
              "`zrp-ga -m experiment=operator_grid hydra/launcher=local hydra.launcher.lockstep=false` (every job "
              f"evolved alone): {a['wall_s']:.1f} s wall, {a['cpu_s']:.1f} s CPU, {a['done']} of {a['runs']} jobs "
              "done. Each run's convergence.csv without its timing columns (`zrp_ga.run.callbacks.WALL_CLOCK_COLUMNS`) "
              "and its summary.json without `wall_s` and `versions`, against the same job of the first timed sweep "
              f"(`experiments/reference_runs.py`, `run_differences`): {verdict}"]  # fmt: skip
    lines += [f"- {d}" for d in named]
    big = raw.get("big")
    if big:
        lines += ["", f"## A {big['runs']:,}-run study (the grid with {args.big_seeds} seeds, zrp_ga's launcher)", "",
                  f"`zrp-ga -m experiment=operator_grid hydra/launcher=local{' hydra/sweeper=basic' * (sweeper == 'basic')} "
                  f"seed=range({args.big_seeds})`: "
                  f"**{big['wall_s']:.1f} s wall** ({big['wall_s'] / 60:.1f} min; {big['wall_s'] / big['runs'] * 1000:.1f} s per "
                  f"1,000 runs), {big['cpu_s']:.1f} s CPU ({big['cpu_s'] / big['runs'] * 1000:.0f} ms per run); "
                  f"{big['done']:,} of {big['runs']:,} manifest jobs done; {big['pose_evals'] / 1e6:,.0f} M pose evaluations. "
                  + ("" if big.get("launch_s") is None else
                     f"Of the wall time, {big['launch_s']:.0f} s passed before the jobs were launched (the log's `Launching` line: "
                     + ("zrp_ga's sweeper composes the jobs that bring a new choice or value" if sweeper == "zrp_ga"
                        else "Hydra's sweeper composes every job to check it") + ", the workers wait)."),
                  "", f"10,000 such runs at this machine's speed, one worker being one core: "
                  f"{big['cpu_s'] / big['runs'] * 10_000 / 60:.1f} worker-minutes on zrp_ga's launcher; "
                  f"{statistics.median(j['cpu_s'] for j in jobs) * 10_000 / 60:.0f} worker-minutes with a process per "
                  "run (CPU of the job above)."]  # fmt: skip
    runs = raw["runs"]
    lines += ["", "## A default run (`zrp-ga`, the paper's case study)", "",
              "| code | wall, s | the run's compute (wall_s), s | fixed cost (wall - wall_s), s | CPU, s | "
              "fixed cost in CPU (CPU - wall_s), s | imports of a run's modules, s |",
              "|---|---|---|---|---|---|---|"]  # fmt: skip
    for c in runs:
        fixed_cpu = [{"x": r["cpu_s"] - r["compute_s"]} for r in runs[c]]
        lines.append(f"| {c} | {med(runs[c], 'wall_s')} | {med(runs[c], 'compute_s')} | {med(runs[c], 'fixed_s')} | "
                     f"{med(runs[c], 'cpu_s')} | {med(fixed_cpu, 'x')} | {raw['imports'][c]:.2f} |")  # fmt: skip
    if studies:
        lines += ["", "## The committed studies run again", "",
                  "Each study's sweeps with zrp_ga's launcher, its report with the options of the committed tables "
                  "(`zrp-ga-report ... --formats none`), the medians, quartiles and run counts of each table against "
                  "the committed one (experiments/results/).", "",
                  "| study | runs (done) | wall, s (sweeps and reports) | table | medians and quartiles |", "|---|---|---|---|---|"]  # fmt: skip
        notes = []
        for name in studies:
            s = raw["studies"][name]
            for f, diffs in s["differences"].items():
                lines.append(f"| {name} | {s['runs']} ({s['done']}) | {s['wall_s']:.0f} | {f} | "
                             f"{'unchanged' if not diffs else f'{len(diffs)} differ'} |")  # fmt: skip
                notes += [f"- {f}: {d}" for d in diffs[:10]] + ([f"- {f}: ... {len(diffs) - 10} more"] if len(diffs) > 10 else [])
        lines += (["", "Differences (first 10 per table):", "", *notes] if notes else [])
        rest = [s for s in STUDIES if s not in studies]
        lines += ["", (f"Not run this time: {', '.join(rest)} (`--studies {' '.join(rest)}`). " if rest else "") + LEFT_OUT]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
