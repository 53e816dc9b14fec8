"""Every ``zrp-ga``, ``zrp-ga-report`` and ``zrp-ga-compensate`` command of README.md,
experiments/README.md and ``zrp-ga --help`` (as tests/test_readme_commands.py extracts them), run
in a scratch folder with the installed Hydra, each sweep made small by the overrides said beside it
(one seed, a small budget: the command's own path through Hydra, not its study), and its output
abridged into a Markdown file:

    python experiments/hydra_versions.py --out experiments/results/hydra_versions.md

Commands that need what this machine lacks (a SLURM or Ray cluster, the user's own files, another
extra) are listed as not run, with the reason.
"""

from __future__ import annotations

import argparse
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from test_readme_commands import all_commands

SMALL = ["hydra.sweeper.params.seed=0", "population.max_evals=1000", "population.generations=null", "progress=false"]
SKIP = {
    "slurm": "needs a SLURM cluster (hydra/launcher=slurm; tests/test_cluster_launchers.py runs submitit's local cluster with -m slow)",
    "ray": "needs Ray (the ray extra)",
    "robot=file": "needs the user's own arm and measurement files",
    "--config-dir DIR": "needs the user's own config folder (tests/test_app.py::test_a_users_own_config_directory runs one)",
    "calibration_file=...": "a placeholder for the user's files",
    "program.csv": "needs the user's own robot program (the UR10 command below runs compensation)",
    "zrp-ga-report DIR": "a placeholder for the user's folders (the report commands of the sweeps run)",
}


def _skip(command: str) -> str | None:
    return next((why for key, why in SKIP.items() if key in command), None)


def _prepared(command: str) -> tuple[list[str], str]:
    """The command's words as run here, and what was added to make it small."""
    words = shlex.split(command)
    added: list[str] = []
    if words[0] == "zrp-ga" and ("-m" in words or "--multirun" in words):
        added = [*SMALL] if any(w.startswith("experiment=") for w in words) else SMALL[1:]  # one seed: an experiment's
        if any(w.startswith("hparams_search=") for w in words):
            added = ["hydra.sweeper.n_trials=2", "population.max_evals=1000", "progress=false"]
    words = [str(ROOT / w) if w.startswith("zrp_ga/data/") else w for w in words]  # the package's data, from here
    if words[0] == "zrp-ga" and "resume=outputs/DATE/TIME" in words:
        words[words.index("resume=outputs/DATE/TIME")] = "resume=cut"
    return words + added, " ".join(added)


def _abridged(text: str, n: int = 4) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip() and "setup plugin" not in line]
    return "\n".join(lines if len(lines) <= 2 * n else [*lines[:n], "...", *lines[-n:]])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default=None)
    parser.add_argument("--only", default=None, help="run the commands holding this text again, their sections replaced in --out")
    parser.add_argument("--work", default=None, help="the scratch folder (default: a new one; an earlier one: its sweeps reported)")
    args = parser.parse_args()
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="hydra_versions-"))
    print(f"scratch folder: {work}", flush=True)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    versions = ", ".join(f"{p} {metadata.version(p)}" for p in ("zrp_ga", "hydra-core", "omegaconf", "hydra-optuna-sweeper", "optuna"))
    # a run stopped early (SIGTERM, as a cluster's time limit stops it), for the README's resume command
    proc = None if (work / "cut").exists() else subprocess.Popen(["zrp-ga", "problem=multipose", "population.generations=2000", "checkpoint_every=5", "progress=false",
                             "hydra.run.dir=cut"], cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    curve, deadline = work / "cut" / "convergence.csv", time.monotonic() + 600
    while proc and proc.poll() is None and time.monotonic() < deadline and not (curve.exists() and curve.read_text().count("\n") > 20):
        time.sleep(0.2)
    if proc:
        proc.send_signal(signal.SIGTERM)
        proc.wait()
    lines = [f"# The README's commands under {versions}", "",
             f"`python experiments/hydra_versions.py` on {time.strftime('%Y-%m-%d')}, load average "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores. Each command as the documents write it (`pip` lines and "
             "`python experiments/...` scripts left out: they install or run a study of their own), sweeps made small by the "
             "overrides beside them; the output abridged.", ""]  # fmt: skip
    commands = [c for c in all_commands() if c.split(" ")[0] in ("zrp-ga", "zrp-ga-report", "zrp-ga-compensate") and "&&" not in c]
    # the sweeps, tuning, resume and reports first (the paths a version change breaks), single runs after
    commands.sort(key=lambda c: 0 if (" -m " in c or "resume=" in c) else 1 if c.startswith("zrp-ga-") else 2)
    if args.only:
        commands = [c for c in commands if args.only in c]
    for command in commands:
        why = _skip(command)
        if why:
            lines += [f"## `{command}`", "", f"Not run: {why}.", ""]
            continue
        words, added = _prepared(command)
        t0 = time.perf_counter()
        try:
            out = subprocess.run(words, cwd=work, env=env, capture_output=True, text=True, timeout=1800)
            code, text = out.returncode, out.stdout + out.stderr
        except subprocess.TimeoutExpired:
            code, text = "timeout", ""
        wall = time.perf_counter() - t0
        lines += [f"## `{command}`", "", f"Run{' with ' + repr(added) if added else ''}: exit {code}, {wall:.0f} s.", "", "```",
                  _abridged(text), "```", ""]  # fmt: skip
        print(f"{code} {wall:6.0f} s  {command}", flush=True)
        if args.out and not args.only:  # as it goes
            Path(args.out).write_text("\n".join(lines))
    if args.out and args.only:  # the sections of these commands replaced
        text = Path(args.out).read_text()
        for section in "\n".join(lines).split("\n## ")[1:]:
            parts = text.split("\n## ")
            heads = [q.split("\n", 1)[0] for q in parts]
            head = section.split("\n", 1)[0]
            if head in heads:
                parts[heads.index(head)] = section
                text = "\n## ".join(parts)
            else:
                text += "\n## " + section
        Path(args.out).write_text(text)
    if not args.out:
        print("\n".join(lines))


if __name__ == "__main__":
    main()
