"""The run directory and the sweep directory: the one module that knows their files.

A run directory holds ``convergence.csv`` (written as the run goes), ``checkpoint.npz``,
``status.json`` (``running``, then ``done``, ``failed`` or ``interrupted``), and at the end
``summary.json``, ``best_params.csv``, ``initial_population.csv`` and the calibrated arm's
files. One run writes into a directory at a time: it holds ``.zrp_ga.lock`` (:func:`locked`)
while it runs, and removes the temporary files (``.NAME.PID.tmp``) a killed or failed run left
(:func:`remove_temporary`). A finished run whose files were damaged since (:func:`damage`) is
not taken as finished. A sweep directory holds one run directory per job, the manifest and, under ``.zrp_ga``,
what its jobs share (the identifiability and floor of each problem instance, computed once).

The manifest: every job of a sweep appends its state to ``manifest.jsonl`` when it starts
(``running``) and when it ends (``done``; ``failed`` with the error; ``interrupted`` at
Ctrl-C), one JSON line each, so that a sweep still running, or killed, can be read at any time;
the last line of a job is its state. A job whose directory already holds a finished run (a
sweep started again) is recorded ``done`` without passing through ``running``.
``manifest.csv`` holds one row per job, rewritten whole (a temporary file, then a rename).

Nothing a kill can do loses a recorded state: lines are short and appended with one ``write``
each (jobs of a parallel launcher do not interleave them, and a killed process writes a line
whole or not at all), and a sweep started again first ends a line that a crash of the machine
left unfinished (:func:`repair`), so that its own lines stay whole; :func:`read_manifest` skips
such a fragment.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import datetime
import hashlib
import json
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

CONVERGENCE = "convergence.csv"
SUMMARY = "summary.json"
STATUS = "status.json"
CHECKPOINT = "checkpoint.npz"
BEST_PARAMS = "best_params.csv"
INITIAL_POPULATION = "initial_population.csv"
RUN_FILES = (CONVERGENCE, SUMMARY, STATUS, CHECKPOINT, BEST_PARAMS, INITIAL_POPULATION)  # a directory holding any holds a run
MANIFEST = "manifest.jsonl"
TABLE = "manifest.csv"
COLUMNS = ["job", "overrides", "dir", "status", "error", "time"]
ROUND_OFF = 1e-9  # a floor below ROUND_OFF x the nominal cost is round-off (the runs' floors and the report)
SHARED = ".zrp_ga"  # what the jobs of a sweep share, in the sweep directory


# --- a run --------------------------------------------------------------------------------------------
def holds_run(out: Path) -> bool:
    """Whether ``out`` already holds a run's files."""
    return any((out / f).exists() for f in RUN_FILES)


LOCK = ".zrp_ga.lock"  # held by the process writing into a run directory (filelock)


@contextlib.contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold ``out``'s lock while the block runs (released at exit, also when the process dies):
    a second run into the same directory, from this process or another, is refused with a
    ConfigError naming the process that holds it. The lock is ``filelock``'s: ``flock`` on
    Linux and macOS, ``LockFileEx`` on Windows, a file naming its holder where neither exists
    (taken over when that process is gone)."""
    from filelock import FileLock, Timeout

    from zrp_ga.core.schema import ConfigError

    lock = FileLock(out / LOCK, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise ConfigError(f"{out}: another run (process {_holder(out)}) is writing into this directory; "
                          "wait for it to end or choose another directory") from None  # fmt: skip
    try:
        if type(lock).__name__ != "SoftFileLock":  # a soft lock's file names its holder itself
            with contextlib.suppress(OSError):  # Windows: the locked file is not written (the holder is then unknown)
                (out / LOCK).write_text(str(os.getpid()))
        yield
    finally:
        lock.release()


def _holder(out: Path) -> str:
    """The process holding ``out``'s lock, as its lock file says (the first line)."""
    try:
        return (out / LOCK).read_text(errors="replace").split("\n", 1)[0].strip() or "unknown"
    except OSError:
        return "unknown"


def remove_temporary(out: Path) -> None:
    """Remove the temporary files (``.NAME.PID.tmp``: written, then renamed) a killed or failed
    run left in ``out``; called while holding its lock, so no other run is writing them."""
    for tmp in out.glob(".*.tmp"):
        tmp.unlink(missing_ok=True)


def status(out: Path) -> str | None:
    """The ``status`` in ``out/status.json``; None when there is none (or it cannot be read)."""
    try:
        state: str | None = json.loads((out / STATUS).read_text()).get("status")
        return state
    except (OSError, ValueError, AttributeError):
        return None


def write_status(out: Path, state: str, error: str | None = None) -> None:
    """``out/status.json`` saying ``state`` (and the ``error``), written atomically; a run that
    stops because its disk is full writes ``failed`` over the file in place, which needs no
    new space (the file exists from the run's start, and the text fits in its first block)."""
    from zrp_ga.io import records

    data = {"status": state} if error is None else {"status": state, "error": error}
    try:
        records.write_json(out / STATUS, data)
    except OSError:
        if state == "running" or not (out / STATUS).exists():
            raise
        _overwrite(out / STATUS, (json.dumps(data) + "\n").encode())


