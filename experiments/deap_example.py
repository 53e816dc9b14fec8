"""An ordinary DEAP script on a ZRP calibration problem: zrp_ga's cost, zrp_ga's operators and
the pseudo-inverse step (the paper's step 8) registered in a plain DEAP toolbox on list
individuals, run by DEAP's own ``algorithms.eaMuPlusLambda``.

    python experiments/deap_example.py [--generations 100] [--seed 0]

The operators are the defaults of ``zrp-ga``: tournaments of 3, two-point crossover, Gaussian
mutation (sigma 0.1 of the gene range, indpb 0.2), children clipped into the gene ranges, and
a tenth of the children taking the pseudo-inverse step. ``zrp_ga.operators.deap_tools.for_deap`` turns
each into DEAP's convention (lists changed in place); ``toolbox.map`` evaluates a generation in
one vectorised call. It prints the final cost beside Levenberg-Marquardt's floor on the same
problem (the 30-pose PUMA 560 problem of ``zrp-ga problem=multipose``).
"""

from __future__ import annotations

import argparse
import random

import numpy as np
from deap import algorithms, base, tools

from zrp_ga import config
from zrp_ga.operators import crossover, deap_tools, mutation, refine, selection
from zrp_ga.run.build import prepare


def toolbox_for(problem, rng: np.random.Generator, refine_share: float = 0.1) -> base.Toolbox:
    """A DEAP toolbox with the problem's cost and zrp_ga's default operators on list individuals."""
    low, up = problem.lower, problem.upper
    tb = base.Toolbox()
    tb.register("individual", lambda: deap_tools.Individual(rng.uniform(low, up).tolist()))
    tb.register("population", tools.initRepeat, list, tb.individual)
    tb.register("evaluate", deap_tools.evaluator(problem))
    tb.register("map", deap_tools.batched_map(problem))  # one vectorised call per generation
    tb.register("select", deap_tools.for_deap(selection.tournament, rng, size=3))
    tb.register("mate", deap_tools.for_deap(crossover.two_point, rng))
    tb.register("mutate", deap_tools.for_deap(mutation.gaussian, rng, low=low, up=up, sigma=0.1, indpb=0.2))
    step = deap_tools.for_deap(refine.pinv, rng, problem=problem, rcond=1e-9)  # the pseudo-inverse step
    for alias in ("mate", "mutate"):  # vary, clip into the ranges, a share takes the step, clip again
        tb.decorate(alias, deap_tools.within(low, up), deap_tools.sometimes(step, refine_share, rng),
                    deap_tools.within(low, up))  # fmt: skip
    return tb


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    random.seed(args.seed)  # eaMuPlusLambda's own draws (which child is crossed or mutated)
    rng = np.random.default_rng(args.seed)  # zrp_ga's operators
    cfg = config.load(["problem=multipose", f"seed={args.seed}"])
    problem = prepare(cfg, None).task.problem  # the same problem instance zrp-ga builds
    toolbox = toolbox_for(problem, rng)

    stats = tools.Statistics(lambda ind: ind.fitness.values[0])
    stats.register("best", np.min)
    hof = tools.HallOfFame(1)
    pop = toolbox.population(n=50)
    pop, log = algorithms.eaMuPlusLambda(pop, toolbox, mu=50, lambda_=50, cxpb=0.6, mutpb=0.3, ngen=args.generations,
                                         stats=stats, halloffame=hof, verbose=False)  # fmt: skip

    from zrp_ga.algorithms.lm import LM

    floor = LM().run(problem, np.random.default_rng(0)).cost
    best = hof[0].fitness.values[0]
    print(f"DEAP eaMuPlusLambda with zrp_ga's operators, {args.generations} generations: best cost {best:.6g} "
          f"= {best / floor:.6f} x the LM floor {floor:.6g}")  # fmt: skip
    return {"best": best, "floor": floor, "log": log}


if __name__ == "__main__":
    main()
