"""The worked example: an ABB IRB 140 (not a preset) calibrated from simulated tracker files.

Runs the obvious command for the arm given as a DH file (``irb140.yaml``) and as a URDF
(``irb140.urdf``), with the GA (and its pseudo-inverse step) and with Levenberg-Marquardt,

    zrp-ga problem=measured robot=file robot.file=experiments/own_arm/irb140.yaml \\
        problem.calibration_file=experiments/own_arm/calibration.csv \\
        problem.validation_file=experiments/own_arm/validation.csv [algorithm=lm]

then the two other validations (the tracker moved: ``validation_moved.csv`` with
``problem.validation_registration=rigid``; a fourth reflector at a known place:
``validation_tool_d.csv`` with ``problem.known_tools={D:[0,0,80]}``), and checks each run's
calibrated URDF read back (for the URDF arm: ``irb140.urdf`` with only its joint origins
changed; the robot alone, from its own base frame): the base transform of
``calibrated_robot_frames.yaml``, its forward kinematics from the root link to the hand and the
tool transforms of that file must predict the validation points as the run's
``pose_errors.csv`` says. Writes results/own_arm.md. Make the
data first (``python experiments/own_arm/make_data.py``). Run:

    python experiments/own_arm/run.py [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from zrp_ga import config
from zrp_ga.io import robot_files
from zrp_ga.model import kinematics
from zrp_ga.run import execute

HERE = Path(__file__).parent
RESULTS = HERE.parent / "results"
ROOT = HERE.parent.parent


def _rel(path: Path) -> str:
    """The path as the overrides give it (absolute: the script runs from any folder)."""
    return str(path.resolve())


ARM = {"DH file": f"robot.file={_rel(HERE / 'irb140.yaml')}", "URDF": f"robot.file={_rel(HERE / 'irb140.urdf')}"}
VALIDATIONS = {
    "same tracker position": [f"problem.validation_file={_rel(HERE / 'validation.csv')}"],
    "tracker moved": [f"problem.validation_file={_rel(HERE / 'validation_moved.csv')}", "problem.validation_registration=rigid"],
    "known other tool point D": [f"problem.validation_file={_rel(HERE / 'validation_tool_d.csv')}", "problem.known_tools={D:[0,0,80]}"],
}
METHODS = {"GA + pseudo-inverse step": [], "Levenberg-Marquardt": ["algorithm=lm"]}


def runs() -> dict[tuple[str, str, str], list[str]]:
    """(arm, validation, method) -> the command's overrides: both arm files with the first
    validation, the DH file with the other two."""
    out = {}
    for (arm, file), (val, vover), (method, mover) in (
        (a, v, m) for a in ARM.items() for v in VALIDATIONS.items() for m in METHODS.items()
    ):
        if arm == "URDF" and val != "same tracker position":
            continue
        out[arm, val, method] = ["problem=measured", "robot=file", file,
                                 f"problem.calibration_file={_rel(HERE / 'calibration.csv')}", *vover, *mover]  # fmt: skip
    return out


def urdf_check(run_dir: Path, summary: dict) -> float:
    """Largest difference (mm) between the validation errors the run reports (``pose_errors.csv``)
    and those of its calibrated URDF read back (the frames file's base, FK from the URDF's root
    link to its hand, then each row's tool transform from the frames file), for validations in
    the calibration's frame."""
    urdf = robot_files.read_robot(run_dir / "calibrated_robot.urdf")  # the robot's own root and hand
    frames = yaml.safe_load((run_dir / "calibrated_robot_frames.yaml").read_text())
    base = np.array(frames["base"]["matrix"])
    tools = {k: np.array(v["matrix"]) for k, v in frames.get("tools", {"tool": frames["tool"]}).items()}
    val = pd.read_csv(ROOT / summary["problem"]["files"]["validation"])
    reported = pd.read_csv(run_dir / "pose_errors.csv")
    reported = reported[reported["set"] == "validation"].reset_index(drop=True)
    worst = 0.0
    for k, row in val.iterrows():
        R, p = kinematics.forward(urdf, np.radians(row[[f"q{i}" for i in range(1, 7)]].to_numpy(dtype=float)))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p
        T = base @ T @ tools[row.get("tool", "tool") if len(tools) > 1 else next(iter(tools))]
        err = np.linalg.norm(T[:3, 3] * 1e3 - row[["x", "y", "z"]].to_numpy(dtype=float))
        worst = max(worst, abs(err - reported["calibrated_mm"][k]))
    return worst


def urdf_diff(original: Path, calibrated: Path) -> str:
    """What differs between the user's URDF and the run's calibrated one, element by element
    (lxml): the changed attributes by joint, then the elements the run added at the end."""
    from lxml import etree

    a, b = (etree.parse(str(path)).getroot() for path in (original, calibrated))
    changed: dict[str, list[str]] = {}
    same = 0
    for x, y in zip(a.iter(), b.iter()):
        same += x.attrib == y.attrib
        if x.tag != y.tag or (x.text or "").strip() != (y.text or "").strip():
            return f"{calibrated.name}: element <{y.tag}> on line {y.sourceline} differs from the input's"
        for key in sorted(set(x.attrib) | set(y.attrib)):
            if x.get(key) != y.get(key):
                changed.setdefault(x.getparent().get("name"), []).append(f"{x.tag} {key}")
    added = [f"{e.tag} {e.get('name')}" for e in list(b)[len(a):] if isinstance(e.tag, str)]
    return ("changed: " + "; ".join(f"{joint}: {', '.join(attrs)}" for joint, attrs in changed.items())
            + f"; added at the end: {', '.join(added) or 'nothing'}; the other {same} elements (links, limits, comments, ...) as they were")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_own_arm_"))
    lines = ["# ABB IRB 140 (not a preset), simulated tracker data with three reflectors", "",
             "Command: `python experiments/own_arm/run.py` (data: `python experiments/own_arm/make_data.py`). "
             "Position errors in mm; every run is `zrp-ga` with the overrides shown.", "",
             "| arm | validation | method | overrides | set | points | nominal, registered: mean / RMS / max | calibrated: mean / RMS / max | optimiser wall time, s | URDF check, mm |",
             "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    fmt = lambda d: f"{d['mean']:.3f} / {d['rms']:.3f} / {d['max']:.3f}"
    summaries = {}
    for key, over in runs().items():
        run_dir = root / str(len(summaries))
        execute.run(config.load(over + ["progress=false"]), run_dir)
        s = summaries[key] = json.loads((run_dir / "summary.json").read_text())
        check = f"{urdf_check(run_dir, s):.1e}" if key[1] == "same tracker position" else "n/a"
        if key[0] == "URDF" and "diff" not in summaries:
            summaries["diff"] = urdf_diff(HERE / "irb140.urdf", run_dir / "calibrated_robot.urdf")
        shown = " ".join(o for o in over if not o.startswith(("problem=measured", "robot=file", "problem.calibration_file")))
        shown = shown.replace(str(ROOT.resolve()) + "/", "")
        for part in ("calibration", "validation"):
            e = s["position_error_mm"][part]
            lines.append(f"| {key[0]} | {key[1]} | {key[2]} | `{shown}` | {part} | {e['nominal']['poses']} | "
                         f"{fmt(e['nominal'])} | {fmt(e['calibrated'])} | {s['wall_s']:.2f} | {check if part == 'validation' else ''} |")  # fmt: skip
    diff = summaries.pop("diff")
    lines += ["", "Validation RMS, GA / LM:"]
    for arm in ARM:
        for val in VALIDATIONS:
            if (arm, val, "Levenberg-Marquardt") in summaries:
                ga, lm = (summaries[arm, val, m]["position_error_mm"]["validation"]["calibrated"]["rms"] for m in METHODS)
                lines.append(f"- {arm}, {val}: {ga / lm:.4f}")
    first = summaries["DH file", "same tracker position", "Levenberg-Marquardt"]
    reg = first["registration"]
    lines += ["", f"Registration of the nominal IRB 140 to the calibration file: {reg['rms_mm']:.3f} mm RMS, {reg['max_mm']:.3f} mm max; "
              "reflector offsets (mm, flange frame): " + "; ".join(f"{k} {', '.join(f'{v * 1e3:.2f}' for v in xyz)}"
                                                                  for k, xyz in reg["tools_m"].items()) + ".",
              f"Units found in the files: {first['problem']['units']}. Calibrated DH table's mismatch to the calibrated model: "
              f"{first['calibrated_robot']['dh_mismatch']['position_mm']:.2g} mm, {first['calibrated_robot']['dh_mismatch']['orientation_mrad']:.2g} mrad.",
              f"The URDF run's calibrated_robot.urdf against irb140.urdf (GA run; lxml, element by element): {diff}.",
              "Warnings of the runs: " + ("; ".join(sorted({w for s in summaries.values() for w in s["warnings"]})) or "none") + ".", ""]  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "own_arm.md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(f"runs in {root}")


if __name__ == "__main__":
    main()
