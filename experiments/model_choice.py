"""Model choice on the UR10 data (issue 30): each candidate's cross-validated and validation
RMS side by side, the choice and why, in both protocols:

- **B -> C**: calibrate on series B, validate on series C (C lies beyond B's joint ranges: the
  folds hold out the extreme ranges of the joints C goes beyond, with the coverage warning);
- **B -> C, positions only** (``problem.use_orientation=false``): the fit issue 30's figures
  come from (its geometric 1.328 mm); the default fits the files' orientations too;
- **C 70/30**: series C split 70/30 at random (``problem.validation_fraction=0.3``, seed 0:
  the targets lie inside the calibration's ranges, random 5-fold cross-validation).

The candidates are fixed here, before any number is computed: geometric, geometric + GP residual,
joint compliance under gravity of shoulder and elbow (``problem.terms={compliance: [2, 3]}``,
generic mass model) with and without the residual, and, in B -> C, joint-angle harmonics of
every joint (orders 1 and 3), which extrapolate with full amplitude. The choice
(:func:`zrp_ga.problems.choice.select`) sees the calibration data and the validation poses'
joint values only; each candidate is then fitted on the whole calibration set and validated once,
for the table. Writes results/model_choice.md and results/model_choice_PROTOCOL.json. Run:

    nice python experiments/model_choice.py [--protocol b_to_c|positions_b_to_c|c_70_30] [--only CANDIDATE ...]

(``--only``: a part of a protocol's table, for running parts at once; the page joins the parts
and chooses over the whole table.)

Data: Landgraf, Ernst, Schleth, Fabritius and Huber, "A Hybrid Neural Network Approach for
Increasing the Absolute Accuracy of Industrial Robots", IEEE CASE 2021, pp. 468-474
(christianlandgraf/ipa-robot-accuracy, MIT licence; shipped in zrp_ga/data/ur10_ipa).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from zrp_ga import config
from zrp_ga.core import targets
from zrp_ga.problems import choice, measured

RESULTS = Path(__file__).parent / "results"
COMPLIANCE = {"compliance": [2, 3]}
ALL = [1, 2, 3, 4, 5, 6]
CANDIDATES = [choice.Candidate("geometric"), choice.Candidate("geometric+gp", None, True),
              choice.Candidate("compliance 2,3", COMPLIANCE), choice.Candidate("compliance 2,3+gp", COMPLIANCE, True)]  # fmt: skip
HARMONICS = [choice.Candidate("harmonics order 1, all joints", {"harmonics": {"order": 1, "joints": ALL}}),
             choice.Candidate("harmonics order 3, all joints", {"harmonics": {"order": 3, "joints": ALL}})]  # fmt: skip
PROTOCOLS = {
    "b_to_c": (["problem=ur10_ipa"], CANDIDATES + HARMONICS),
    "positions_b_to_c": (["problem=ur10_ipa", "problem.use_orientation=false"], CANDIDATES + HARMONICS),
    "c_70_30": (["problem=ur10_ipa", "problem.calibration_file=pkg:ur10_ipa/series_c_random_poses.csv",
                 "problem.validation_file=null", "problem.validation_fraction=0.3"], CANDIDATES),
}  # fmt: skip
TITLES = {"b_to_c": "UR10 series B -> series C (positions and orientations fitted)",
          "positions_b_to_c": "UR10 series B -> series C, positions only (the issue's protocol)",
          "c_70_30": "UR10 series C split 70/30 (seed 0)"}


def study(name: str, only: list[str] | None = None) -> dict:
    """The choice and every candidate's validation figure in protocol ``name`` (``only``: these
    candidates, a part of the table that :func:`merged` joins with the others')."""
    over, cands = PROTOCOLS[name]
    cands = [c for c in cands if only is None or c.name in only]
    cfg = config.load([*over, "progress=false"])
    robot = targets.create(cfg.robot, "robot")
    c = cfg.problem
    calib, val = measured.read_sets(robot, int(cfg.seed), c)
    calib = calib.with_tool_names(calib.tool_names or ("tool",))
    t0 = time.time()
    fit = measured.refit(robot, c)
    scheme = choice.folds(calib.q, val.q)
    rows = choice.cross_validate(fit, calib, cands, scheme, progress=lambda line: print(f"  [{name}] {line}", flush=True))
    cv_s = time.time() - t0
    val_rms = {}
    shared: dict = {}
    for cand in cands:  # after the choice: each candidate on the whole calibration set, validated once
        key = repr(cand.terms)
        if key not in shared:
            shared[key] = fit(calib, cand.terms)
        f = choice.fit_candidate(fit, calib, cand, shared[key])
        val_rms[cand.name] = float(np.sqrt(np.mean(np.sum((val.p - f.predict(val)) ** 2, axis=1)))) * 1e3
        print(f"  [{name}] validation {cand.name}: {val_rms[cand.name]:.4g} mm", flush=True)
    return {"protocol": name, "overrides": over, "calibration_poses": calib.M, "validation_poses": val.M,
            "folds": scheme.to_dict(), "cross_validation": rows, "validation_rms_mm": val_rms, "cv_wall_s": cv_s,
            "wall_s": time.time() - t0, "date": time.strftime("%Y-%m-%d", time.gmtime()),
            "load": [round(x, 1) for x in os.getloadavg()]}  # fmt: skip