def fail_lost(out: Path, error: str) -> None:
    """The run in ``out`` whose process died (a killed worker or cluster job) set ``failed``,
    as it would have set it, when it had started and not ended (and no other run holds it)."""
    from zrp_ga.core.schema import ConfigError

    if holds_run(out) and status(out) in (None, "running"):
        with contextlib.suppress(OSError, ConfigError), locked(out):  # the dead process's lock is released
            write_status(out, "failed", error)


def _overwrite(path: Path, data: bytes) -> None:
    """Write ``data`` over the file ``path`` in place: no new file (and, up to the size of the
    blocks it holds, no new space). ``data`` cut to 512 bytes, the error's text shortened."""
    if len(data) > 512:
        data = (json.dumps({"status": json.loads(data)["status"], "error": json.loads(data).get("error", "")[:300]}) + "\n").encode()
    with open(path, "r+b") as f:
        f.write(data)
        f.truncate(len(data))


def read_summary(out: Path) -> dict[str, Any]:
    summary: dict[str, Any] = json.loads((out / SUMMARY).read_text())
    return summary


def damage(out: Path) -> str | None:
    """What is wrong with the finished run in ``out`` (None: nothing): a ``summary.json`` that
    cannot be read whole, a ``convergence.csv`` missing, cut short, or not ending at the
    summary's evaluation count."""
    try:
        written = read_summary(out)
    except (OSError, ValueError) as exc:
        return f"{out / SUMMARY} cannot be read ({type(exc).__name__})"
    if not isinstance(written, dict) or "final_cost" not in written:
        return f"{out / SUMMARY} is not a run's summary"
    try:
        with open(out / CONVERGENCE, newline="") as f:
            text = f.read()
        rows = list(csv.DictReader(text.splitlines()))
    except (OSError, ValueError, csv.Error) as exc:
        return f"{out / CONVERGENCE} cannot be read ({type(exc).__name__})"
    if not rows or not text.endswith("\n") or any(None in r.values() or None in r for r in rows):
        return f"{out / CONVERGENCE} is cut short"
    if "nevals" in written and str(rows[-1].get("nevals")) != str(written["nevals"]):
        return f"{out / CONVERGENCE} ends before the run did (nevals {rows[-1].get('nevals')}, not {written['nevals']})"
    return None


def clear(out: Path) -> None:
    """Remove a run's files from ``out`` (a damaged run, to be run again)."""
    for name in RUN_FILES:
        (out / name).unlink(missing_ok=True)


# --- a sweep ------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Sweep:
    """A job of a sweep: the sweep's directory, the job's number, its overrides (command-line
    lines) and its directory below the sweep's."""

    dir: Path
    job: int
    overrides: tuple[str, ...] = ()
    subdir: str = ""


def _append(path: Path, record: dict[str, Any]) -> None:
    line = json.dumps(record) + "\n"
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line.encode())
        finally:
            os.close(fd)
    except OSError as exc:  # a full disk: the error names the manifest
        from zrp_ga.core.fileio import named

        raise named(exc, path) from None


def record(sweep: Sweep, state: str, error: str | None = None) -> None:
    """Append the job's state to its sweep's manifest."""
    sweep.dir.mkdir(parents=True, exist_ok=True)
    _append(sweep.dir / MANIFEST, {
        "job": int(sweep.job),
        "overrides": " ".join(sweep.overrides),
        "dir": str(sweep.subdir),
        "status": state,
        "error": error,
        "time": datetime.datetime.now().isoformat(timespec="seconds"),
    })  # fmt: skip


def _records(sweep: Path) -> list[dict[str, Any]]:
    """The manifest's records, skipping a line a crash left unfinished."""
    out = []
    for line in (Path(sweep) / MANIFEST).read_text().splitlines():
        try:
            entry = json.loads(line)
        except ValueError:
            continue
        if isinstance(entry, dict) and "job" in entry:
            out.append(entry)
    return out


def job_states(sweep: str | Path) -> list[dict[str, Any]]:
    """Each job's last record, by job number."""
    last = {int(r["job"]): r for r in _records(Path(sweep))}
    return [{k: last[job].get(k) for k in COLUMNS} for job in sorted(last)]


def read_manifest(sweep: str | Path) -> pd.DataFrame:
    """One row per job with its last state (a pandas DataFrame): job, overrides, dir, status, error, time."""
    import pandas as pd

    return pd.DataFrame(job_states(sweep), columns=COLUMNS)


def write_table(sweep: str | Path) -> None:
    """``manifest.csv`` from ``manifest.jsonl``, replaced whole (nothing without a manifest)."""
    sweep = Path(sweep)
    if not (sweep / MANIFEST).exists():
        return
    tmp = sweep / f".manifest.{os.getpid()}.csv"
    try:
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=COLUMNS)
            writer.writeheader()
            writer.writerows(job_states(sweep))
        os.replace(tmp, sweep / TABLE)
    except OSError as exc:  # a full disk: the old table stays, the error names the file
        from zrp_ga.core.fileio import named

        tmp.unlink(missing_ok=True)
        raise named(exc, sweep / TABLE) from None


