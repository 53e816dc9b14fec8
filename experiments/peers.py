"""The GA beside what a user would pick instead, on the suite's instances: pymoo's GA and DE,
nevergrad's CMA-ES and the cma package's, each fed the package's vectorised cost, at the same
evaluation budget; Levenberg-Marquardt gives each instance's floor.

    pip install ".[peers]"      # pymoo, nevergrad
    python experiments/peers.py [--seeds 10] [--budget 20000] [--instances puma560_30poses ...]
          [--ga "crossover=blend mutation=polynomial ..."]

Writes experiments/results/peers.md (median over seeds of the final cost / floor, the share of
seeds reaching 1.05 x and 1.01 x the floor, and the median evaluations to do so).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from zrp_ga import config
from zrp_ga.core import targets
from zrp_ga.run import build

RESULTS = Path(__file__).parent / "results"
SUITE = ["puma560_1pose", "puma560_6poses", "puma560_30poses", "puma560_200poses", "puma560_30poses_exact",
         "puma560_30poses_tracker", "puma560_30poses_positions", "ur10_30poses", "stanford_30poses", "ur10_ipa"]  # fmt: skip
LEVELS = (1.05, 1.01)


class Trace:
    """The best cost after each batch of evaluations: (evaluations, best so far)."""

    def __init__(self):
        self.evals, self.best = [], []

    def add(self, n: int, costs: np.ndarray) -> None:
        finite = costs[np.isfinite(costs)]
        low = float(finite.min()) if finite.size else np.inf
        self.evals.append((self.evals[-1] if self.evals else 0) + n)
        self.best.append(min(low, self.best[-1]) if self.best else low)

    def first(self, target: float) -> float:
        hit = [e for e, b in zip(self.evals, self.best) if b <= target]
        return float(hit[0]) if hit else np.inf


def ga(problem, budget: int, seed: int, overrides: list[str]) -> Trace:
    """zrp_ga's GA with the given settings (population.max_evals = the budget)."""
    from zrp_ga.algorithms import Callback

    trace = Trace()

    class Record(Callback):
        def on_generation(self, algorithm, row):
            trace.evals.append(row["nevals"])
            trace.best.append(min(row["best"], trace.best[-1]) if trace.best else row["best"])

    cfg = config.load(overrides + ["population.generations=null", f"population.max_evals={budget}"])
    targets.create(cfg.algorithm, "algorithm").run(problem, np.random.default_rng([seed, 0]), [Record()])
    return trace


def pymoo_run(problem, budget: int, seed: int, which: str) -> Trace:
    from pymoo.algorithms.soo.nonconvex.de import DE
    from pymoo.algorithms.soo.nonconvex.ga import GA
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize

    trace = Trace()

    class Vectorised(Problem):
        def __init__(self):
            super().__init__(n_var=problem.lower.size, n_obj=1, xl=problem.lower, xu=problem.upper)

        def _evaluate(self, X, out, *args, **kwargs):
            costs = problem.costs(X)
            trace.add(len(X), costs)
            out["F"] = np.where(np.isfinite(costs), costs, np.finfo(float).max)[:, None]

    algorithm = DE(pop_size=50) if which == "DE" else GA(pop_size=50)
    minimize(Vectorised(), algorithm, ("n_evals", budget), seed=seed, verbose=False)
    return trace


def nevergrad_cma(problem, budget: int, seed: int) -> Trace:
    import nevergrad as ng

    trace = Trace()
    param = ng.p.Array(init=np.zeros(problem.lower.size), lower=problem.lower, upper=problem.upper)
    param.random_state = np.random.RandomState(seed)
    opt = ng.optimizers.CMA(parametrization=param, budget=budget, num_workers=20)
    done = 0
    while done < budget:
        asked = [opt.ask() for _ in range(min(20, budget - done))]
        costs = problem.costs(np.array([a.value for a in asked]))
        trace.add(len(asked), costs)
        done += len(asked)
        for a, c in zip(asked, costs):
            opt.tell(a, float(c) if np.isfinite(c) else 1e300)
    return trace


