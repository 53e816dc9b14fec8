"""Writers of the files a run leaves besides ``convergence.csv`` (written as it goes by
:class:`zrp_ga.run.callbacks.ConvergenceLog`):

- ``summary.json``: final figures, settings, versions, seed, warnings;
- ``best_params.csv``: the parameter errors by joint (the paper's Table 3), the true ones beside
  them in simulation;
- ``initial_population.csv``: the initial genomes with their costs (the paper's Table 2).

Plain ``csv`` and ``json``: a run does not import pandas.
"""

from __future__ import annotations

import csv
import functools
import io

import numpy as np

from zrp_ga.core.fileio import package_versions, write_csv, write_json, yaml_text  # noqa: F401 (the writers' names here, as before)
from zrp_ga.model.layout import Layout


@functools.cache  # looked up in the installed packages' metadata: 10 ms a run, the same every time
def _versions() -> tuple[tuple[str, str], ...]:
    return tuple(package_versions(("zrp_ga", "numpy", "scipy", "numba", "deap", "hydra-core", "cma")).items())


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a run uses."""
    return dict(_versions())


def params_by_joint(layout: Layout, x: np.ndarray, truth: np.ndarray | None = None) -> list[dict]:
    """Parameter errors by joint (Table 3 style): ``du0_x..z`` of joint i and ``db0_x..z`` of
    ``b0_{i+1}`` (m); extra rows ``base`` (db0_1), ``hand`` (rotation vector, rad) and ``tool2`` ..
    (the other tools' last body vectors, m); with non-geometric terms, a row per term (its name,
    ``term_value`` and ``term_unit``: rad/(N m) for a compliance, rad for a harmonic); the true
    errors in ``true_*`` columns when known. With fixed genes (zero: nominal), a ``fixed`` column
    names them per row."""
    x, truth = layout.expand(x), None if truth is None else layout.expand(truth)
    fixed, layout = set(layout.fixed), layout.unmasked
    n, blocks = layout.n, layout.blocks
    u_cols, b_cols = ["du0_x", "du0_y", "du0_z"], ["db0_x", "db0_y", "db0_z"]

    def table(v: np.ndarray) -> list[dict]:
        u, b = v[blocks["u0"]].reshape(n, 3), v[blocks["b0"]].reshape(n, 3)
        rows = [{"joint": str(i + 1), **dict(zip(u_cols, u[i])), **dict(zip(b_cols, b[i]))} for i in range(n)]
        for name, cols in [("base", b_cols), ("hand", u_cols)] + [(k, b_cols) for k in blocks if k.startswith("tool")]:
            if name in blocks:
                rows.append({"joint": name, **dict.fromkeys(u_cols + b_cols, ""), **dict(zip(cols, v[blocks[name]]))})
        if layout.terms:  # one row per non-geometric term: its value in term_value, its unit in term_unit
            for row in rows:
                row.update(term_value="", term_unit="")
            for name, value in zip(layout.terms.names, v[blocks["terms"]]):
                unit = "rad/(N m)" if name.startswith("compliance_") else "rad"
                rows.append({"joint": name, **dict.fromkeys(u_cols + b_cols, ""), "term_value": value, "term_unit": unit})
        return rows

    out = table(np.asarray(x, dtype=float))
    if fixed:
        for row in out:
            j = row["joint"]
            if j in layout.terms.names:
                row["fixed"] = j if j in fixed else ""
                continue
            genes = {"base": ["b0_1{}"], "hand": ["rh_{}"]}.get(j) or (
                [f"u0_{j}{{}}", f"b0_{int(j) + 1}{{}}"] if j.isdigit() else [f"b0_{n + 1}{{}}_{j}"])  # fmt: skip
            row["fixed"] = " ".join(g.format(c) for g in genes for c in "xyz" if g.format(c) in fixed)
    if truth is not None:
        for row, true in zip(out, table(np.asarray(truth, dtype=float))):
            row.update({f"true_{k}": v for k, v in true.items() if k not in ("joint", "term_unit")})
    return out


def write_population(path, names: list[str], X: np.ndarray, costs: np.ndarray) -> None:
    """``write_csv(path, population_table(names, X, costs))``, the same text, row by row from the
    arrays (a sweep writes one per run: building a dict per individual took most of the time)."""
    X, costs = np.asarray(X), np.asarray(costs)
    columns = ["individual", *names, "cost"]
    if (len(set(columns)) != len(columns) or X.ndim != 2 or X.shape[1] != len(names) or X.dtype.kind != "f"
            or costs.shape != (len(X),) or costs.dtype.kind != "f" or not len(X)):  # fmt: skip
        write_csv(path, population_table(names, X, costs))  # the general path
        return
    out = io.StringIO()
    csv.writer(out).writerow(columns)  # the header as csv.DictWriter writes it (names quoted where they must be)
    # each row as it writes it: floats as repr (write_csv), which needs no quoting; repr(list) joins them in C
    out.writelines(f"{i + 1},{repr(x)[1:-1].replace(', ', ',')},{c!r}\r\n"
                   for i, (x, c) in enumerate(zip(X.tolist(), costs.tolist())))  # fmt: skip
    with open(path, "w", newline="") as f:
        f.write(out.getvalue())


def population_table(names: list[str], X: np.ndarray, costs: np.ndarray) -> list[dict]:
    """Initial population (Table 2 style): one row per individual, one column per gene, its cost."""
    return [{"individual": i + 1, **dict(zip(names, x)), "cost": c} for i, (x, c) in enumerate(zip(X, costs))]
