"""What happens after each generation, outside the algorithm: timing, the validation error of
the reported genome, the convergence CSV, the progress line and checkpoints. Each is a
:class:`zrp_ga.algorithms.Callback`; the app runs them in that order (each adds to the row or
reads it)."""

from __future__ import annotations

import contextlib
import csv
import functools
import io
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from zrp_ga.algorithms import Algorithm, Callback, Result, Row, State
from zrp_ga.core import compiled
from zrp_ga.core.fileio import named
from zrp_ga.model.metrics import Judge
from zrp_ga.run import checkpoint

COLUMNS = [
    "gen", "nevals", "best", "mean", "median", "std", "worst", "n_nonfinite",
    "val_rms_mm", "val_max_mm", "param_err", "eval_s", "bookkeeping_s", "refine_s", "wall_s",
]  # fmt: skip
WALL_CLOCK_COLUMNS = ["eval_s", "bookkeeping_s", "refine_s", "wall_s"]
Array = NDArray[np.float64]
R = TypeVar("R")


class Timing(Callback):
    """Seconds spent per generation in the cost (``eval_s``), in the pseudo-inverse step
    (``refine_s``) and in everything else (``bookkeeping_s``: selection, variation, survival,
    statistics, callbacks), and since the start (``wall_s``). The toolbox's ``evaluate`` and
    ``refine`` are timed by decorating them (DEAP's ``Toolbox.decorate``)."""

    def on_start(self, algorithm: Algorithm) -> None:
        self.spent = {"eval_s": 0.0, "refine_s": 0.0}
        for alias, key in (("evaluate", "eval_s"), ("refine", "refine_s")):
            if hasattr(algorithm.toolbox, alias):
                algorithm.toolbox.decorate(alias, self._timed(key))
        self.last = self._now(algorithm)

    @staticmethod
    def _now(algorithm: Algorithm) -> float:
        return time.perf_counter() if algorithm.clock is None else algorithm.clock

    def _timed(self, key: str) -> Callable[[Callable[..., R]], Callable[..., R]]:
        def decorator(fn: Callable[..., R]) -> Callable[..., R]:
            @functools.wraps(fn)
            def timed(*args: Any, **kwargs: Any) -> R:
                t0 = time.perf_counter()
                try:
                    return fn(*args, **kwargs)
                finally:
                    self.spent[key] += time.perf_counter() - t0

            return timed

        return decorator

    def on_generation(self, algorithm: Algorithm, row: Row) -> None:
        now = self._now(algorithm)  # evolved with other runs: this run's share of their time
        total = now - self.last
        spent = {k: v + algorithm.shared_s.get(k, 0.0) for k, v in self.spent.items()}
        row.update(spent, bookkeeping_s=total - sum(spent.values()), wall_s=algorithm.elapsed())
        self.spent = dict.fromkeys(self.spent, 0.0)
        algorithm.shared_s = dict.fromkeys(algorithm.shared_s, 0.0)
        self.last = now


class Validation(Callback):
    """The validation error (mm) and the parameter error of the genome each row reports (judged
    again only when that genome changes: most generations keep their best)."""

    def __init__(self, judge: Judge):
        self.judge = judge
        self._last: tuple[bytes, dict[str, float]] | None = None

    @classmethod
    def together(cls, pairs: Sequence[tuple[Validation, Algorithm]]) -> None:
        """Judge the new reported genomes of runs evolved together in one call per judge (the
        validation poses' positions of all of them at once); each callback then finds its own."""
        todo: dict[int, list[tuple[Validation, Array]]] = {}
        for cb, algorithm in pairs:
            x = algorithm.current()[0]
            if x is not None:
                x = np.asarray(x, dtype=float)
                if cb._last is None or cb._last[0] != x.tobytes():
                    todo.setdefault(id(cb.judge), []).append((cb, x))
        for items in todo.values():
            judge = items[0][0].judge
            if len(items) < 2 or judge.layout.known_tools:  # known tools' ends are not computed `each`: alone
                continue
            rms, vmax = judge.validation_errors(np.stack([x for _, x in items]), each=True)
            for (cb, x), r, m in zip(items, rms.tolist(), vmax.tolist()):
                cb._last = (x.tobytes(), {"val_rms_m": r, "val_max_m": m, "param_err": float(judge.param_error(x)[0])})

    def on_generation(self, algorithm: Algorithm, row: Row) -> None:
        x = algorithm.current()[0]
        if x is None:  # no finite cost yet (the optimiser diverged): nothing to judge
            row.update(val_rms_mm=np.nan, val_max_mm=np.nan, param_err=np.nan)
            return
        x = np.asarray(x, dtype=float)
        if self._last is None or self._last[0] != x.tobytes():
            self._last = (x.tobytes(), self.judge(x))
        m = self._last[1]
        row.update(val_rms_mm=m["val_rms_m"] * 1e3, val_max_mm=m["val_max_m"] * 1e3, param_err=m["param_err"])


