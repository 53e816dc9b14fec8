"""Run the slow tests (``pytest -m slow``: killed sweeps, cluster launchers, a killed worker, full
disks, the whole operator grid's compositions) and write their latest result into
experiments/results/slow_tests.md: the pass/fail/skip counts, each failing test, the date, the
wall time and the machine's load while they ran.

    nice python experiments/slow_tests.py            # all of them
    nice python experiments/slow_tests.py -- -x      # extra arguments go to pytest

The default ``pytest`` leaves them out (``-m 'not slow'`` in pyproject.toml) to stay fast; the
cluster launchers' tests need the ``slurm`` and ``ray`` extras (skipped without them).
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "experiments" / "results" / "slow_tests.md"


def main(extra: list[str]) -> int:
    command = [sys.executable, "-m", "pytest", "-m", "slow", "-q", "-rfEs", "-p", "no:cacheprovider", *extra]
    started = datetime.datetime.now(datetime.UTC)
    load_before = os.getloadavg()
    t0 = time.monotonic()
    # Ctrl-C as the tests send it: a shell's background job (``cmd &`` without job control, nohup,
    # cron) inherits SIGINT ignored, and so would every sweep the tests interrupt with it
    proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, preexec_fn=_default_sigint)
    wall = time.monotonic() - t0
    load_after = os.getloadavg()
    text = proc.stdout + proc.stderr
    sys.stdout.write(text)
    summary = next((line.strip("= ") for line in reversed(text.splitlines()) if re.search(r"\d+ (passed|failed|error)", line)), "no summary")
    problems = [line for line in text.splitlines() if line.startswith(("FAILED ", "ERROR ", "SKIPPED "))]
    lines = [
        "# Slow tests: latest result",
        "",
        "Written by `nice python experiments/slow_tests.py` (runs `pytest -m slow`; see experiments/README.md).",
        "",
        f"- date: {started:%Y-%m-%d %H:%M} UTC; commit {_commit()}",
        f"- result: **{summary}** (exit code {proc.returncode})",
        f"- wall time: {wall / 60:.1f} min",
        f"- machine: {os.cpu_count()} cores, Python {platform.python_version()}; load average (1, 5, 15 min) "
        f"{_load(load_before)} at the start, {_load(load_after)} at the end (other sessions share the machine)",
        f"- command: `{' '.join(['pytest', *command[3:]])}`",
        "",
    ]
    if problems:
        lines += ["Failed, errors and skipped:", "", *[f"- `{p}`" for p in problems], ""]
    OUT.write_text("\n".join(lines))
    print(f"written: {OUT.relative_to(ROOT)}")
    return proc.returncode


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _load(la: tuple[float, float, float]) -> str:
    return ", ".join(f"{x:.1f}" for x in la)


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip() or "?"
    except OSError:
        return "?"


if __name__ == "__main__":
    args = sys.argv[1:]
    sys.exit(main(args[1:] if args[:1] == ["--"] else args))