def merged(name: str) -> dict | None:
    """The parts of protocol ``name`` joined, in the candidates' fixed order, and the choice
    over the whole table (:func:`zrp_ga.problems.choice.choose`, the rule ``problem.model=auto``
    uses); None when a candidate has no figures yet."""
    parts = [json.loads(f.read_text()) for f in sorted(RESULTS.glob(f"model_choice_{name}*.json"))]
    if not parts:
        return None
    rows = {row["name"]: row for part in parts for row in part["cross_validation"]}
    val = {k: v for part in parts for k, v in part["validation_rms_mm"].items()}
    order = [c.name for c in PROTOCOLS[name][1]]
    missing = [n for n in order if n not in rows]
    table = [rows[n] for n in order if n in rows]
    chosen, why = choice.choose(table)
    return {**parts[0], "cross_validation": table, "validation_rms_mm": val, "chosen": table[chosen]["name"], "why": why,
            "missing": missing, "load_range": _load_range(parts), "date": max(p.get("date", "2026-12-02") for p in parts),
            "cv_wall_s": sum(p["cv_wall_s"] for p in parts), "wall_s": sum(p["wall_s"] for p in parts)}  # fmt: skip


def _load_range(parts: list[dict]) -> str:
    """The load averages at the parts' ends (1-minute figures), as a range."""
    loads = [p["load"][0] for p in parts if "load" in p]
    if len(loads) < len(parts):
        loads += [15, 24]  # the parts run 2026-12-02 recorded no load; the page said 15-24 then
    return f"{min(loads):.0f}-{max(loads):.0f}" if max(loads) - min(loads) >= 1 else f"{loads[0]:.0f}"


def table(r: dict) -> list[str]:
    geo = r["validation_rms_mm"].get("geometric", float("nan"))
    chosen = r["chosen"]
    lines = [f"## {TITLES[r['protocol']]}", "",
             f"Overrides: `{' '.join(r['overrides'])}`; {r['calibration_poses']} calibration poses, {r['validation_poses']} "
             f"validation poses. Fold scheme: **{r['folds']['scheme']}** "
             f"({', '.join(f['name'] + ': ' + str(f['held_out']) for f in r['folds']['folds'])}).", ""]  # fmt: skip
    if "warning" in r["folds"]:
        lines += [f"> Warning: {r['folds']['warning']}", ""]
    lines += ["| candidate | CV RMS, mm | CV per fold, mm | fit RMS, mm | validation RMS, mm | chosen |", "|---|---:|---|---:|---:|---|"]  # fmt: skip
    for row in r["cross_validation"]:
        n = row["name"]
        folds = " / ".join(f"{v:.3f}" for v in row["fold_rms_mm"])
        lines.append(f"| {n} | {row['cv_rms_mm']:.3f} | {folds} | {row['fit_rms_mm']:.3f} | {r['validation_rms_mm'][n]:.3f} | "
                     f"{'**yes**' if n == chosen else ''} |")  # fmt: skip
    if r.get("missing"):
        lines += ["", f"Not computed (yet): {', '.join(r['missing'])}; the choice is over the rows above."]
    v = r["validation_rms_mm"][chosen]
    lines += ["", f"Chosen: **{chosen}**, {r['why']}. Its validation RMS: {v:.3f} mm against the geometric model's {geo:.3f} mm "
              f"({'not worse' if v <= geo else 'WORSE' if v > geo else 'geometric not computed'}). Cross-validation {r['cv_wall_s']:.0f} s, all {r['wall_s']:.0f} s "
              f"(summed over the parts; run {r.get('date', '2026-12-02')}, 2 cores shared with other sessions, load average "
              f"{r.get('load_range', '15-24')}).", ""]  # fmt: skip
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", choices=sorted(PROTOCOLS), action="append")
    parser.add_argument("--only", action="append", help="these candidates only (a part of the table; repeat)")
    parser.add_argument("--page", action="store_true", help="only write the page from the results' JSON files")
    args = parser.parse_args()
    RESULTS.mkdir(exist_ok=True)
    for name in [] if args.page else args.protocol or list(PROTOCOLS):  # one file per protocol (and part): they may run at once
        with threadpool_limits(limits=1, user_api="blas"):  # one BLAS thread: as the runs (zrp_ga.run.execute)
            result = study(name, args.only)
        part = "" if args.only is None else "_" + "_".join(n.split()[0] + "".join(ch for ch in n if ch.isdigit()) for n in args.only)  # fmt: skip
        (RESULTS / f"model_choice_{name}{part}.json").write_text(json.dumps(result, indent=1))
    done = {n: r for n in PROTOCOLS if (r := merged(n)) is not None}
    lines = ["# Model choice on the UR10 data (issue 30)", "",
             "Command: `nice python experiments/model_choice.py`. Position errors in mm. The candidates are fixed in the "
             "script before any figure; the choice sees the calibration data (cross-validation, the geometry refitted "
             "by Levenberg-Marquardt in every fold) and the validation poses' joint values (the fold scheme) only. "
             "The validation column is computed after the choice, each candidate fitted on the whole calibration set.", ""]  # fmt: skip
    for name in PROTOCOLS:
        if name in done:
            lines += table(done[name])
    (RESULTS / "model_choice.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
