"""The UR10 laser-tracker data: calibrate on series B, validate on series C, GA and LM.

Runs the generic measured problem on the shipped files (what ``problem=ur10_ipa`` names),

    zrp-ga problem=measured robot=ur10 problem.format=ur10_ipa
        problem.calibration_file=pkg:ur10_ipa/series_b_joint_configurations.csv
        problem.validation_file=pkg:ur10_ipa/series_c_random_poses.csv [algorithm=lm]

(the GA with the pseudo-inverse step, and Levenberg-Marquardt) through ``zrp_ga.run.execute.run``, with
positions, weighted positions and orientations, and writes results/ur10_ipa.md and the GA's
per-pose error plot. Run:

    python experiments/ur10_ipa.py [--out DIR]

Data: Landgraf, Ernst, Schleth, Fabritius and Huber, "A Hybrid Neural Network Approach for
Increasing the Absolute Accuracy of Industrial Robots", IEEE CASE 2021, pp. 468-474
(christianlandgraf/ipa-robot-accuracy, MIT licence; shipped in zrp_ga/data/ur10_ipa).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from zrp_ga import config, report
from zrp_ga.run import execute

RESULTS = Path(__file__).parent / "results"
VARIANTS = {"positions": [], "positions, weighted by their standard deviations": ["problem.use_weights=true"],
            "positions and orientations": ["problem.use_orientation=true"]}  # fmt: skip
MEASURED = ["problem=measured", "robot=ur10", "problem.format=ur10_ipa",
            "problem.calibration_file=pkg:ur10_ipa/series_b_joint_configurations.csv",
            "problem.validation_file=pkg:ur10_ipa/series_c_random_poses.csv"]  # fmt: skip
RUNS = {f"{method}, {data}": [*MEASURED, *alg, *over]
        for data, over in VARIANTS.items()
        for method, alg in (("GA + pseudo-inverse step", []), ("Levenberg-Marquardt", ["algorithm=lm"]))}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_ur10_"))
    lines = ["# UR10, series B -> series C", "",
             f"Command: `python experiments/ur10_ipa.py`. Position errors in mm. Every run is `zrp-ga {' '.join(MEASURED)}` "
             "(the same as `zrp-ga problem=ur10_ipa`) with the overrides shown.", "",
             "| method | overrides | set | poses | nominal, registered: mean / RMS / max | calibrated: mean / RMS / max | wall time, s |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    summaries = {}
    for name, over in RUNS.items():
        run_dir = root / str(len(summaries))
        execute.run(config.load(over + ["progress=false"]), run_dir)
        s = summaries[name] = json.loads((run_dir / "summary.json").read_text())
        for part in ("calibration", "validation"):
            e = s["position_error_mm"][part]
            fmt = lambda d: f"{d['mean']:.3f} / {d['rms']:.3f} / {d['max']:.3f}"
            shown = " ".join(over[len(MEASURED):]) or "(none)"
            lines.append(f"| {name} | `{shown}` | {part} ({Path(s['problem']['files'][part]).name}) | "
                         f"{e['nominal']['poses']} | {fmt(e['nominal'])} | {fmt(e['calibrated'])} | {s['wall_s']:.2f} |")  # fmt: skip
    ratios = []
    for data in VARIANTS:
        ga, lm = (summaries[f"{m}, {data}"]["position_error_mm"]["validation"]["calibrated"]["rms"]
                  for m in ("GA + pseudo-inverse step", "Levenberg-Marquardt"))  # fmt: skip
        ratios.append(f"{data}: {ga / lm:.4f}")
    reg = summaries["Levenberg-Marquardt, positions"]["registration"]
    lines += ["", f"Registration of the nominal UR10 to series B: {reg['rms_mm']:.3f} mm RMS, {reg['max_mm']:.3f} mm max; "
              f"tool offset {', '.join(f'{v * 1e3:.2f}' for v in reg['tool_m'])} mm in the flange frame.", "",
              "Series C RMS error, GA / LM: " + "; ".join(ratios) + ".", ""]  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "ur10_ipa.md").write_text("\n".join(lines))
    report.pose_error_figure(root / "0").savefig(RESULTS / "ur10_ipa_pose_errors.png", dpi=150)  # GA, positions
    print("\n".join(lines))
    print(f"runs in {root}")


if __name__ == "__main__":
    main()
