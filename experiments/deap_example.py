"""An ordinary DEAP script on a ZRP calibration problem: DEAP's own operators and
``algorithms.eaMuPlusLambda``, with the package's cost as the fitness and a batched ``toolbox.map``.

    python experiments/deap_example.py [--generations 200] [--seed 0]

It prints the final cost beside Levenberg-Marquardt's floor on the same problem (the 30-pose
PUMA 560 problem of ``zrp-ga problem=multipose``).
"""

from __future__ import annotations

import argparse
import random

import numpy as np
from deap import algorithms, base, tools

from zrp_ga import config, deap_tools
from zrp_ga.app import prepare


def within(low: list[float], up: list[float]):
    """A DEAP decorator that clips an operator's children into the gene ranges."""

    def decorator(op):
        def wrapped(*args, **kwargs):
            children = op(*args, **kwargs)
            for child in children:
                child[:] = np.clip(child, low, up).tolist()
            return children

        return wrapped

    return decorator


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    random.seed(args.seed)  # DEAP's operators draw from `random`
    rng = np.random.default_rng(args.seed)
    cfg = config.load(["problem=multipose", f"seed={args.seed}"])
    problem = prepare(cfg, None).task.problem  # the same problem instance zrp-ga builds
    low, up = problem.lower.tolist(), problem.upper.tolist()

    toolbox = base.Toolbox()
    toolbox.register("individual", lambda: deap_tools.Individual(rng.uniform(problem.lower, problem.upper)))
    toolbox.register("population", tools.initRepeat, list, toolbox.individual)
    toolbox.register("evaluate", deap_tools.evaluator(problem))
    toolbox.register("map", deap_tools.batched_map(problem))  # one vectorised call per generation
    toolbox.register("mate", tools.cxBlend, alpha=0.5)
    toolbox.register("mutate", tools.mutPolynomialBounded, eta=100.0, low=low, up=up, indpb=0.2)
    toolbox.register("select", tools.selTournament, tournsize=3)
    toolbox.decorate("mate", within(low, up))  # cxBlend leaves the ranges: DEAP's checkBounds recipe
    toolbox.decorate("mutate", within(low, up))

    stats = tools.Statistics(lambda ind: ind.fitness.values[0])
    stats.register("best", np.min)
    hof = tools.HallOfFame(1)
    pop = toolbox.population(n=50)
    pop, log = algorithms.eaMuPlusLambda(pop, toolbox, mu=50, lambda_=50, cxpb=0.8, mutpb=0.2, ngen=args.generations,
                                         stats=stats, halloffame=hof, verbose=False)  # fmt: skip

    from zrp_ga.algorithms.lm import LM

    floor = LM().run(problem, rng).cost
    best = hof[0].fitness.values[0]
    print(f"DEAP eaMuPlusLambda, {args.generations} generations: best cost {best:.6g} = {best / floor:.4f} x the LM floor {floor:.6g}")
    return {"best": best, "floor": floor, "log": log}


if __name__ == "__main__":
    main()
