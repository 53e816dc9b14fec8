"""The paper's case, the 30-pose problem against LM and CMA-ES, and the GA's own speed.

Every number in experiments/README.md's "Calibration against baselines" section comes from
this script's table (experiments/results/calibration_vs_baselines.md). Run:

    python experiments/calibration_vs_baselines.py [--seeds 5] [--paper-seeds 30] [--out DIR]

Runs go through ``zrp_ga.run.execute.run`` (the run layer ``zrp-ga`` runs through) with the shipped configs, so each is also one command line:
the overrides are printed beside every row.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from zrp_ga import config
from zrp_ga.run import execute

RESULTS = Path(__file__).parent / "results"

PAPER = {
    "GA + pseudo-inverse step (default)": [],
    "GA, no pseudo-inverse step": ["refine=none"],
}
MULTI = ["problem=multipose"]
BUDGET = ["refine=none", "population=budget"]
METHODS = {
    "LM (floor)": ["algorithm=lm"],
    "GA + pseudo-inverse step, 30 generations": ["population.generations=30"],
    "GA, best pure operator set, 50,000 evaluations": BUDGET
    + ["crossover=blend", "mutation=polynomial", "mutation.op.eta=100", "inversion=none", "rotation=none"],
    "GA, default operators without the step, 50,000 evaluations": BUDGET,
    "CMA-ES, 50,000 evaluations": ["algorithm=cmaes", "population=budget"],
}
SPEED = MULTI + ["problem.n_poses=50", "population=p200", "refine=none", "population.generations=200"]


def run(overrides: list[str], out: Path) -> tuple[dict, pd.DataFrame]:
    execute.run(config.load(overrides + ["progress=false"]), out)
    return json.loads((out / "summary.json").read_text()), pd.read_csv(out / "convergence.csv")


def first(conv: pd.DataFrame, column: str, threshold: float) -> float:
    hit = conv.loc[conv["best"] <= threshold, column]
    return float(hit.iloc[0]) if len(hit) else np.nan


def iqr(x, digits: int = 3) -> str:
    x = np.asarray(x, dtype=float)
    if np.all(np.isnan(x)):
        return "not reached"
    q1, q2, q3 = np.nanpercentile(x, [25, 50, 75])
    return f"{q2:.{digits}g} [{q1:.{digits}g}, {q3:.{digits}g}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds of the 30-pose problem")
    parser.add_argument("--paper-seeds", type=int, default=30, help="seeds of the one-pose case")
    parser.add_argument("--out", type=Path, default=None, help="run directory (default: a temporary one)")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_baselines_"))
    lines = ["# Calibration against baselines", "", "Command: `python experiments/calibration_vs_baselines.py"
             f" --seeds {args.seeds} --paper-seeds {args.paper_seeds}`. Median [interquartile range] over seeds.", ""]  # fmt: skip

    lines += ["## The paper's case: one pose, linear cost, 11 generations, population 20", ""]
    lines += ["| method | overrides | final/initial cost | validation RMS nominal, mm | validation RMS calibrated, mm |",
              "|---|---|---|---|---|"]  # fmt: skip
    for name, over in PAPER.items():
        rows = [run(over + [f"seed={s}"], root / "paper" / name[:12].replace(" ", "_") / str(s))[0]
                for s in range(args.paper_seeds)]  # fmt: skip
        ratio = [r["final_over_initial"] for r in rows]
        before = [r["validation_rms_mm"]["nominal"] for r in rows]
        after = [r["validation_rms_mm"]["calibrated"] for r in rows]
        lines.append(f"| {name} | `{' '.join(over) or '(none)'}` | {iqr(ratio)} | {iqr(before)} | {iqr(after)} |")

    lines += ["", "## 30 poses (PUMA 560, the paper's errors and joint noise), nonlinear cost", ""]
    lines += ["| method | overrides (after `problem=multipose`) | final cost / LM cost | evaluations to 1.05 x LM | "
              "generations to 1.01 x LM | validation RMS, mm | wall time, s |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    results: dict[str, list] = {name: [] for name in METHODS}
    for s in range(args.seeds):
        floor = None
        for name, over in METHODS.items():
            summary, conv = run(MULTI + over + [f"seed={s}"], root / "multi" / str(s) / name[:20].replace(" ", "_"))
            floor = summary["final_cost"] if floor is None else floor
            results[name].append(
                dict(ratio=summary["final_cost"] / floor, e105=first(conv, "nevals", 1.05 * floor),
                     g101=first(conv, "gen", 1.01 * floor), val=summary["validation_rms_mm"]["calibrated"],
                     wall=summary["wall_s"], nominal=summary["validation_rms_mm"]["nominal"])
            )  # fmt: skip
    for name, over in METHODS.items():
        df = pd.DataFrame(results[name])
        g101 = iqr(df.g101) if "pseudo-inverse" in name else "-"  # generations mean little for LM
        e105 = iqr(df.e105) if not name.startswith("LM") else "-"
        lines.append(f"| {name} | `{' '.join(over)}` | {iqr(df.ratio, 4)} | {e105} | {g101} | "
                     f"{iqr(df.val)} | {iqr(df.wall)} |")  # fmt: skip
    nominal = pd.DataFrame(results["LM (floor)"]).nominal
    lines += ["", f"Validation RMS of the nominal robot on the same poses: {iqr(nominal)} mm.", ""]

    lines += ["## Speed inside the GA: population 200, 50 poses", ""]
    summary, conv = run(SPEED + ["seed=0"], root / "speed")
    body = conv.iloc[1:]
    evaluated = body["nevals"].diff().fillna(body["nevals"].iloc[0] - conv["nevals"].iloc[0])
    rate = (evaluated * 50 / body["eval_s"]).median()
    lines += [f"Overrides: `{' '.join(SPEED)}`, {len(body)} generations.", "",
              "| per generation (median) | value |", "|---|---|",
              f"| evaluation of the changed children, ms | {body['eval_s'].median() * 1e3:.3f} |",
              f"| fitness throughput, million pose evaluations/s | {rate / 1e6:.2f} |",
              f"| bookkeeping (selection, cloning, variation, repair, survival, statistics, callbacks), ms | "
              f"{body['bookkeeping_s'].median() * 1e3:.3f} |",
              f"| bookkeeping / evaluation, median over generations | {(body['bookkeeping_s'] / body['eval_s']).median():.2f} |",
              ""]  # fmt: skip

    RESULTS.mkdir(exist_ok=True)
    text = "\n".join(lines) + "\n"
    (RESULTS / "calibration_vs_baselines.md").write_text(text)
    print(text)
    print(f"runs in {root}")


if __name__ == "__main__":
    main()
