"""The files every run writes (DESIGN.md section 4), and nothing else.

- ``convergence.csv``: one row per generation (iteration), written and flushed as it happens;
- ``summary.json``: final figures, settings, versions, seed;
- ``best_params.csv``: the parameter errors by joint (the paper's Table 3), true values beside
  them when the case is simulated;
- ``initial_population.csv``: the initial genomes with their costs (the paper's Table 2).
"""

from __future__ import annotations

import csv
import json
import math
import platform
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd
from deap import tools

from zrp_ga.problem import CalibrationProblem

CONVERGENCE_COLUMNS = [
    "gen", "nevals", "best", "mean", "median", "std", "worst", "n_nonfinite",
    "val_rms", "val_max", "param_err", "eval_s", "bookkeeping_s", "refine_s", "wall_s",
]  # fmt: skip
WALL_CLOCK_COLUMNS = ["eval_s", "bookkeeping_s", "refine_s", "wall_s"]


class ConvergenceLog:
    """``convergence.csv``, one row per generation, flushed at once so that an interrupted run
    keeps every finished generation."""

    def __init__(self, path: Path, keep_until_gen: int | None = None):
        """A new file; or, resuming, the existing one cut after generation ``keep_until_gen``
        (rows a killed run wrote past its last checkpoint are written again by the resumed run)."""
        self.path = Path(path)
        kept = []
        if keep_until_gen is not None and self.path.exists():
            with open(self.path, newline="") as f:
                kept = [row for row in csv.DictReader(f) if int(row["gen"]) <= keep_until_gen]
        self._file = open(self.path, "w", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=CONVERGENCE_COLUMNS, extrasaction="ignore")
        self._writer.writeheader()
        self._writer.writerows(kept)
        self._file.flush()
        self._kept = kept

    def logbook(self) -> tools.Logbook:
        """A DEAP logbook of the rows kept from a resumed run (numbers as numbers)."""
        book = tools.Logbook()
        for row in self._kept:
            book.record(**{k: _number(v) for k, v in row.items()})
        return book

    def write(self, row: dict) -> None:
        self._writer.writerow({k: _plain(v) for k, v in row.items()})
        self._file.flush()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> ConvergenceLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _number(text: str):
    try:
        value = float(text)
    except ValueError:
        return text
    return int(value) if value.is_integer() and "." not in text and "e" not in text.lower() else value


def _plain(v):
    if isinstance(v, (np.floating, float)):
        return repr(float(v))
    if isinstance(v, np.integer):
        return int(v)
    return v


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for pkg in ("zrp_ga", "numpy", "scipy", "numba", "deap", "hydra-core", "cma"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def write_json(path: Path, data: dict) -> None:
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.floating, np.integer)):
            return o.item()
        return str(o)

    def clean(o):
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o

    text = json.dumps(clean(json.loads(json.dumps(data, default=default))), indent=2)
    Path(path).write_text(text + "\n")


def params_by_joint(problem: CalibrationProblem, de: np.ndarray, truth: np.ndarray | None = None) -> pd.DataFrame:
    """Parameter errors by joint (Table 3 style): ``du0_x..z`` of joint i and ``db0_x..z`` of
    ``b0_{i+1}`` (m); extra rows ``base`` (db0_1) and ``hand`` (rotation vector, rad); the true
    errors ``truth`` (default ``problem.true_de``) in ``true_*`` columns when known."""
    layout, n = problem.layout, problem.nominal.n
    blocks = layout.blocks

    def table(v: np.ndarray) -> pd.DataFrame:
        u = v[blocks["u0"]].reshape(n, 3)
        b = v[blocks["b0"]].reshape(n, 3)
        df = pd.DataFrame(np.hstack([u, b]), columns=["du0_x", "du0_y", "du0_z", "db0_x", "db0_y", "db0_z"])
        df.insert(0, "joint", [str(i) for i in range(1, n + 1)])
        extra = [(name, v[blocks[name]]) for name in ("base", "hand") if name in blocks]
        for name, vec in extra:
            cols = ["db0_x", "db0_y", "db0_z"] if name == "base" else ["du0_x", "du0_y", "du0_z"]
            df.loc[len(df)] = {"joint": name, **dict(zip(cols, vec))}
        return df

    out = table(np.asarray(de, dtype=float))
    truth = problem.true_de if truth is None else truth
    if truth is not None:
        truth = table(truth).drop(columns="joint").add_prefix("true_")
        out = pd.concat([out, truth], axis=1)
    return out


def population_table(problem: CalibrationProblem, genes: np.ndarray, costs: np.ndarray) -> pd.DataFrame:
    """Initial population (Table 2 style): one row per individual, one column per gene, its cost."""
    df = pd.DataFrame(genes, columns=problem.layout.names)
    df.insert(0, "individual", np.arange(1, len(genes) + 1))
    df["cost"] = costs
    return df
