"""What sweeps and single runs cost beyond their compute, before and after zrp_ga's launcher.

    python experiments/bench_sweep.py [--repeats 3] [--before REV] [--big-seeds 21] [--out DIR]

- **A default run** (``zrp-ga``, the paper's case study): wall time of the command, the run's
  own compute (``wall_s`` in its summary.json) and the difference, its fixed cost; the import
  time of the modules a run loads (``python -X importtime``), as a share of it.
- **The 144-run operator grid** (``zrp-ga experiment=operator_grid``, 4 crossovers x 3
  mutations x 2 inversions x 2 rotations x 3 seeds of the 30-pose problem at 5,000 evaluations)
  with Hydra's joblib launcher and zrp_ga's (``hydra/launcher=local``), and with ``--before``
  the old code with Hydra's basic and joblib launchers: wall time, CPU time of all its
  processes, and the runs' own compute (the sum of their ``wall_s``); each sweep's manifest must
  say "done" for every job.
- **A 1,008-run sweep**: the grid with 21 seeds, on zrp_ga's launcher only.
- ``--before REV``: the same default run and grid with the code of git revision ``REV`` (the
  commit before the launcher, e.g. 3c19fb5), from a copy of that tree on ``PYTHONPATH``.

Variants are run in turn, ``--repeats`` times, so that the load of a shared machine falls on all
of them; figures are medians, with the range. The machine's load average is recorded before
and after. Writes results/bench_sweep.md.
"""

from __future__ import annotations

import argparse
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

RESULTS = Path(__file__).parent / "results"
ROOT = Path(__file__).resolve().parents[1]
GRID = ["experiment=operator_grid"]
LAUNCHERS = {"basic": [], "joblib": ["hydra/launcher=joblib"], "zrp_ga": ["hydra/launcher=local"]}
RUN_MODULES = ("zrp_ga.app zrp_ga.robots zrp_ga.problems.simulated zrp_ga.algorithms.ga zrp_ga.operators "
               "zrp_ga.callbacks zrp_ga.summary zrp_ga.records zrp_ga.checkpoint threadpoolctl")  # fmt: skip


def tree(rev: str, where: Path) -> Path:
    """The code of git revision ``rev`` in ``where``, importable from ``PYTHONPATH``."""
    where.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
    (where / "zrp_ga" / "conf").symlink_to(where / "conf")  # as the installed package ships it
    return where


def command(args: list[str], code: Path | None, cwd: Path) -> tuple[float, float, subprocess.CompletedProcess]:
    """Wall and CPU seconds (all processes) of ``python -m zrp_ga.app ARGS``."""
    env = dict(os.environ, PYTHONPATH=str(code)) if code else dict(os.environ)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.app", *args], capture_output=True, text=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(args)}: {proc.stderr[-2000:]}")
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
    return {"wall_s": wall, "cpu_s": cpu, "compute_s": compute, "fixed_s": wall - compute}


def grid_job(code: Path | None, work: Path, k: int) -> dict:
    """One job of the grid as a process of its own, as a launcher that starts one per job
    (submitit on SLURM) runs it."""
    out = work / f"grid-job-{k}"
    job = ["crossover=sbx", "mutation=gaussian", "inversion=segment", "rotation=segment", f"seed={k % 3}"]
    wall, cpu, _ = command([*GRID, "hydra.mode=RUN", *job, f"hydra.run.dir={out}"], code, work)
    compute = json.loads((out / "summary.json").read_text())["wall_s"]
    return {"wall_s": wall, "cpu_s": cpu, "compute_s": compute, "fixed_s": wall - compute}


def sweep(args: list[str], code: Path | None, work: Path, name: str) -> dict:
    where = work / name
    wall, cpu, _ = command([*args, f"hydra.sweep.dir={where}"], code, work)
    jobs = manifest(where)
    assert all(j["status"] == "done" for j in jobs), f"{name}: not every job done"
    compute = sum(json.loads((where / str(j["dir"]) / "summary.json").read_text())["wall_s"] for j in jobs)
    return {"wall_s": wall, "cpu_s": cpu, "compute_s": compute, "runs": len(jobs)}


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


