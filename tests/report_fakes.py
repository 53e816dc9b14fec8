"""Made-up run directories for the report's tests: the files a run writes (summary.json,
convergence.csv, status.json, optionally initial_population.csv) with numbers chosen so that
every figure of the report can be computed by hand."""

from __future__ import annotations

import json
from pathlib import Path

ALGORITHMS = {
    "ga": {"_target_": "zrp_ga.algorithms.ga.GA", "population": {"mu": 10, "lambda_": 10, "generations": 5, "max_evals": None},
           "crossover": {"prob": 0.8, "op": {"_target_": "zrp_ga.operators.crossover.blend", "_partial_": True}}},
    "lm": {"_target_": "zrp_ga.algorithms.lm.LM", "max_evals": None},
    "cmaes": {"_target_": "zrp_ga.algorithms.cmaes.CMAES", "sigma0": 0.3},
}  # fmt: skip


def fake_run(path: Path, instance: str, algorithm: str, rows: list[tuple[int, float]], *, final: float | None = None,
             nominal: float = 10.0, floor: float | None = None, seed: int = 0, initial: list[float] | None = None,
             validation: float | None = 1.0, config: dict | None = None, choices: dict | None = None,
             stop_reason: str = "max_evals") -> Path:  # fmt: skip
    """A finished run in ``path``: ``rows`` are (evaluations, best cost) per generation; the final
    cost is the last row's unless ``final`` is given (None there writes null, a diverged run);
    ``stop_reason``: why it stopped (its budget, by default; anything else: by itself)."""
    path.mkdir(parents=True)
    lines = ["gen,nevals,best,mean"] + [f"{g},{e},{b!r},{b!r}" for g, (e, b) in enumerate(rows)]
    (path / "convergence.csv").write_text("\n".join(lines) + "\n")
    if initial is not None:
        (path / "initial_population.csv").write_text("individual,g1,cost\n" + "".join(f"{i + 1},0.0,{c!r}\n" for i, c in enumerate(initial)))
    cost = rows[-1][1] if final is None else final
    summary = {
        "instance": instance, "algorithm": algorithm, "choices": {"algorithm": algorithm} if choices is None else choices, "seed": seed,
        "final_cost": cost, "initial_cost": rows[0][1], "nominal_cost": nominal,
        "final_over_initial": None if cost is None else cost / rows[0][1], "nevals": rows[-1][0], "wall_s": 0.1,
        "stop_reason": stop_reason,
        "validation_rms_mm": {"nominal": None if validation is None else 10.0, "calibrated": validation},
        "best_genome": {"g1": 0.5, "g2": -0.25}, "config": {"algorithm": config or ALGORITHMS[algorithm], "seed": seed},
    }  # fmt: skip
    if floor is not None:
        summary["floor"] = floor
    (path / "summary.json").write_text(json.dumps(summary))
    (path / "status.json").write_text('{"status": "done"}')
    return path


def many(root: Path, runs: int, configurations: int = 5, generations: int = 60, seed: int = 0) -> None:
    """``runs`` made-up finished runs under ``root``: ``configurations`` crossovers on one
    instance, each run its own seed (no two configurations share one: the independent-runs
    design, whose effect sizes need the most memory), a GA-like trace of ``generations`` rows."""
    import numpy as np

    rng = np.random.default_rng(seed)
    names = ["blend", "sbx", "two_point", "one_point", "uniform", "x5", "x6", "x7", "x8", "x9"][:configurations]
    for i in range(runs):
        cx = names[i % configurations]
        cfg = json.loads(json.dumps(ALGORITHMS["ga"]))
        cfg["crossover"]["op"]["_target_"] = f"zrp_ga.operators.crossover.{cx}"
        start, end = 10.0 * (1 + rng.random()), 1.0 + 0.1 * (i % configurations) + 0.5 * rng.random()
        best = start * (end / start) ** (np.arange(generations) / (generations - 1))
        rows = [(50 * (g + 1), float(b)) for g, b in enumerate(best)]
        fake_run(root / f"run{i:05d}", "inst", "ga", rows, floor=1.0, seed=i, config=cfg, nominal=20.0,
                 choices={"algorithm": "ga", "crossover": cx}, validation=float(0.5 + rng.random()))  # fmt: skip


if __name__ == "__main__":  # python tests/report_fakes.py DIR RUNS: made-up runs to measure the report on
    import sys

    many(Path(sys.argv[1]), int(sys.argv[2]))


def crossover_study(root: Path, instances: int = 4, seeds: int = 4) -> None:
    """Three crossovers (blend, sbx, two_point) on ``instances`` instances, ``seeds`` shared seeds
    each, blend always best: every figure of the report drawn (with four instances, Friedman's
    test across them, p = exp(-4), draws the critical-difference diagram)."""
    import copy

    for i in range(instances):
        inst, floor = f"inst-{'ABCD'[i]}", (0.01, 0.02, 0.03, 0.04)[i]
        for cx, scale in (("blend", 1.0), ("sbx", 1.4), ("two_point", 2.0)):
            cfg = copy.deepcopy(ALGORITHMS["ga"])
            cfg["crossover"]["op"]["_target_"] = f"zrp_ga.operators.crossover.{cx}"
            for seed in range(seeds):
                rows = [(10 * (g + 1), floor * (1 + (10 + seed) * scale * 0.5**g)) for g in range(8)]
                fake_run(root / f"{inst}-{cx}-{seed}", inst, "ga", rows, floor=floor, seed=seed, config=cfg, nominal=1.0,
                         choices={"algorithm": "ga", "crossover": cx}, validation=1 + 0.1 * scale + 0.01 * seed)  # fmt: skip