def cma_package(problem, budget: int, seed: int) -> Trace:
    """zrp_ga's CMA-ES (the cma package) through the same interface as the GA."""
    return ga(problem, budget, seed, ["algorithm=cmaes", "population.lambda_=20"])


def floor_of(task) -> float:
    """The floor's reference as runs with ``objective=over_floor`` divide by (LM's cost, or 1e-9 x
    the nominal cost where that is round-off)."""
    from zrp_ga.run import summary

    return summary.floor(task)["reference"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--budget", type=int, default=20000)
    parser.add_argument("--instances", nargs="*", default=SUITE)
    parser.add_argument("--ga", default="refine=none crossover=blend mutation=polynomial mutation.op.eta=100 "
                        "inversion=none rotation=none population.mu=50 population.lambda_=50",
                        help="the GA's settings (default: the best pure set of the operator study)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=RESULTS / "peers.md")
    parser.add_argument("--methods", nargs="*", default=None, help="a subset of the methods (default: all)")
    args = parser.parse_args()
    methods = {"zrp_ga GA": lambda p, s: ga(p, args.budget, s, args.ga.split()),
               "pymoo GA": lambda p, s: pymoo_run(p, args.budget, s, "GA"),
               "pymoo DE": lambda p, s: pymoo_run(p, args.budget, s, "DE"),
               "nevergrad CMA": lambda p, s: nevergrad_cma(p, args.budget, s),
               "cma (zrp_ga CMAES)": lambda p, s: cma_package(p, args.budget, s)}  # fmt: skip
    if args.methods:
        methods = {k: v for k, v in methods.items() if k in args.methods}
    rows, raw = [], []
    for name in args.instances:
        task = build.prepare(config.load([f"instance={name}"]), None).task
        floor = floor_of(task)
        for method, run in methods.items():
            t0 = time.perf_counter()
            traces = [run(task.problem, s) for s in range(args.seeds)]
            ratio = [t.best[-1] / floor for t in traces]
            hits = {c: [t.first(c * floor) for t in traces] for c in LEVELS}
            raw.append({"instance": name, "method": method, "floor": floor, "ratio": ratio,
                        "evals_to": {str(c): v for c, v in hits.items()}})  # fmt: skip
            cells = [f"{np.median(ratio):.4f}"]
            for c in LEVELS:
                e = np.array(hits[c])
                ok = np.isfinite(e)
                cells.append(f"{ok.sum()}/{len(e)}" + (f", {np.median(e[ok]):,.0f}" if ok.any() else ""))
            rows.append(f"| {name} | {method} | {' | '.join(cells)} | {time.perf_counter() - t0:.1f} |")
            print(rows[-1], flush=True)
            write(args, rows, raw)  # after every method: a long run killed keeps what it finished
    print(f"wrote {args.out}")


def write(args: argparse.Namespace, rows: list[str], raw: list[dict]) -> None:
    head = ["# The GA beside pymoo's GA and DE, nevergrad's CMA and cma", "",
            f"Command: `python experiments/peers.py --seeds {args.seeds} --budget {args.budget} "
            f"--instances {' '.join(args.instances)}` (GA settings: `{args.ga}`). Budget {args.budget:,} cost "
            f"evaluations, {args.seeds} seeds; the floor is LM's final cost (1e-9 x the nominal cost where that is "
            "at round-off).", "",
            "| instance | method | final cost / floor, median | seeds reaching 1.05 x, median evaluations | "
            "seeds reaching 1.01 x, median evaluations | wall s |", "|---|---|---|---|---|---|"]  # fmt: skip
    args.out.parent.mkdir(exist_ok=True)
    args.out.write_text("\n".join(head + rows) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(raw, indent=1, default=float))


if __name__ == "__main__":
    main()