def repair(sweep: str | Path) -> None:
    """Before a sweep (started again) writes: end a line left unfinished by a crash, so that the
    next one stays whole, and remove temporary tables of killed processes."""
    sweep = Path(sweep)
    sweep.mkdir(parents=True, exist_ok=True)
    path = sweep / MANIFEST
    if path.exists() and path.stat().st_size:
        with open(path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            unfinished = f.read(1) != b"\n"
        if unfinished:
            fd = os.open(path, os.O_WRONLY | os.O_APPEND)
            try:
                os.write(fd, b"\n")
            finally:
                os.close(fd)
    for tmp in sweep.glob(".manifest.*.csv"):
        tmp.unlink(missing_ok=True)


SWEEP_RECORD = "sweep.json"  # in SHARED: what the sweep in this directory is (claim)


def claim(sweep: Path, overrides: list[str], grid: Any = None) -> None:
    """Make ``sweep`` the directory of the sweep of the command line's ``overrides`` (and the
    config's own sweep ``grid``: ``hydra.sweeper.params``), or refuse, with a ConfigError naming
    the folder and what differs, when it holds another sweep: one that ran jobs there, or whose
    process still runs. The same sweep started again goes on (its jobs continue). A sweep folder
    from before this record is taken as it is (each job still refuses a run of another config)."""
    from zrp_ga.core.schema import ConfigError

    path = sweep / SHARED / SWEEP_RECORD
    path.parent.mkdir(parents=True, exist_ok=True)
    mine = {"overrides": [o for o in overrides if not o.startswith(("progress=", "+progress="))], "grid": grid}
    for _ in range(2):
        try:
            theirs = json.loads(path.read_text())
        except FileNotFoundError:
            theirs = None
        except (OSError, ValueError):  # damaged: written again
            theirs = dict(mine)
        if theirs is None and _ran_jobs(sweep):  # a sweep folder from before this record: left as it was
            return
        if theirs is None:  # the first sweep here; two starting at once: one writes it, the other compares
            try:
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                continue
            with os.fdopen(fd, "w") as f:
                json.dump({**mine, "pid": os.getpid()}, f)
            return
        break
    same = {k: theirs.get(k) for k in mine} == mine
    if not same and (_ran_jobs(sweep) or _alive(theirs.get("pid"))):
        raise ConfigError(f"{sweep} holds another sweep ({_sweep_difference(mine, theirs)}); run this one into another "
                          "hydra.sweep.dir, or continue that one with its own command")  # fmt: skip
    from zrp_ga.core.fileio import write_json

    write_json(path, {**mine, "pid": os.getpid()})


def _ran_jobs(sweep: Path) -> bool:
    try:
        return bool(_records(sweep))
    except OSError:
        return False


def _alive(pid: Any) -> bool:
    if not isinstance(pid, int) or pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process
        return True
    return True


def _sweep_difference(mine: dict[str, Any], theirs: dict[str, Any]) -> str:
    """What differs between two sweeps' records (:func:`claim`), said in a few words."""

    def by_key(overrides: list[str]) -> dict[str, str]:
        return {k: v for k, _, v in (o.partition("=") for o in overrides or [])}

    a, b = by_key(mine["overrides"]), by_key(theirs.get("overrides") or [])
    said = [f"{k}={a[k]} here, {k}={b[k]} there" if k in a and k in b else f"{k}={a[k]} here, not there" if k in a
            else f"{k}={b[k]} there, not here" for k in [*a, *(k for k in b if k not in a)] if a.get(k) != b.get(k)]  # fmt: skip
    if mine.get("grid") != theirs.get("grid"):
        said.append("hydra.sweeper.params differ")
    if not said:
        said.append("the same settings in another order, which numbers the jobs otherwise")
    return "; ".join(said[:4]) + ("; ..." if len(said) > 4 else "")


def _hash(key: str, n: int) -> str:
    return hashlib.sha1(key.encode()).hexdigest()[:n]


def shared(sweep: Path | None, key: str, compute: Callable[[], dict[str, Any]], what: str) -> dict[str, Any]:
    """``compute()``, kept in the sweep directory as ``what`` under ``key``'s hash, so that the
    jobs of a sweep compute it once (outside a sweep: computed)."""
    if sweep is None:
        return compute()
    path = sweep / SHARED / f"{what}-{_hash(key, 16)}.json"
    try:
        kept: dict[str, Any] = json.loads(path.read_text())
        return kept
    except (OSError, ValueError):
        pass
    d = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(d))  # floats as repr: read back exactly (inf as Infinity)
    os.replace(tmp, path)
    return d


def first_to_ask(sweep: Path | None, what: str) -> bool:
    """True outside a sweep, and for the first job of a sweep that asks about ``what``."""
    if sweep is None:
        return True
    marks = sweep / SHARED
    marks.mkdir(parents=True, exist_ok=True)
    try:
        os.close(os.open(marks / f"announced-{_hash(what, 12)}", os.O_CREAT | os.O_EXCL))
    except FileExistsError:
        return False
    return True
