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

from zrp_ga.report.common import ReportError
from zrp_ga.run.directory import CONVERGENCE, INITIAL_POPULATION, MANIFEST, STATUS, SUMMARY

Array = np.ndarray
IGNORED_KEYS = ("hydra", "experiment", "progress", "checkpoint_every")
NEEDED_COLUMNS = ("gen", "nevals", "best")


class LeftOut(Exception):
    """Why a run is not in the report (one line)."""


@dataclasses.dataclass
class Run:
    """A finished run as its files tell it.

    ``evals``/``best``: the run's trace, (T,) evaluation counts (increasing, >= 1) and the
    best cost seen by then (non-increasing; see :func:`trace`)."""

    path: Path
    overrides: dict[str, str]
    summary: dict[str, Any]
    convergence: pd.DataFrame
    evals: Array
    best: Array

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


def _hydra_overrides(path: Path) -> dict[str, str]:
    """The overrides Hydra saved for a single run (none when absent or unreadable: they only name settings)."""
    try:
        items = yaml.safe_load((path / ".hydra" / "overrides.yaml").read_text())
    except (OSError, yaml.YAMLError):
        return {}
    return parse_overrides(items) if isinstance(items, list) else {}


# --- one run ---------------------------------------------------------------------------------------
def read_summary(path: Path) -> dict[str, Any]:
    """``summary.json`` checked for the fields the report uses; LeftOut says what is wrong."""
    try:
        summary = json.loads((path / SUMMARY).read_text())
    except json.JSONDecodeError as exc:
        raise LeftOut(f"summary.json is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LeftOut(f"summary.json cannot be read ({exc})") from None
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


def read_convergence(path: Path) -> pd.DataFrame:
    """``convergence.csv`` checked whole: every line complete, the needed columns numbers,
    evaluations finite and non-decreasing, costs >= 0 or +inf (a diverged run: it reaches no
    target). A cost of -inf (it would reach every target), a negative one or NaN is no cost: the
    run is left out, named, not read around. LeftOut names the first line that is not."""
    try:
        text = (path / CONVERGENCE).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise LeftOut(f"convergence.csv cannot be read ({exc})") from None
    rows = list(csv.reader(io.StringIO(text)))
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
    conv = pd.read_csv(io.StringIO(text))
    for column in NEEDED_COLUMNS:
        k = header.index(column)
        values = np.empty(len(rows) - 1)
        for line, row in enumerate(rows[1:], start=2):
            try:
                values[line - 2] = float(row[k])  # float() reads 'inf' and 'nan', which a diverged run writes
            except ValueError:
                raise LeftOut(f"convergence.csv line {line}: {column} is {row[k]!r}") from None
            value = values[line - 2]
            if (column != "best" and not math.isfinite(value)) or math.isnan(value) or value < 0:
                what = "not a finite number" if column != "best" else "not a cost (a cost is >= 0, or inf when diverged)"
                raise LeftOut(f"convergence.csv line {line}: {column} is {row[k]!r}, {what}")
        conv[column] = values
    if (np.diff(conv["nevals"].to_numpy()) < 0).any():
        line = int(np.argmax(np.diff(conv["nevals"].to_numpy()) < 0)) + 3
        raise LeftOut(f"convergence.csv line {line}: evaluations go down")
    return conv


def _initial_costs(path: Path) -> Array | None:
    """The initial population's costs in evaluation order, or None when unreadable."""
    try:
        costs = pd.read_csv(path / INITIAL_POPULATION, usecols=["cost"])["cost"]
        return pd.to_numeric(costs, errors="raise").to_numpy(dtype=float)
    except (OSError, ValueError, KeyError, pd.errors.ParserError):
        return None


def trace(conv: pd.DataFrame, initial_costs: Array | None = None) -> tuple[Array, Array]:
    """The run's best-so-far cost by evaluation count: (T,) evaluations (increasing, >= 1)
    and (T,) best cost seen within that many evaluations (non-finite costs count as +inf).

    Rows of ``convergence.csv`` are at generation ends, so an improvement counts at the end of
    its generation. The initial population is finer: when ``initial_population.csv`` holds as
    many costs as the first row's evaluations, with the same best, its costs are the first
    evaluations one by one. A row at 0 evaluations (Levenberg-Marquardt's starting point)
    counts as evaluation 1.

    >>> conv = pd.DataFrame({"nevals": [3, 6, 9], "best": [5.0, 4.0, 4.5]})
    >>> e, b = trace(conv, np.array([7.0, 5.0, 6.0]))
    >>> e.tolist(), b.tolist()
    ([1, 2, 3, 6, 9], [7.0, 5.0, 5.0, 4.0, 4.0])
    """
    e = np.maximum(conv["nevals"].to_numpy(dtype=float), 1.0).astype(np.int64)
    c = np.where(np.isnan(conv["best"].to_numpy(dtype=float)), np.inf, conv["best"].to_numpy(dtype=float))
    if initial_costs is not None and len(initial_costs) == e[0] and len(initial_costs):
        first = np.where(np.isnan(initial_costs), np.inf, initial_costs)
        if np.isclose(first.min(), c[0], rtol=1e-12, atol=0.0) or first.min() == c[0]:
            e = np.r_[np.arange(1, len(first) + 1), e[1:]]
            c = np.r_[first, c[1:]]
    best = np.minimum.accumulate(c)
    last = np.r_[e[1:] != e[:-1], True]  # several rows at one count: the last holds the best of them
    return e[last], best[last]


def load_run(path: Path, overrides: dict[str, str]) -> Run:
    """The finished run in ``path``; LeftOut says why it does not count."""
    status = _status(path)
    if not (path / SUMMARY).exists():
        raise LeftOut(_unfinished(status, path))
    if status and status.get("status") in ("failed", "interrupted"):
        raise LeftOut(_unfinished(status, path))
    summary = read_summary(path)
    if not (path / CONVERGENCE).exists():
        raise LeftOut("no convergence.csv")
    conv = read_convergence(path)
    last = int(conv["nevals"].iloc[-1])
    if last != summary["nevals"]:
        raise LeftOut(f"convergence.csv ends at {last} evaluations, summary.json says {summary['nevals']} (truncated?)")
    evals, best = trace(conv, _initial_costs(path))
    return Run(path, overrides, summary, conv, evals, best)


def _status(path: Path) -> dict | None:
    try:
        status = json.loads((path / STATUS).read_text())
    except (OSError, ValueError):
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
    for n, line in enumerate((sweep / MANIFEST).read_text(errors="replace").splitlines(), start=1):
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
    overrides = parse_overrides(job.get("overrides") or "")
    if job.get("status") == "done":
        return load_run(path, overrides)
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
        if (path / MANIFEST).is_file():
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
