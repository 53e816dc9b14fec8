"""The pure GA on the identified genome (``problem.subspace=identified``, the default) against
the old genome (``problem.subspace=full``: every parameter a gene) and against CMA-ES (the cma
package as zrp_ga's ``algorithm=cmaes``, and nevergrad's CMA, as experiments/peers.py runs
them): the cost evaluations to reach 1.05 x the floor, per seed.

    pip install -e ".[peers]"
    python experiments/identified_genome.py [--seeds 10] [--budget 20000]
          [--instances puma560_30poses ur10_30poses stanford_30poses] [--methods ...]

The floor of an instance is Levenberg-Marquardt's final cost on the old genome (every
parameter free: the lowest of the two floors; the identified genome's own floor, LM within
it, is in the table too), so that both genomes chase the same target. A run stops at its first
hit (at most ``--budget`` evaluations). The GA is the pure GA of experiments/peers.py (no
pseudo-inverse step: blend crossover, polynomial mutation with eta 100, mu = lambda = 50).
Writes experiments/results/identified_genome.md and .json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import peers  # the peers' runners, as they are benchmarked there

from zrp_ga import config
from zrp_ga.run import build, summary

RESULTS = Path(__file__).parent / "results"
INSTANCES = ["puma560_30poses", "ur10_30poses", "stanford_30poses"]
PURE_GA = ("refine=none crossover=blend mutation=polynomial mutation.op.eta=100 inversion=none rotation=none "
           "population.mu=50 population.lambda_=50")  # fmt: skip
TARGET = 1.05


class Hit(Exception):
    """The target was reached: the run stops."""


class Stopping:
    """``problem`` whose cost evaluations are counted; raises :class:`Hit` once a cost reaches
    ``target`` (everything else is the problem's)."""

    def __init__(self, problem, target: float) -> None:
        self._p, self.target, self.evals, self.hit = problem, target, 0, None

    def __getattr__(self, name):
        return getattr(self._p, name)

    def costs(self, X):
        c = self._p.costs(X)
        first = np.flatnonzero(np.asarray(c) <= self.target)
        if first.size and self.hit is None:
            self.hit = self.evals + int(first[0]) + 1
        self.evals += len(c)
        if self.hit is not None:
            raise Hit
        return c


def evals_to(run, problem, target: float) -> float:
    """Evaluations until ``run(problem)`` first reaches ``target`` (inf if it never does)."""
    s = Stopping(problem, target)
    try:
        run(s)
    except Hit:
        pass
    return float(s.hit) if s.hit is not None else np.inf


METHODS = {
    "zrp_ga GA (pure)": lambda p, seed, budget: peers.ga(p, budget, seed, PURE_GA.split()),
    "cma (zrp_ga CMAES)": lambda p, seed, budget: peers.cma_package(p, budget, seed),
    "nevergrad CMA": lambda p, seed, budget: peers.nevergrad_cma(p, budget, seed),
}


def task_of(instance: str, subspace: str):
    return build.prepare(config.load([f"instance={instance}", f"problem.subspace={subspace}"]), None).task


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--budget", type=int, default=20000)
    ap.add_argument("--instances", nargs="*", default=INSTANCES)
    ap.add_argument("--methods", nargs="*", default=list(METHODS))
    ap.add_argument("--out", type=Path, default=RESULTS / "identified_genome.md")
    args = ap.parse_args()
    raw = []
    for name in args.instances:
        tasks = {g: task_of(name, g) for g in ("full", "identified")}
        floors = {g: summary.floor(t)["reference"] for g, t in tasks.items()}
        target = TARGET * floors["full"]
        for method in args.methods:
            for genome, task in tasks.items():
                t0 = time.perf_counter()
                run = METHODS[method]
                hits = [evals_to(lambda p, s=s, run=run: run(p, s, args.budget), task.problem, target) for s in range(args.seeds)]
                raw.append({"instance": name, "method": method, "genome": genome, "genes": task.problem.lower.size,
                            "floor": floors[genome], "floor_full": floors["full"], "evals": hits,
                            "wall_s": time.perf_counter() - t0})  # fmt: skip
                print(_row(raw[-1]), flush=True)
                write(args, raw)
    print(f"wrote {args.out}")


def _row(r: dict) -> str:
    e = np.array(r["evals"])
    ok = np.isfinite(e)
    med = f"{np.median(e[ok]):,.0f}" if ok.any() else "-"
    quart = f"{np.percentile(e[ok], 25):,.0f} - {np.percentile(e[ok], 75):,.0f}" if ok.any() else "-"
    return (f"| {r['instance']} | {r['method']} | {r['genome']} | {r['genes']} | {r['floor'] / r['floor_full']:.4f} | "
            f"{ok.sum()}/{e.size} | {med} | {quart} | {r['wall_s']:.0f} |")  # fmt: skip


def write(args, raw: list[dict]) -> None:
    head = ["# The pure GA on the identified genome, the old genome and CMA-ES", "",
            f"Command: `python experiments/identified_genome.py --seeds {args.seeds} --budget {args.budget} --instances "
            f"{' '.join(args.instances)}`. Target: {TARGET} x the floor, LM's final cost on the old genome (every "
            "parameter free); a run stops at its first hit. Genes: the genome's size (identified: the combinations the "
            "data identify). Own floor: LM's final cost within the genome over the old floor. Wall times on a machine "
            "running other jobs.", "",
            "| instance | method | genome | genes | own floor / floor | seeds reaching 1.05 x | median evaluations | "
            "quartiles | wall s |", "|---|---|---|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    args.out.parent.mkdir(exist_ok=True)
    args.out.write_text("\n".join(head + [_row(r) for r in raw]) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(raw, indent=1, default=float))


if __name__ == "__main__":
    main()