def med(rows: list[dict], key: str) -> str:
    values = [r[key] for r in rows]
    return f"{statistics.median(values):.2f} ({min(values):.2f} - {max(values):.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", default=None, help="git revision to compare with (e.g. 3c19fb5)")
    parser.add_argument("--big-seeds", type=int, default=21, help="seeds of the big sweep (21: 1,008 runs; 0: none)")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    codes = {"after": None}
    if args.before:
        codes[f"before ({args.before})"] = tree(args.before, work / "before-tree")
    load_before = load()
    for i, code in enumerate(codes.values()):  # compile and cache what each tree runs, outside the timings
        default_run(code, work, 1000 + i)
    runs, grids, jobs = {c: [] for c in codes}, {}, []
    for k in range(args.repeats):
        jobs.append(grid_job(None, work, k))
        for i, (c, code) in enumerate(codes.items()):
            runs[c].append(default_run(code, work, 100 * i + k))
            for name in ("joblib", "zrp_ga") if code is None else ("basic", "joblib"):
                grids.setdefault((c, name), []).append(sweep(GRID + LAUNCHERS[name], code, work, f"{c.split()[0]}-{name}-{k}"))
            raw = {"runs": runs, "grids": {" / ".join(key): rows for key, rows in grids.items()}, "jobs": jobs}
            (work / "raw.json").write_text(json.dumps(raw, indent=1))  # what a crash would not take away
        print(f"round {k + 1} of {args.repeats} done, load {load()}", flush=True)
    big = sweep(GRID + LAUNCHERS["zrp_ga"] + [f"seed=range({args.big_seeds})"], None, work, "big") if args.big_seeds else None
    (work / "raw.json").write_text(json.dumps({**raw, "big": big}, indent=1))
    imports = {c: import_s(code, work) for c, code in codes.items()}
    text = report(args, codes, runs, grids, jobs, big, imports, load_before, load())
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "bench_sweep.md").write_text(text)
    print(text)
    print(f"files in {work}")


def report(args, codes, runs, grids, jobs, big, imports, load_before: str, load_after: str) -> str:
    cmd = "python experiments/bench_sweep.py" + (f" --before {args.before}" if args.before else "")
    cmd += f" --repeats {args.repeats}" + (f" --big-seeds {args.big_seeds}" if args.big_seeds != 21 else "")
    lines = [
        "# What runs and sweeps cost beyond their compute", "",
        f"Command: `{cmd}`, on {os.cpu_count()} cores (Python {sys.version.split()[0]}). Machine load average "
        f"(1, 5, 15 min) before: {load_before}; after: {load_after}. Medians of {args.repeats} runs, range in brackets.", "",
        "## A default run (`zrp-ga`, the paper's case study)", "",
        "| code | wall, s | the run's compute, s | fixed cost, s | CPU, s | imports of a run's modules, s |",
        "|---|---|---|---|---|---|",
    ]  # fmt: skip
    for c in codes:
        lines.append(f"| {c} | {med(runs[c], 'wall_s')} | {med(runs[c], 'compute_s')} | {med(runs[c], 'fixed_s')} | "
                     f"{med(runs[c], 'cpu_s')} | {imports[c]:.2f} |")  # fmt: skip
    lines += ["", "## The 144-run operator grid (`zrp-ga experiment=operator_grid`)", "",
              "| code | launcher | wall, s | CPU, s (all processes) | the runs' compute, s (sum) | CPU per run, s |",
              "|---|---|---|---|---|---|"]  # fmt: skip
    for (c, name), rows in grids.items():
        per_run = [dict(x=r["cpu_s"] / r["runs"]) for r in rows]
        lines.append(f"| {c} | {name} (`{' '.join(LAUNCHERS[name]) or 'default'}`) | {med(rows, 'wall_s')} | "
                     f"{med(rows, 'cpu_s')} | {med(rows, 'compute_s')} | {med(per_run, 'x')} |")  # fmt: skip
    ours = grids[("after", "zrp_ga")]
    for (c, name), rows in grids.items():
        if (c, name) != ("after", "zrp_ga"):
            ratio = {k: statistics.median(r[k] for r in rows) / statistics.median(r[k] for r in ours) for k in ("wall_s", "cpu_s")}
            lines.append(f"\n{c}, {name} launcher / after, zrp_ga's launcher: wall time x {ratio['wall_s']:.2f}, "
                         f"CPU time x {ratio['cpu_s']:.2f} (medians).")  # fmt: skip
    lines += ["", f"One job of the grid as a process of its own (`zrp-ga experiment=operator_grid hydra.mode=RUN "
              f"crossover=sbx mutation=gaussian inversion=segment rotation=segment seed=K`, as a launcher that starts "
              f"a process per job runs it): {med(jobs, 'wall_s')} s wall, {med(jobs, 'cpu_s')} s CPU, of which the "
              f"run's compute {med(jobs, 'compute_s')} s."]  # fmt: skip
    if big:
        lines += ["", f"## A {big['runs']:,}-run sweep (the grid with {args.big_seeds} seeds, zrp_ga's launcher)", "",
                  f"`zrp-ga experiment=operator_grid hydra/launcher=local seed=range({args.big_seeds})`: "
                  f"{big['wall_s']:.1f} s wall ({big['wall_s'] / big['runs'] * 1000:.1f} s per 1,000 runs), "
                  f"{big['cpu_s']:.1f} s CPU ({big['cpu_s'] / big['runs']:.3f} s per run), of which the runs' own "
                  f"compute {big['compute_s']:.1f} s (wall time inside the runs, summed).",
                  "", f"10,000 such runs at this machine's speed, one worker being one core: "
                  f"{big['cpu_s'] / big['runs'] * 10_000 / 3600:.2f} worker-hours on zrp_ga's launcher; "
                  f"{statistics.median(j['cpu_s'] for j in jobs) * 10_000 / 3600:.2f} worker-hours with a process per "
                  "run (CPU of the job above)."]  # fmt: skip
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
