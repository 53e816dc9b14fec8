"""Reference runs of every kind, to show that a change of the run machinery changes no result.

    python experiments/reference_runs.py OUT            # run them, write OUT/<name>.csv and OUT/<name>.json
    python experiments/reference_runs.py OUT --legacy   # the same with issue 29's new defaults off (below)
    python experiments/reference_runs.py --compare A B  # the same numbers in A and B?

Each run goes through the command line (``python -m zrp_ga.cli``, as ``zrp-ga``), except
``api``, which goes through ``zrp_ga.calibrate``. Kinds: simulated (GA with and without the
pseudo-inverse step, LM, CMA-ES), measured (the UR10 laser-tracker data), pose selection, and a
GA run stopped by Ctrl-C after generation 23 then resumed (``zrp-ga resume=DIR``). Written per
run: ``convergence.csv`` without its timing columns, and the numbers of ``summary.json`` that
do not depend on timing or versions. ``--compare`` prints every difference and exits 1 if any. ``--legacy`` adds :data:`LEGACY` (every
parameter moves, measured orientations left out: what the runs fitted before issue 29), to show
that nothing else changed. :func:`run_differences` compares two
run directories in the same terms (experiments/bench_sweep.py compares whole sweeps with it).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS as TIMING

SMALL = ["problem=multipose", "problem.n_poses=10", "problem.n_validation=10", "seed=4"]
RUNS = {
    "paper_ga_pinv": [],
    "sim_ga_no_step": [*SMALL, "refine=none", "population.generations=15"],
    "sim_lm": [*SMALL, "algorithm=lm"],
    "sim_cmaes": [*SMALL, "algorithm=cmaes", "population.generations=15"],
    "measured_ga": ["problem=ur10_ipa", "population.generations=4"],
    "measured_lm": ["problem=ur10_ipa", "algorithm=lm"],
    "selection_ga": ["experiment=pose_selection", "problem.n_candidates=60", "problem.k=8", "problem.n_validation=20",
                     "population.generations=4"],
}  # fmt: skip
RESUMED = [*SMALL, "refine=none", "population.mu=30", "population.lambda_=30", "population.generations=40", "checkpoint_every=7"]
# A Ctrl-C after generation 23, in the run's own process: the convergence log raises it.
CUT = """
import runpy, sys
from zrp_ga.run import callbacks
write = callbacks.ConvergenceLog.on_generation
def cut(self, algorithm, row):
    write(self, algorithm, row)
    if row["gen"] == 23:
        raise KeyboardInterrupt
