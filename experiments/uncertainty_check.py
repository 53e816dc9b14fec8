"""Predicted against measured validation error: does a calibration know how good it is?

Each run's ``summary.json`` predicts the RMS position error on its validation poses from the
covariance of the identified combinations, the prior of those left at nominal and the noise
(docs/model.md, section 3.3), beside the RMS measured there. Cases:

- ``tracker``: the suite's simulated tracker problem (PUMA 560, 30 poses, positions and
  orientations, joints 0.1 mrad, positions 50 um, orientations 0.1 mrad; 100 validation poses
  from the same distribution), over 20 instance seeds, LM;
- ``tracker, positions only``: the same, positions only;
- the UR10 laser-tracker data (series B to calibrate, series C to validate), with and without
  its orientations, LM;
- the measured example of experiments/own_arm (simulated tracker files of an IRB 140 with three
  reflectors): the same tracker position, the tracker moved, a fourth reflector; LM.

    python experiments/uncertainty_check.py [--seeds 20] [--out experiments/results/uncertainty.md]
"""

from __future__ import annotations

import argparse
import logging
import time
import warnings
from pathlib import Path

import numpy as np

import zrp_ga

HERE = Path(__file__).parent
OUT = HERE / "results" / "uncertainty.md"
TRACKER = {"n_poses": 30, "cost": "nonlinear", "joint_noise": 0.0001, "position_noise": 5e-5, "orientation_noise": 0.0001,
           "search_scale": 2.0}  # fmt: skip
OWN = HERE / "own_arm"
MEASURED = {
    "UR10 series B -> C, positions and orientations": ("ur10", "pkg:ur10_ipa/series_b_joint_configurations.csv",
                                                        {"format": "ur10_ipa", "validation_file": "pkg:ur10_ipa/series_c_random_poses.csv"}),
    "UR10 series B -> C, positions only": ("ur10", "pkg:ur10_ipa/series_b_joint_configurations.csv",
                                           {"format": "ur10_ipa", "validation_file": "pkg:ur10_ipa/series_c_random_poses.csv",
                                            "use_orientation": False}),
    "own_arm, same tracker position": (OWN / "irb140.yaml", OWN / "calibration.csv", {"validation_file": OWN / "validation.csv"}),
    "own_arm, tracker moved (rigid)": (OWN / "irb140.yaml", OWN / "calibration.csv",
                                       {"validation_file": OWN / "validation_moved.csv", "validation_registration": "rigid"}),
    "own_arm, fourth reflector D": (OWN / "irb140.yaml", OWN / "calibration.csv",
                                    {"validation_file": OWN / "validation_tool_d.csv", "known_tools": "{D:[0,0,80]}"}),
}  # fmt: skip


def row(s: dict) -> tuple:
    u, cov = s["uncertainty"], s["coverage"].get("validation", {})
    v = u["validation_rms_mm"]
    return v["predicted"], v["measured"], v["measured_over_predicted"], cov.get("share_outside", float("nan")), u["noise_mm"]


def simulated(seeds: int, position_only: bool) -> list[tuple]:
    rows = []
    for seed in range(seeds):
        cal = zrp_ga.calibrate("puma560", algorithm="lm", problem={**TRACKER, "position_only": position_only, "seed": 1000 + seed})
        rows.append(row(cal.summary))
    return rows


def measured(robot, calibration, settings: dict) -> dict:
    """``zrp-ga problem=measured`` as the command line runs it (the files by name)."""
    from zrp_ga import config
    from zrp_ga.run import build, execute

    over = ["problem=measured", "algorithm=lm", f"problem.calibration_file={calibration}"]
    over.append(f"robot={robot}" if isinstance(robot, str) else "robot=file")
    if not isinstance(robot, str):
        over.append(f"robot.file={robot}")
    over += [f"problem.{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in settings.items()]
    p = build.prepare(config.load(over), None)
    return execute.execute(p, False)[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    lines = []
    for label, position_only in (("simulated tracker (PUMA 560, 30 poses), positions and orientations", False),
                                 ("simulated tracker (PUMA 560, 30 poses), positions only", True)):  # fmt: skip
        t0 = time.perf_counter()
        rows = np.array(simulated(args.seeds, position_only))
        r = rows[:, 2]
        lines.append(f"| {label} | {args.seeds} seeds | {np.mean(rows[:, 0]):.4f} | {np.mean(rows[:, 1]):.4f} | "
                     f"{np.mean(r):.3f} (median {np.median(r):.3f}, {r.min():.3f} - {r.max():.3f}) | "
                     f"{np.mean(rows[:, 3]):.0%} | {np.mean(rows[:, 4]):.4f} | {time.perf_counter() - t0:.0f} |")  # fmt: skip
        print(lines[-1], flush=True)
    for label, (robot, calibration, settings) in MEASURED.items():
        t0 = time.perf_counter()
        p, m, ratio, outside, noise = row(measured(robot, calibration, settings))
        lines.append(f"| {label} | 1 | {p:.4f} | {m:.4f} | {ratio:.3f} | {outside:.0%} | {noise:.4f} | {time.perf_counter() - t0:.0f} |")
        print(lines[-1], flush=True)
    head = ["# Predicted against measured validation RMS", "",
            f"Command: `python experiments/uncertainty_check.py --seeds {args.seeds}` (module docstring). Every run is LM "
            "with the defaults (the identified genome). Predicted: `summary.json`'s `uncertainty.validation_rms_mm.predicted` "
            "(the identified combinations' covariance, the prior of those left at nominal, the noise); measured: the "
            "validation RMS. Outside: the share of validation poses outside the calibration poses' joint-space region "
            "(`coverage`). Wall times on a machine running other jobs.", "",
            "| case | runs | predicted RMS, mm (mean) | measured RMS, mm (mean) | measured / predicted | validation outside | "
            "noise, mm | wall s |", "|---|---:|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(head + lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
