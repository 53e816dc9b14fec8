"""Wall time of the operator-grid sweep (144 runs) with Hydra's basic launcher and with joblib.

4 crossovers x 3 mutations x 2 inversions x 2 rotations x 3 seeds of the 30-pose problem at
5,000 evaluations each (conf/experiment/operator_grid.yaml). Run:

    python experiments/bench_sweep.py [--out DIR]

It runs ``zrp-ga experiment=operator_grid`` twice, checks that every job of each sweep is
"done" in its manifest, and writes results/bench_sweep.md.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from zrp_ga.callbacks import read_manifest

RESULTS = Path(__file__).parent / "results"


def sweep(launcher: list[str], where: Path) -> float:
    cmd = [sys.executable, "-m", "zrp_ga.app", "experiment=operator_grid", *launcher, f"hydra.sweep.dir={where}"]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    wall = time.perf_counter() - t0
    status = read_manifest(where)["status"].value_counts().to_dict()
    assert status == {"done": 144}, status
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_sweep_"))
    basic = sweep([], root / "basic")
    joblib = sweep(["hydra/launcher=joblib"], root / "joblib")
    text = "\n".join([
        "# Operator-grid sweep: 144 runs of the 30-pose problem, 5,000 evaluations each", "",
        f"Command: `python experiments/bench_sweep.py`, on {os.cpu_count()} cores.", "",
        "| launcher | command | wall time, s |", "|---|---|---|",
        f"| basic (one job after another) | `zrp-ga experiment=operator_grid` | {basic:.1f} |",
        f"| joblib (all cores) | `zrp-ga experiment=operator_grid hydra/launcher=joblib` | {joblib:.1f} |", "",
        f"Speed-up of joblib over the basic launcher: {basic / joblib:.2f}.", "",
    ])  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "bench_sweep.md").write_text(text)
    print(text)
    print(f"sweeps in {root}")


if __name__ == "__main__":
    main()
