"""Runs in IOHprofiler's format, for IOHanalyzer (upload the folder, zipped) and IOHinspector.

The layout is the one the ``ioh`` package's ``logger.Analyzer`` writes (ioh 0.4.2): one folder per
algorithm (here: per configuration) holding, per function (here: per problem instance), a meta
file ``IOHprofiler_f<id>_<name>.json`` and a data file ``data_f<id>_<name>/IOHprofiler_f<id>_DIM<D>.dat``.
The data file has one block per run: a line ``evaluations raw_y``, then ``<evaluations> <cost>``
lines from evaluation 1, at each improvement of the best cost and at the run's last evaluation
(the cost written is the best so far, which is what IOHanalyzer analyses; a run whose
initial_population.csv cannot be read has its first row's best from evaluation 1 on). Costs are written
exactly (``repr``), not with ioh's ten fixed decimals, which would turn round-off-level costs
into 0. Minimisation; D is the genome's length. IOHprofiler's conventions: a function is one
problem (here one problem instance of the suite, as it is one for every configuration) and its
repetitions are told apart by their instance ids (IOHanalyzer averages over them): a run's
instance id is its seed (summary.json's ``seed``; the runs of a function without a usable seed
are numbered 1, 2, ... instead). Function ids number the problem instances 1, 2, ... in name
order, the same in every configuration's folder. No other file may be in the folder:
IOHanalyzer takes a .csv or .txt file beside the data as another format and refuses the folder.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from zrp_ga.report.runs import Run
from zrp_ga.report.targets import dimension

FORMAT_VERSION = "0.4.2"  # the ioh release whose Analyzer output this layout follows


def safe_name(text: str) -> str:
    """``text`` as a file-name part: letters, digits, ``.``, ``-`` and ``_`` only.

    >>> safe_name("GA, sbx crossover")
    'GA_sbx_crossover'
    """
    return re.sub(r"[^A-Za-z0-9.\-]+", "_", text).strip("_") or "unnamed"


def lines(run: Run) -> list[str]:
    """The run's block of the data file: the header, then evaluations and best cost at each
    improvement (the first evaluation included) and at the last evaluation."""
    e, b = run.evals, run.best
    keep = np.r_[True, b[1:] < b[:-1]]
    out = ["evaluations raw_y"] + [f"{int(n)} {float(c)!r}" for n, c in zip(e[keep], b[keep])]
    if e[0] > 1:  # no initial_population.csv to tell evaluation by evaluation: the first row's best from the start
        out.insert(1, f"1 {float(b[0])!r}")
    last = max(int(e[-1]), run.nevals)
    if not keep[-1] or last > int(e[-1]):
        out.append(f"{last} {float(b[-1])!r}")
    return out


def instance_ids(runs: list[Run]) -> list[int]:
    """Each run's IOHprofiler instance id: its seed when every run has a distinct non-negative
    integer seed, else 1, 2, ... in the runs' order."""
    seeds: list[Any] = [r.summary.get("seed") for r in runs]
    if all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds) and len(set(seeds)) == len(seeds):
        return seeds
    return list(range(1, len(runs) + 1))


def _meta(fid: int, name: str, label: str, info: str, dim: int, path: str, runs: list[Run]) -> dict:
    records = []
    for r, iid in zip(runs, instance_ids(runs)):
        at = int(r.evals[int(np.argmin(r.best))])
        genome = r.summary.get("best_genome")
        x = list(genome.values()) if isinstance(genome, dict) else list(genome or [])
        records.append({"instance": iid, "evals": max(r.nevals, int(r.evals[-1])), "best": {"evals": at, "y": float(r.best[-1]), "x": x}})
    return {
        "version": FORMAT_VERSION, "suite": "zrp_ga", "function_id": fid, "function_name": name, "maximization": False,
        "algorithm": {"name": label, "info": info}, "attributes": ["evaluations", "raw_y"],
        "scenarios": [{"dimension": dim, "path": path, "runs": records}],
    }  # fmt: skip


def export(runs: list[Run], labels: list[str], shown: dict[str, dict[str, str]], out: Path) -> list[tuple[str, str]]:
    """Write ``runs`` into ``out`` (see the module docstring); ``shown``: per label, the settings
    its label names (the algorithm's info). Returns the runs left out, as (path, reason): those
    that never had a finite cost (JSON has no infinity)."""
    instances = sorted({r.instance for r in runs})
    fids = {name: i for i, name in enumerate(instances, start=1)}
    folders: dict[str, str] = {}
    for label in dict.fromkeys(labels):
        folder = safe_name(label)
        while folder in folders.values():
            folder += "_"
        folders[label] = folder
    cells: dict[tuple[str, str], list[Run]] = {}
    for r, lab in zip(runs, labels):
        cells.setdefault((lab, r.instance), []).append(r)
    left = []
    for label, folder in folders.items():
        for instance in instances:
            group = cells.get((label, instance), [])
            bad = [r for r in group if not math.isfinite(float(r.best[-1]))]
            left += [(str(r.path), "no finite cost") for r in bad]
            group = [r for r in group if r not in bad]
            if not group:
                continue
            fid, name = fids[instance], safe_name(instance)
            dim = max(dimension(r) for r in group)
            rel = f"data_f{fid}_{name}/IOHprofiler_f{fid}_DIM{dim}.dat"
            (out / folder / rel).parent.mkdir(parents=True, exist_ok=True)
            (out / folder / rel).write_text("\n".join(line for r in group for line in lines(r)) + "\n")
            info = "; ".join(f"{k}={v}" for k, v in shown.get(label, {}).items()) or label
            meta = _meta(fid, name, label, info, dim, rel, group)
            (out / folder / f"IOHprofiler_f{fid}_{name}.json").write_text(json.dumps(meta, indent=1) + "\n")
    return left
