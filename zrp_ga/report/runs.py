"""Finding runs and reading their files, checked: a run whose files are malformed or truncated
is left out with the reason, never read half.

A run is a directory holding ``convergence.csv``; it counts when it also holds a readable
``summary.json`` and its ``status.json`` (when present) does not say it failed or was
interrupted. A sweep directory holds ``manifest.jsonl`` (:mod:`zrp_ga.run.directory`): its
jobs are read in the manifest's order with the manifest's state, then any run directory below it
that the manifest does not name.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from zrp_ga.core.files import regular_file
from zrp_ga.report.common import ReportError
from zrp_ga.run.directory import CONVERGENCE, INITIAL_POPULATION, MANIFEST, STATUS, SUMMARY

MAX_BYTES = {SUMMARY: 64 << 20, CONVERGENCE: 256 << 20, STATUS: 1 << 20, INITIAL_POPULATION: 256 << 20,
             MANIFEST: 1 << 30, "overrides.yaml": 1 << 20, "hydra.yaml": 16 << 20, "best_params.csv": 64 << 20}  # a file larger than this is not a run's (bounded memory)

Array = np.ndarray
IGNORED_KEYS = ("hydra", "experiment", "progress", "checkpoint_every", "outputs")
NEEDED_COLUMNS = ("gen", "nevals", "best")


class LeftOut(Exception):
    """Why a run is not in the report (one line)."""


@dataclasses.dataclass
class Run:
    """A finished run as its files tell it.

    ``evals``/``best``: the run's trace, (T,) evaluation counts (increasing, >= 1) and the
    best cost seen by then (non-increasing; see :func:`trace`). ``columns``: convergence.csv's
    columns as arrays (``convergence``, the same as a DataFrame); ``tokens``: the Hydra overrides
    as given (``overrides`` without Hydra's own and bookkeeping keys); ``sweep``: the sweep
    directory of a job of one."""

    path: Path
    overrides: dict[str, str]
    summary: dict[str, Any]
    columns: dict[str, Array]
    evals: Array
    best: Array
    tokens: tuple[str, ...] = ()
    sweep: Path | None = None

    @property
    def convergence(self) -> pd.DataFrame:
        return pd.DataFrame(self.columns)

    @property
    def instance(self) -> str:
        return str(self.summary["instance"])

    @property
    def final_cost(self) -> float:
        return number(self.summary.get("final_cost"))

    @property
    def nevals(self) -> int:
        return int(self.summary["nevals"])

    @property
    def choices(self) -> dict[str, str]:
        return {str(k): str(v) for k, v in (self.summary.get("choices") or {}).items()}

    def validation_mm(self, which: str) -> float:
        """The RMS validation error (mm) of the ``nominal`` or ``calibrated`` model; NaN without validation."""
        return number((self.summary.get("validation_rms_mm") or {}).get(which))


def number(value: Any) -> float:
    """A JSON number as float; null (a non-finite number written by the app) as NaN."""
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan


# --- overrides -------------------------------------------------------------------------------------
def parse_overrides(items: list[str] | str) -> dict[str, str]:
    """``KEY=VALUE`` tokens (Hydra's overrides) as a dict, Hydra's own and bookkeeping keys left out."""
    tokens = items.split() if isinstance(items, str) else [str(t) for t in items]
    out = {}
    for token in tokens:
        key, _, value = token.lstrip("+~").partition("=")
        if not key.startswith(IGNORED_KEYS):
            out[key] = value
    return out


def read_text(path: Path, name: str | None = None, errors: str = "strict") -> str:
    """A run's file as text, checked first to be a regular file of at most ``MAX_BYTES`` (a FIFO
    named like a run file would block the read forever, ``/dev/zero`` would fill the memory);
    LeftOut says what it is instead."""
    name = name or path.name
    try:
        regular_file(path, f"a run's {name}")
        size = path.stat().st_size
    except ValueError as exc:
        raise LeftOut(str(exc)) from None
    if size > MAX_BYTES.get(name, 1 << 30):
        raise LeftOut(f"{path}: {size:,} bytes, larger than a run's {name} can be ({MAX_BYTES[name]:,})")
    try:
        return path.read_text(errors=errors)
    except (OSError, UnicodeDecodeError) as exc:
        raise LeftOut(f"{name} cannot be read ({exc})") from None


def _hydra_overrides(path: Path) -> list[str]:
    """The overrides Hydra saved for a single run, as given (none when absent or unreadable: they only name settings)."""
    try:
        items = yaml.load(read_text(path / ".hydra" / "overrides.yaml", "overrides.yaml"), Loader=_LOADER)
    except (LeftOut, yaml.YAMLError):
        return []
    return [str(t) for t in items] if isinstance(items, list) else []


_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


# --- one run ---------------------------------------------------------------------------------------
def read_summary(path: Path) -> dict[str, Any]:
    """``summary.json`` checked for the fields the report uses; LeftOut says what is wrong."""
    try:
        summary = json.loads(read_text(path / SUMMARY))
    except json.JSONDecodeError as exc:
        raise LeftOut(f"summary.json is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    if not isinstance(summary, dict):
        raise LeftOut("summary.json does not hold an object")
    checks = {
        "instance": lambda v: isinstance(v, str) and v != "",
        "nevals": lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
        "final_cost": lambda v: v is None or (isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0),
    }
    for key, ok in checks.items():
        if key not in summary:
            raise LeftOut(f"summary.json has no {key!r}")
        if not ok(summary[key]):
            raise LeftOut(f"summary.json: {key!r} is {summary[key]!r}")
    for key in ("config", "choices", "validation_rms_mm"):
        if summary.get(key) is not None and not isinstance(summary[key], dict):
            raise LeftOut(f"summary.json: {key!r} is not an object")
    return summary


def read_convergence(path: Path) -> dict[str, Array]:
    """``convergence.csv`` checked whole, as {column: (T,) array}: every line complete, the
    needed columns numbers, evaluations finite and non-decreasing, costs >= 0 or +inf (a
    diverged run: it reaches no target). A cost of -inf (it would reach every target), a
    negative one or NaN is no cost: the run is left out, named, not read around. LeftOut names
    the first line that is not. Other columns: numbers, NaN where a field is not one."""
    text = read_text(path / CONVERGENCE)
    if '"' in text or "\r" in text or "\0" in text:
        rows = list(csv.reader(io.StringIO(text)))
    else:  # no quoting, one line end: the fields are the text split at commas, as the csv module splits them
        rows = [line.split(",") if line else [] for line in text.split("\n")]
        if rows and not rows[-1]:
            rows.pop()
    if not rows:
        raise LeftOut("convergence.csv is empty")
    header = rows[0]
    missing = [c for c in NEEDED_COLUMNS if c not in header]
    if missing:
        raise LeftOut(f"convergence.csv has no column {missing[0]!r}")
    if len(rows) < 2:
        raise LeftOut("convergence.csv has no rows")
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise LeftOut(f"convergence.csv line {line} is truncated ({len(row)} of {len(header)} fields)")
    if not text.endswith("\n"):
        raise LeftOut(f"convergence.csv line {len(rows)} is truncated (no line end)")
    try:
        table = np.array(rows[1:], dtype=float)  # every field a number: the usual case, at once
        columns = {c: table[:, k] for k, c in enumerate(header)}
    except ValueError:
        columns = {c: pd.to_numeric(pd.Series([r[k] for r in rows[1:]]), errors="coerce").to_numpy(dtype=float)
                   for k, c in enumerate(header)}  # fmt: skip
    for column in NEEDED_COLUMNS:
        values = columns[column]
        bad = np.isnan(values) | (values < 0) | (np.isinf(values) if column != "best" else False)
        if bad.any():
            line = int(np.argmax(bad))
            raw = rows[line + 1][header.index(column)]
            what = "not a finite number" if column != "best" else "not a cost (a cost is >= 0, or inf when diverged)"
            raise LeftOut(f"convergence.csv line {line + 2}: {column} is {raw!r}, {what}")
    if (np.diff(columns["nevals"]) < 0).any():
        line = int(np.argmax(np.diff(columns["nevals"]) < 0)) + 3
        raise LeftOut(f"convergence.csv line {line}: evaluations go down")
    return columns


def _initial_costs(path: Path) -> Array | None:
    """The initial population's costs in evaluation order, or None when unreadable (the last
    column, ``cost``, of each line: read without parsing the genes)."""
    try:
        lines = read_text(path / INITIAL_POPULATION).splitlines()
        if not lines or lines[0].rsplit(",", 1)[-1].strip() != "cost":
            return None
        return np.array([ln.rsplit(",", 1)[-1] for ln in lines[1:] if ln], dtype=float)
    except (LeftOut, ValueError):
        return None


def trace(conv: dict[str, Array] | pd.DataFrame, initial_costs: Array | None = None) -> tuple[Array, Array]:
    """The run's best-so-far cost by evaluation count: (T,) evaluations (increasing, >= 1)
    and (T,) best cost seen within that many evaluations (non-finite costs count as +inf).

    Rows of ``convergence.csv`` are at generation ends, so an improvement counts at the end of
    its generation. The initial population is finer: when ``initial_population.csv`` holds as
    many costs as the first row's evaluations, with the same best, its costs are the first
    evaluations one by one. A row at 0 evaluations (Levenberg-Marquardt's starting point)
    counts as evaluation 1.

    >>> conv = {"nevals": np.array([3, 6, 9]), "best": np.array([5.0, 4.0, 4.5])}
    >>> e, b = trace(conv, np.array([7.0, 5.0, 6.0]))
    >>> e.tolist(), b.tolist()
    ([1, 2, 3, 6, 9], [7.0, 5.0, 5.0, 4.0, 4.0])
    """
    e = np.maximum(np.asarray(conv["nevals"], dtype=float), 1.0).astype(np.int64)
    c = np.asarray(conv["best"], dtype=float)
    c = np.where(np.isnan(c), np.inf, c)
    if initial_costs is not None and len(initial_costs) == e[0] and len(initial_costs):
        first = np.where(np.isnan(initial_costs), np.inf, initial_costs)
        if np.isclose(first.min(), c[0], rtol=1e-12, atol=0.0) or first.min() == c[0]:
            e = np.r_[np.arange(1, len(first) + 1), e[1:]]
            c = np.r_[first, c[1:]]
    best = np.minimum.accumulate(c)
    last = np.r_[e[1:] != e[:-1], True]  # several rows at one count: the last holds the best of them
    return e[last], best[last]


def load_run(path: Path, tokens: list[str], sweep: Path | None = None) -> Run:
    """The finished run in ``path`` (``tokens``: its Hydra overrides as given); LeftOut says why
    it does not count."""
    status = _status(path)
    if not (path / SUMMARY).exists():
        raise LeftOut(_unfinished(status, path))
    if status and status.get("status") in ("failed", "interrupted"):
        raise LeftOut(_unfinished(status, path))
    summary = read_summary(path)
    if not (path / CONVERGENCE).exists():
        raise LeftOut("no convergence.csv")
    conv = read_convergence(path)
    last = int(conv["nevals"][-1])
    if last != summary["nevals"]:
        raise LeftOut(f"convergence.csv ends at {last} evaluations, summary.json says {summary['nevals']} (truncated?)")
    evals, best = trace(conv, _initial_costs(path))
    return Run(path, parse_overrides(tokens), summary, conv, evals, best, tuple(tokens), sweep)


def _status(path: Path) -> dict | None:
    if not (path / STATUS).exists():
        return None
    try:
        status = json.loads(read_text(path / STATUS))
    except ValueError:
        return None
    return status if isinstance(status, dict) else None


def _unfinished(status: dict | None, path: Path, manifest_state: str | None = None) -> str:
    """Why a run without results does not count, in words: what its status.json says when it
    failed or was interrupted, else what the sweep's manifest says, else that it has not finished."""
    state = (status or {}).get("status")
    if state not in ("failed", "interrupted"):
        state = manifest_state or state
    error = (status or {}).get("error")
    if state == "failed":
        return f"failed: {error}" if error else "failed"
    if state == "interrupted":
        return f"interrupted (continue it with zrp-ga resume={path})"
    if state == "running":
        return "still running (or killed while running)"
    return "not finished (no summary.json)"


# --- finding runs ----------------------------------------------------------------------------------
def read_manifest(sweep: Path) -> tuple[list[dict], list[tuple[str, str]]]:
    """The last state of each job in ``manifest.jsonl`` and the lines that cannot be read
    (a sweep killed while writing may leave half a line)."""
    jobs, bad = {}, []
    try:
        text = read_text(sweep / MANIFEST, errors="replace")
    except LeftOut as why:
        return [], [(str(sweep / MANIFEST), str(why))]
    for n, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
            jobs[int(record["job"])] = record
            str(record["dir"])
        except (ValueError, KeyError, TypeError):
            bad.append((f"{sweep / MANIFEST}:{n}", "manifest line not readable"))
    return [jobs[k] for k in sorted(jobs)], bad


def _job(sweep: Path, job: dict) -> Run:
    """A job of a sweep's manifest, read when the manifest says it is done."""
    path = sweep / str(job["dir"])
    if not path.is_dir():
        raise LeftOut(f"no run directory ({job.get('status')} in the manifest)")
    tokens = str(job.get("overrides") or "").split()
    if job.get("status") == "done":
        return load_run(path, tokens, sweep)
    if job.get("status") == "failed":
        raise LeftOut(f"failed: {job.get('error')}" if job.get("error") else "failed")
    raise LeftOut(_unfinished(_status(path), path, str(job.get("status"))))


def find_runs(paths: list[str | Path]) -> tuple[list[Run], list[tuple[str, str]]]:
    """Runs under ``paths`` (run directories, sweep directories, or folders holding them), and
    the ones left out as (path, reason): failed, still running, interrupted, malformed files.
    A missing path or a file given as a directory is a ReportError (a ValueError, one line)."""
    roots = []
    for p in paths:
        path = Path(p)
        if not path.exists():
            raise ReportError(f"{p}: no such directory")
        if not path.is_dir():
            raise ReportError(f"{p}: not a directory")
        roots.append(path.resolve())
    runs: list[Run] = []
    left: list[tuple[str, str]] = []
    seen: set[Path] = set()

    def take(path: Path, read, *args) -> None:
        seen.add(path)
        try:
            runs.append(read(*args))
        except LeftOut as why:
            left.append((str(path), str(why)))

    def visit(path: Path) -> None:
        if path in seen:
            return
        seen.add(path)
        if (path / MANIFEST).exists():
            jobs, bad = read_manifest(path)
            left.extend(bad)
            for job in jobs:
                job_dir = path / str(job["dir"])
                if job_dir not in seen:
                    take(job_dir, _job, path, job)
        elif (path / CONVERGENCE).exists() or (path / STATUS).exists():
            take(path, load_run, path, _hydra_overrides(path))
            return
        try:
            children = sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
        except OSError as exc:
            left.append((str(path), f"cannot be listed ({exc.strerror})"))
            return
        for child in children:
            visit(child)

    for root in roots:
        visit(root)
    return runs, left
