"""What the report understands of a study's design before comparing anything, and how it was
made: which configurations can be compared at all (groups), whether the seed also drew the
instance, the settings held fixed and those varied, the commands that made the runs (from
their own records) and the code's version.

- **Groups**: configurations and instances joined when a configuration ran on an instance;
  each connected part is a group. Nothing is compared across groups: they never shared an
  instance (a folder of unrelated runs is several groups).
- **The seed drew the instance**: two or more instances, each run on exactly one seed, no seed
  on two instances (a simulated problem without ``problem.seed`` takes the run's seed). Then
  no configuration has two runs on an instance; the page says how to hold the instance.
- **Settings**: the runs' resolved configs (summary.json's ``config``) flattened; a key with one
  value in every run is held fixed, any other varied.
- **Commands**: per sweep, ``zrp-ga -m`` with the overrides every job was given, the swept keys
  that the sweep's config does not sweep itself as comma lists, and Hydra's own overrides (the
  launcher); per single run its overrides. Read from Hydra's record of a job (``.hydra``).
"""

from __future__ import annotations

import functools
import os
import shlex
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from zrp_ga.report.labels import flatten
from zrp_ga.report.runs import LeftOut, Run, read_text

IGNORED = ("hydra", "progress", "checkpoint_every", "experiment", "outputs")


def groups(pairs: pd.DataFrame) -> dict[str, int]:
    """Group number (1, 2, ...) of each configuration, from ``pairs`` (columns configuration,
    instance: one row per run): configurations that ran on a shared instance, directly or through
    others, share a group; groups numbered by their first configuration in ``pairs``' order."""
    parent: dict[tuple, tuple] = {}

    def find(x: tuple) -> tuple:
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for c, i in pairs[["configuration", "instance"]].drop_duplicates().itertuples(index=False):
        parent[find(("c", c))] = find(("i", i))
    roots: dict[tuple, int] = {}
    out = {}
    for c in dict.fromkeys(pairs["configuration"]):
        out[c] = roots.setdefault(find(("c", c)), len(roots) + 1)
    return out


def seed_drew_instance(runs_df: pd.DataFrame) -> bool:
    """Whether every instance was run on exactly one seed and no seed on two instances (two or
    more instances): the seed chose the problem instance as well as the optimiser's randomness."""
    seeds = runs_df.dropna(subset=["seed"]).groupby("instance")["seed"].agg(lambda s: frozenset(map(str, s)))
    if len(seeds) < 2 or len(seeds) != runs_df["instance"].nunique() or (seeds.map(len) != 1).any():
        return False
    return len({next(iter(s)) for s in seeds}) == len(seeds)


