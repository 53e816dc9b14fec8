"""How soon a big sweep's workers get their first job: the seconds from the command to the
sweep's ``Launching N jobs`` line and to its first ``#N : ...`` line (the first batch sent to a
worker), for the 10,080-run study (the operator grid with 210 seeds), with zrp_ga's sweeper
(``-m``'s default) and Hydra's basic one, in turn, ``--repeats`` times; the sweep is killed
as soon as its first job is sent.

    python experiments/first_job.py [--repeats 3] [--seeds 210] [--sweepers zrp_ga basic]

Prints one line per attempt and the load average before and after. The sweep is started in a
process group of its own (``start_new_session``) and killed with it; its folder is a temporary
one, removed at the end.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SWEEPERS = {"zrp_ga": [], "basic": ["hydra/sweeper=basic"]}


def first_job(seeds: int, sweeper: str, where: Path) -> tuple[float | None, float | None]:
    """Seconds to the ``Launching`` line and to the first job sent (None: never seen)."""
    command = [sys.executable, "-m", "zrp_ga.cli", "-m", "experiment=operator_grid", f"seed=range({seeds})",
               f"hydra.sweep.dir={where}", *SWEEPERS[sweeper]]  # fmt: skip
    started = time.perf_counter()
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            cwd=where.parent)  # fmt: skip
    launched = sent = None
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            if launched is None and "] Launching " in line:
                launched = time.perf_counter() - started
            if "\t#" in line:
                sent = time.perf_counter() - started
                break
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    return launched, sent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seeds", type=int, default=210, help="seeds of the 48-run grid (210: 10,080 runs)")
    parser.add_argument("--sweepers", nargs="+", choices=list(SWEEPERS), default=list(SWEEPERS))
    args = parser.parse_args()
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    work = Path(tempfile.mkdtemp(prefix="first_job_"))
    try:
        for k in range(args.repeats):
            for sweeper in args.sweepers:
                launched, sent = first_job(args.seeds, sweeper, work / f"{sweeper}_{k}")
                show = {name: "never" if t is None else f"{t:.1f} s" for name, t in (("launched", launched), ("sent", sent))}
                print(f"{48 * args.seeds:,} runs, {sweeper} sweeper: Launching at {show['launched']}, first job sent at {show['sent']}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