callbacks.ConvergenceLog.on_generation = cut
sys.argv = ["zrp-ga", *sys.argv[1:]]
runpy.run_module("zrp_ga.cli", run_name="__main__")
"""
LEGACY = {"all": ["problem.subspace=full"], "measured": ["problem.use_orientation=false"]}
SUMMARY_KEYS = ["instance", "algorithm", "seed", "final_cost", "optimiser_cost", "returned", "initial_cost",
                "nominal_cost", "nevals", "stop_reason", "validation_rms_mm", "validation_max_mm", "param_err",
                "identifiability", "best_genome", "choices"]  # fmt: skip
SUMMARY_TIMING = ("wall_s", "versions")  # the fields of summary.json that depend on timing or on installed versions


def command(args: list[str], script: str | None = None) -> subprocess.CompletedProcess:
    head = ["-c", script] if script else ["-m", "zrp_ga.cli"]
    return subprocess.run([sys.executable, *head, *args, "progress=false"], capture_output=True, text=True)


def keep(run_dir: Path, out: Path, name: str, stdout: str = "") -> None:
    curve = pd.read_csv(run_dir / "convergence.csv").drop(columns=TIMING)
    curve.to_csv(out / f"{name}.csv", index=False, float_format="%r")
    summary = json.loads((run_dir / "summary.json").read_text())
    kept = {k: summary.get(k) for k in SUMMARY_KEYS}
    kept["console"] = [re.sub(r"^\[[^]]*\]", "[time]", line) for line in stdout.splitlines() if not line.startswith("results in")]
    (out / f"{name}.json").write_text(json.dumps(kept, indent=1, sort_keys=True))


def run_all(out: Path, only: list[str] | None, legacy: bool = False) -> None:
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="zrp_ga_reference_"))
    for name, args in RUNS.items():
        if only and name not in only:
            continue
        extra = (LEGACY["all"] + (LEGACY["measured"] if name.startswith("measured") else [])) if legacy else []
        proc = command([*args, *extra, f"hydra.run.dir={work / name}"])
        if proc.returncode:
            raise SystemExit(f"{name}: {proc.stderr[-2000:]}")
        keep(work / name, out, name, proc.stdout)
        print(name, "done", flush=True)
    if not only or "resumed" in only:
        cut = command([*RESUMED, *(LEGACY["all"] if legacy else []), f"hydra.run.dir={work / 'resumed'}"], CUT)
        assert cut.returncode == 130, cut.stderr
        proc = command([f"resume={work / 'resumed'}", f"hydra.run.dir={work / 'resume_log'}"])
        if proc.returncode:
            raise SystemExit(f"resumed: {proc.stderr[-2000:]}")
        keep(work / "resumed", out, "resumed", proc.stdout)
        print("resumed done", flush=True)
    if not only or "api" in only:
        import zrp_ga

        zrp_ga.calibrate("puma560", problem={"n_poses": 10, "n_validation": 10, **({"subspace": "full"} if legacy else {})},
                         population={"generations": 8},
                         refine="none", seed=2, out=work / "api")  # fmt: skip
        keep(work / "api", out, "api")
        print("api done", flush=True)


def compare(a: Path, b: Path) -> int:
    bad = 0
    for f in sorted({p.name for p in a.iterdir()} | {p.name for p in b.iterdir()}):
        x, y = a / f, b / f
        if not (x.exists() and y.exists()):
            print(f"{f}: only in {'A' if x.exists() else 'B'}")
            bad += 1
        elif x.read_text() != y.read_text():
            print(f"{f}: differs")
            subprocess.run(["diff", str(x), str(y)])
            bad += 1
    print("identical" if not bad else f"{bad} file(s) differ")
    return 1 if bad else 0


def run_differences(a: Path, b: Path, first: int = 3) -> list[str]:
    """The first ``first`` differences between the runs in directories ``a`` and ``b``: their
    convergence.csv without its timing columns (values read exactly, NaN equal to NaN) and every
    field of their summary.json but :data:`SUMMARY_TIMING`, at any depth; [] when they agree."""
    out: list[str] = []
    x, y = (pd.read_csv(d / "convergence.csv", float_precision="round_trip") for d in (a, b))
    x, y = (c.drop(columns=[t for t in TIMING if t in c.columns]) for c in (x, y))
    if list(x.columns) != list(y.columns) or len(x) != len(y):
        out.append(f"convergence.csv: columns {list(x.columns)} and {len(x)} rows against {list(y.columns)} and {len(y)} rows")
    else:
        same = (x.values == y.values) | (pd.isna(x).values & pd.isna(y).values)
        for i, j in zip(*np.nonzero(~same)):
            u, v = (c.iat[i, j].item() for c in (x, y))
            out.append(f"convergence.csv row {i} ({x.columns[0]} {x.iat[i, 0]}), {x.columns[j]}: {u!r} against {v!r}")
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    out += [f"summary.json {d}" for d in _leaves(sa, sb, "")]
    return out[:first]


def _leaves(a, b, key: str) -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) if k not in SUMMARY_TIMING
                for d in _leaves(a.get(k, "<absent>"), b.get(k, "<absent>"), f"{key}.{k}" if key else k)]  # fmt: skip
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (u, v) in enumerate(zip(a, b)) for d in _leaves(u, v, f"{key}[{i}]")]
    return [] if a == b or (a != a and b != b) else [f"{key}: {a!r} against {b!r}"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, nargs="?")
    parser.add_argument("--only", nargs="*")
    parser.add_argument("--compare", nargs=2, type=Path)
    parser.add_argument("--legacy", action="store_true", help="issue 29's new defaults off (LEGACY)")
    args = parser.parse_args()
    if args.compare:
        sys.exit(compare(*args.compare))
    run_all(args.out, args.only, args.legacy)


if __name__ == "__main__":
    main()