def settings(runs: list[Run]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The settings held fixed (key, value) and varied (key, values: how many and the first
    few, "(absent)" where a run has no such key), from the runs' resolved configs."""
    flats = [_own(flatten(r.summary.get("config") or {})) for r in runs]
    keys = sorted(set().union(*flats)) if flats else []
    fixed, varied = [], []
    for k in keys:
        values = list(dict.fromkeys(f.get(k, "(absent)") for f in flats))
        if len(values) == 1:
            fixed.append(dict(setting=k, value=values[0]))
        else:
            shown = ", ".join(values[:6]) + (f", ... ({len(values)} values)" if len(values) > 6 else "")
            varied.append(dict(setting=k, values=shown))
    return pd.DataFrame(fixed, columns=["setting", "value"]), pd.DataFrame(varied, columns=["setting", "values"])


def _own(flat: dict[str, str]) -> dict[str, str]:
    """A run's flat config without bookkeeping keys and without the algorithm node's copies of
    the top-level groups (``algorithm.population.mu`` when ``population.mu`` says the same)."""
    out = {k: v for k, v in flat.items() if not k.startswith(IGNORED)}
    return {k: v for k, v in out.items() if not (k.startswith("algorithm.") and out.get(k.removeprefix("algorithm.")) == v)}


def relative_command(command: str, where: Path) -> str:
    """The report's command with its absolute paths relative to the report's folder ``where``.

    >>> relative_command("zrp-ga-report /data/sweep --out /data/report", Path("/data/report"))
    'zrp-ga-report ../sweep --out .'
    """
    try:
        words = shlex.split(command)
    except ValueError:
        return command
    return shlex.join(os.path.relpath(w, where) if w.startswith("/") else w for w in words)


def _hydra_record(run: Run) -> dict | None:
    """Hydra's record of the run (``.hydra/hydra.yaml``'s ``hydra`` node), None without one."""
    try:
        node = yaml.load(read_text(run.path / ".hydra" / "hydra.yaml", "hydra.yaml"), Loader=_LOADER)
    except (LeftOut, yaml.YAMLError):
        return None
    return node.get("hydra") if isinstance(node, dict) and isinstance(node.get("hydra"), dict) else None


_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _swept(tokens: list[tuple[str, ...]], by_config: set[str]) -> list[str]:
    """The overrides of a sweep's command from its jobs' ``tokens``: those every job has, and
    each key that varies (and that the sweep's config does not sweep) as a comma list."""
    keys = list(dict.fromkeys(t.split("=", 1)[0] for job in tokens for t in job))
    out = []
    for key in keys:
        values = list(dict.fromkeys(t.split("=", 1)[1] for job in tokens for t in job if t.split("=", 1)[0] == key and "=" in t))
        if len(values) == 1 and all(any(t.split("=", 1)[0] == key for t in job) for job in tokens):
            out.append(f"{key}={values[0]}")
        elif key.lstrip("+~") not in by_config and values:
            out.append(f"{key}={','.join(values)}")
    return out


def commands(runs: list[Run], report_dir: Path) -> list[dict[str, Any]]:
    """The commands that made the runs, one per sweep (or single run), from Hydra's records:
    {command (its paths relative to the folder it ran in), where (that folder, relative to
    ``report_dir``), runs}; runs made without Hydra (the API) are counted under ``command`` ""."""
    by_sweep: dict[Any, list[Run]] = {}
    for r in runs:
        by_sweep.setdefault(r.sweep or r.path, []).append(r)
    out = []
    for members in by_sweep.values():
        record = _hydra_record(members[0])
        if record is None:
            out.append(dict(command="", where="", runs=len(members)))
            continue
        overrides = record.get("overrides") or {}
        multirun = members[0].sweep is not None or str(record.get("mode", "")).endswith("MULTIRUN")
        by_config = set(((record.get("sweeper") or {}).get("params") or {}).keys())
        task = _swept([r.tokens for r in members], by_config) if multirun else list(members[0].tokens)
        words = ["zrp-ga", *(["-m"] if multirun else []), *task, *[str(t) for t in overrides.get("hydra") or []]]
        cwd = str((record.get("runtime") or {}).get("cwd") or "")
        where = os.path.relpath(cwd, report_dir) if cwd else ""
        out.append(dict(command=shlex.join(_relative(words, cwd)), where=where, runs=len(members)))
    return out


def _relative(words: list[str], cwd: str) -> list[str]:
    """Overrides naming an absolute path made relative to ``cwd`` (the folder the command ran
    in): the page names no absolute path of the user's machine."""
    out = []
    for w in words:
        key, eq, value = w.partition("=")
        if eq and value.startswith("/") and cwd:
            w = f"{key}={os.path.relpath(value, cwd)}"
        out.append(w)
    return out


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """zrp_ga's version, with its commit (and "modified" when its code or configs differ from
    it) when the code runs from a git clone (an editable install, or the source tree), e.g. ``0.1.0 (commit
    f139c89)``."""
    try:
        version = metadata.version("zrp_ga")
    except metadata.PackageNotFoundError:
        version = "?"
    root = Path(__file__).resolve().parents[2]  # the folder holding zrp_ga/
    if not ((root / ".git").exists() and (root / "pyproject.toml").exists()):
        return version
    try:
        git = ["git", "-C", str(root)]
        commit = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=10, check=True)
        dirty = subprocess.run([*git, "status", "--porcelain", "--untracked-files=no", "--", "zrp_ga", "conf"], capture_output=True,
                               text=True, timeout=10)  # the code's own folders: a study's results beside it do not count
    except (OSError, subprocess.SubprocessError):
        return version
    return f"{version} (commit {commit.stdout.strip()}{', modified' if dirty.stdout.strip() else ''})"