class ConvergenceLog(Callback):
    """``convergence.csv``: one row per generation, flushed at once, so that an interrupted run
    keeps every finished generation. Resuming, the rows up to ``keep_until_gen`` are kept (rows
    a killed run wrote past its last checkpoint are written again by the resumed run).
    ``buffered``: the rows are kept in memory and written, whole rows in one write, when
    :meth:`flush` is called (by the run's :class:`Checkpoint` before it saves), at the end and
    at an interrupt, as runs evolved together write them: the file then always holds every
    generation the checkpoint holds."""

    def __init__(self, path: str | Path, keep_until_gen: int | None = None, buffered: bool = False):
        self.path, self.keep_until_gen, self.buffered = Path(path), keep_until_gen, buffered

    def on_start(self, algorithm: Algorithm) -> None:
        kept = []
        if self.keep_until_gen is not None and self.path.exists():
            with open(self.path, newline="") as f:
                kept = [row for row in csv.DictReader(f) if int(row["gen"]) <= self.keep_until_gen]
        # The kept rows go to a new file that then replaces the old one: a kill meanwhile leaves
        # the old file whole (rewriting it in place would lose the rows a resumed run needs).
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            with open(tmp, "w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore", restval="")
                writer.writeheader()
                writer.writerows(kept)
            os.replace(tmp, self.path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise named(exc, self.path) from None
        self._file = open(self.path, "a", newline="")
        self._buffer = io.StringIO() if self.buffered else None
        self._writer = csv.DictWriter(self._buffer or self._file, fieldnames=COLUMNS, extrasaction="ignore", restval="")

    def on_generation(self, algorithm: Algorithm, row: Row) -> None:
        if self._buffer is None:
            with self._naming():
                self._writer.writerow({k: repr(float(v)) if isinstance(v, (float, np.floating)) else v for k, v in row.items()})
                self._file.flush()
        else:  # the same line csv writes for numbers (nothing to quote), joined directly
            self._buffer.write(_line(row))

    def flush(self) -> None:
        """Write the rows held in memory."""
        if self._file.closed:  # the run ended (an interrupt while its files were written)
            return
        with self._naming():
            if self._buffer is not None and self._buffer.tell():
                self._file.write(self._buffer.getvalue())  # whole rows in one write: a kill leaves no half row
                self._buffer.seek(0)
                self._buffer.truncate()
            self._file.flush()

    @contextlib.contextmanager
    def _naming(self) -> Iterator[None]:
        """A write's error (a full disk) naming this file; the file is closed then (its rows
        that did not fit are dropped, not written again by a later flush or at exit)."""
        try:
            yield
        except OSError as exc:
            with contextlib.suppress(OSError):
                self._file.close()
            raise named(exc, self.path) from None

    def on_interrupt(self, algorithm: Algorithm) -> None:
        self.flush()
        self._file.close()

    def on_end(self, algorithm: Algorithm, result: Result) -> None:
        self.flush()
        self._file.close()


def write_rows(path: str | Path, rows: Sequence[Row]) -> None:
    """``convergence.csv`` of a finished run from its rows (:attr:`zrp_ga.algorithms.Result.rows`),
    the lines :class:`ConvergenceLog` writes as the run goes (a calibration saved after the fact)."""
    with open(path, "w", newline="") as f:
        f.write(",".join(COLUMNS) + "\r\n")
        f.writelines(_line(row) for row in rows)


def _line(row: Row) -> str:
    """A row's line of ``convergence.csv`` (:func:`_cell` of each column's value, "" where it
    has none), with its line end: Python's floats and ints, most of a row, written directly."""
    return ",".join([repr(v) if type(v) is float else str(v) if type(v) is int else _cell(v)
                     for v in map(row.get, COLUMNS, _BLANK)]) + "\r\n"  # fmt: skip


_BLANK = [""] * len(COLUMNS)


def _cell(v: object) -> str:
    """A value as ``csv.DictWriter`` writes it in :class:`ConvergenceLog` (floats by repr)."""
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    text = "" if v is None else str(v)
    return f'"{text.replace(chr(34), 2 * chr(34))}"' if any(c in text for c in ',"\r\n') else text


def time_left(first: tuple[float, float | None], now: tuple[float, float | None]) -> float | None:
    """Seconds left from two (wall time s, fraction of the budget done) points, ``first`` and
    ``now``, at the pace between them; None before there is a pace. :class:`Progress` takes as
    ``first`` the end of the last generation in which numba compiled anything (or of the first
    generation this process ran), so that compiling or loading the kernels does not count."""
    (t0, f0), (t, f) = first, now
    if f is None or f0 is None or not f0 < f < 1 or t <= t0:
        return None
    return (t - t0) * (1 - f) / (f - f0)


class Progress(Callback):
    """A progress line (generation, evaluations, best cost, validation error, time left) at most
    twice a second and at the end; rewritten in place on a terminal, one line each otherwise.
    The time left is estimated from the generations after the last that compiled code
    (:func:`time_left`)."""

    def __init__(self, stream: IO[str] | None = None, every_s: float = 0.5):
        self.stream = stream or sys.stderr
        self.tty, self.every_s = self.stream.isatty(), every_s
        self._last, self._shown = -np.inf, None
        self._first: tuple[float, float | None] | None = None
        self._compiled = -1

    def on_generation(self, algorithm: Algorithm, row: Row) -> None:
        now = time.perf_counter()
        done = algorithm.fraction_done()
        if self._first is None or compiled.compilations() != self._compiled:  # the pace starts after compiling
            self._first, self._compiled = (row["wall_s"], done), compiled.compilations()
        if algorithm.has_next() and now - self._last < self.every_s:
            return
        self._last, self._shown = now, row["gen"]
        text = (f"gen {row['gen']:5d}  evals {row['nevals']:8d}  best {row['best']:.6g}  "
                f"val_rms {row.get('val_rms_mm', float('nan')):.4g} mm")  # fmt: skip
        left = time_left(self._first, (row["wall_s"], done))
        if left is not None:
            text += f"  time left {left:6.1f} s"
        self.stream.write(f"\r{text}\x1b[K" if self.tty else text + "\n")
        self.stream.flush()

    def on_end(self, algorithm: Algorithm, result: Result | None = None) -> None:
        if self.tty and self._shown is not None:
            self.stream.write("\n")
            self.stream.flush()

    on_interrupt = on_end


class Checkpoint(Callback):
    """``checkpoint.npz`` every ``every`` generations, after the last one, and on an interrupt
    (the state after the last finished generation), with the run's config, its groups' options and
    ``inputs`` (hashes of the robot and data it ran on: :func:`zrp_ga.run.build.inputs`).
    ``min_interval_s``: no checkpoint every ``every`` generations sooner than this after the
    last (runs evolved together: a batch's runs are short, their checkpoints a cost);
    ``before_save``: called before each save (a buffered :class:`ConvergenceLog`'s flush);
    ``final``: False: none after the last generation (a study's run, ``outputs=study``, keeps no
    finished run's checkpoint)."""

    def __init__(self, path: str | Path, every: int, config: dict[str, Any], choices: dict[str, Any] | None = None,
                 inputs: dict[str, str] | None = None, min_interval_s: float = 0.0, before_save: Callable[[], None] | None = None,
                 final: bool = True):  # fmt: skip
        self.path, self.every, self.config, self.choices = Path(path), every, config, choices or {}
        self.final = final
        self.inputs = inputs or {}
        self.min_interval_s, self.before_save = min_interval_s, before_save
        self._saved_at = time.monotonic()

    def on_generation(self, algorithm: Algorithm, row: Row) -> None:
        self.last: State = algorithm.state()
        due = self.every and algorithm.gen % self.every == 0 and time.monotonic() - self._saved_at >= self.min_interval_s
        last = not algorithm.has_next()
        if (last and self.final) or (due and not last):
            self.save()

    def on_interrupt(self, algorithm: Algorithm) -> None:
        if hasattr(self, "last"):
            self.save()

    def save(self) -> None:
        if self.before_save is not None:  # the buffered convergence rows first: the file holds what the checkpoint holds
            self.before_save()
        self._saved_at = time.monotonic()
        checkpoint.save(self.path, {**self.last, "config": self.config, "choices": self.choices, "inputs": self.inputs})
