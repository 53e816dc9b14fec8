"""Where the time of runs evolved together goes: the 144-run operator grid timed, one seed's 48 runs
profiled, and two grids compared run by run (issue 32, item 3).

- ``--grid DIR``: ``zrp-ga -m experiment=operator_grid hydra/launcher=local`` into ``DIR``; its wall
  and CPU seconds (all processes) and the load average before and after. ``--code REV``: with the
  code of git revision ``REV`` (a copy of its tree on ``PYTHONPATH``, as ``bench_sweep.py --before``;
  or a folder holding such a copy: its kernels compiled by an earlier run, not again).
- ``--profile``: one seed's 48 grid runs evolved together in this process (``outputs=study``, a
  sweep job's files, into a temporary folder), once untimed (kernels loaded, modules imported),
  then under cProfile: milliseconds per run by part (the generations and within them the kernel,
  the unpacking of parameter arrays, operators, selection, survival; each generation's rows and
  statistics; the end of the run) and the functions with most own time.
- ``--compare A B``: every run of grid ``A`` against the same job's run of grid ``B``:
  ``best_params.csv`` and ``initial_population.csv`` byte for byte, ``convergence.csv`` line for line without its wall-clock
  columns (every other cell's text equal), ``summary.json`` equal but for its timing fields
  (``wall_s``, ``versions``); exit code 1 if any differs.

    python experiments/profile_lockstep.py --profile
    python experiments/profile_lockstep.py --grid /tmp/grid-main --code main
    python experiments/profile_lockstep.py --grid /tmp/grid-new
    python experiments/profile_lockstep.py --compare /tmp/grid-main /tmp/grid-new
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import csv
import io
import itertools
import json
import os
import pstats
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
from bench_sweep import tree  # a git revision's code, importable from PYTHONPATH

ROOT = Path(__file__).resolve().parents[1]
GRID = ["experiment=operator_grid"]
SETS = list(itertools.product(["one_point", "two_point", "blend", "sbx"], ["gaussian", "polynomial", "uniform_reset"],
                              ["none", "segment"], ["none", "segment"]))  # fmt: skip
WALL_CLOCK = {"eval_s", "bookkeeping_s", "refine_s", "wall_s"}  # convergence.csv's timing columns
SUMMARY_TIMING = {"wall_s", "versions"}
# The parts of a run, by the functions whose cumulative time they are (file suffix, function name).
PARTS = [
    ("generations (step_together)", "algorithms/ga.py", "step_together"),
    ("  cost kernel (compiled call)", "core/compiled.py", "call"),
    ("  evaluation (problem.costs)", "model/cost.py", "costs"),
    ("  unpacking (layout.unpack)", "model/layout.py", "unpack"),
    ("  operators (_apply)", "algorithms/ga.py", "_apply"),
    ("  selection (_select)", "algorithms/ga.py", "_select"),
    ("  survival (_survive)", "algorithms/ga.py", "_survive"),
    ("rows and statistics (_emit_together)", "algorithms/__init__.py", "_emit_together"),
    ("end of the run (assembly.finish)", "run/assembly.py", "finish"),
    ("  summary (summary.build)", "run/summary.py", "build"),
    ("  assessment (assessment.assess)", "problems/assessment.py", "assess"),
    ("  files (summary.write)", "run/summary.py", "write"),
    ("everything (run_together)", "run/together.py", "run_together"),
]


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def grid(out: Path, rev: str | None) -> dict:
    env = dict(os.environ)
    if rev:  # a folder: a tree extracted before (its kernels compiled and cached by an earlier run)
        env["PYTHONPATH"] = rev if Path(rev).is_dir() else str(tree(rev, Path(tempfile.mkdtemp(prefix="zrp_ga_tree_"))))
    before, load_before = resource.getrusage(resource.RUSAGE_CHILDREN), load()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "-m", *GRID, "hydra/launcher=local", f"hydra.sweep.dir={out}"],
                          capture_output=True, text=True, env=env, cwd=out.parent)  # fmt: skip
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        sys.exit(f"the grid failed: {proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"dir": str(out), "code": rev or "this tree", "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
            "load_before": load_before, "load_after": load()}  # fmt: skip


def prepared(seed: int, out: Path) -> list:
    from zrp_ga import config
    from zrp_ga.run.build import prepare
    from zrp_ga.run.shared import Cache

    cache = Cache()
    runs = []
    for k, (c, m, i, r) in enumerate(SETS):
        over = [f"crossover={c}", f"mutation={m}", f"inversion={i}", f"rotation={r}", f"seed={seed}", "outputs=study"]
        runs.append(prepare(config.load(GRID + over), out / str(k), cache=cache))
    return runs


@contextlib.contextmanager
def timed() -> Iterator[dict[str, float]]:
    """CPU seconds of this process spent in the three parts of runs evolved together (the generations, the
    rows and statistics, the ends of the runs), by wrapping the functions that do them."""
    from unittest import mock

    from zrp_ga.algorithms import Algorithm
    from zrp_ga.algorithms.ga import GA
    from zrp_ga.run import assembly

    spent = {"generations (GA.step_together)": 0.0, "rows and statistics (_emit_together)": 0.0,
             "end of the run (assembly.finish)": 0.0}  # fmt: skip

    def wrap(fn: Callable[..., Any], key: str) -> Callable[..., Any]:
        def run(*args: Any, **kwargs: Any) -> Any:
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[key] += time.process_time() - t0

        return run

    keys = list(spent)
    with mock.patch.object(GA, "step_together", staticmethod(wrap(GA.step_together, keys[0]))), \
         mock.patch.object(Algorithm, "_emit_together", staticmethod(wrap(Algorithm._emit_together, keys[1]))), \
         mock.patch.object(assembly, "finish", wrap(assembly.finish, keys[2])):  # fmt: skip
        yield spent


def profile(seed: int, top: int, dump: Path | None = None, repeats: int = 3) -> None:
    import logging

    from zrp_ga.run.together import run_together

    logging.getLogger("zrp_ga").setLevel(logging.ERROR)
    with tempfile.TemporaryDirectory() as tmp:
        run_together(prepared(seed, Path(tmp) / "warm"))  # kernels loaded, modules imported
        rounds = []
        for r in range(repeats):  # the round of least CPU: the one least disturbed by other processes
            runs = prepared(seed, Path(tmp) / f"timed{r}")
            with timed() as parts:
                t0, c0 = time.perf_counter(), time.process_time()
                run_together(runs)
                rounds.append((time.process_time() - c0, time.perf_counter() - t0, dict(parts)))
        cpu, wall, parts = min(rounds, key=lambda r: r[0])
        runs = prepared(seed, Path(tmp) / "profiled")
        prof = cProfile.Profile()
        prof.enable()
        run_together(runs)
        prof.disable()
    if dump:
        prof.dump_stats(dump)
    n = len(SETS)
    stats = pstats.Stats(prof)
    cum: dict[tuple[str, str], float] = {}
    for (file, _, name), (_, _, _, ct, _) in stats.stats.items():  # type: ignore[attr-defined]
        for _, suffix, fn in PARTS:
            if file.endswith(suffix) and name == fn:
                cum[(suffix, fn)] = max(cum.get((suffix, fn), 0.0), ct)  # a wrapper and its function: once
    print(f"seed {seed}: {n} runs evolved together, load {load()}")
    print(f"without the profiler, the least CPU of {repeats} rounds: {cpu * 1e3 / n:.1f} ms CPU a run ({wall * 1e3 / n:.1f} ms wall); "
          f"all rounds' CPU: {', '.join(f'{r[0] * 1e3 / n:.1f}' for r in rounds)} ms a run; of it:")
    for label, spent in parts.items():
        print(f"  {label:<42} {spent * 1e3 / n:7.2f}")
    print("under cProfile, ms a run (cumulative):")
    for label, suffix, fn in PARTS:
        print(f"  {label:<42} {cum.get((suffix, fn), 0.0) * 1e3 / n:7.2f}")
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(top)
    print("\n".join(line for line in text.getvalue().splitlines() if line.strip())[-(top + 2) * 200:])


def _convergence(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    keep = [j for j, c in enumerate(rows[0]) if c not in WALL_CLOCK]
    return [[r[j] for j in keep] for r in rows]


def _strip(value: object) -> object:
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in SUMMARY_TIMING}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def run_differences(a: Path, b: Path) -> list[str]:
    """What differs between the runs in ``a`` and ``b`` ([] when nothing does)."""
    out = [name for name in ("best_params.csv", "initial_population.csv") if (a / name).read_bytes() != (b / name).read_bytes()]
    if _convergence(a / "convergence.csv") != _convergence(b / "convergence.csv"):
        out.append("convergence.csv")
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    if json.dumps(_strip(sa), sort_keys=True) != json.dumps(_strip(sb), sort_keys=True):
        out.append("summary.json")
    return out


def jobs(sweep: Path) -> dict[object, Path]:
    """The sweep's jobs, each its run directory (the manifest's last line for the job)."""
    last = {}
    for line in (sweep / "manifest.jsonl").read_text().splitlines():
        if line.strip():
            record = json.loads(line)
            last[record["job"]] = sweep / str(record["dir"])
    return last


def compare(a: Path, b: Path) -> int:
    ja, jb = jobs(a), jobs(b)
    if set(ja) != set(jb):
        print(f"different jobs: {len(ja)} in {a}, {len(jb)} in {b}")
        return 1
    bad = {job: d for job in sorted(ja, key=str) if (d := run_differences(ja[job], jb[job]))}
    for job, d in list(bad.items())[:10]:
        print(f"job {job} ({ja[job]}): {', '.join(d)} differ")
    print(f"identical: {len(ja) - len(bad)} of {len(ja)} runs")
    return 1 if bad else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=Path, metavar="DIR", help="run the 144-run grid into DIR, timed")
    parser.add_argument("--code", metavar="REV", help="with --grid: the code of git revision REV (or in folder REV)")
    parser.add_argument("--profile", action="store_true", help="profile one seed's 48 runs evolved together")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="rounds timed without the profiler")
    parser.add_argument("--top", type=int, default=30, help="functions listed by own time")
    parser.add_argument("--dump", type=Path, metavar="FILE", help="with --profile: the profile's statistics into FILE")
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("A", "B"))
    args = parser.parse_args()
    if not (args.grid or args.profile or args.compare):
        parser.error("nothing to do: give --grid DIR, --profile or --compare A B")
    if args.grid:
        if args.grid.exists():
            parser.error(f"--grid: {args.grid} exists; give a new folder")
        print(json.dumps(grid(args.grid.resolve(), args.code)))
    if args.profile:
        profile(args.seed, args.top, args.dump, args.repeats)
    if args.compare:
        sys.exit(compare(*args.compare))


if __name__ == "__main__":
    main()
