"""``zrp-ga-compensate``: a calibration turned into a corrected robot program
(:func:`zrp_ga.compensation.compensate.compensate`). Bad input is one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by spaces or commas, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="zrp-ga-compensate",
        description="Corrected joint values and Cartesian targets that bring the calibrated arm to a program's targets. "
        "Targets are in the robot's base frame (the nominal model's, the controller's).",
    )  # fmt: skip
    p.add_argument("calibration", help="a zrp-ga run directory, or a calibrated robot file (then give --nominal)")
    p.add_argument("program", help="CSV: x,y,z[,rx,ry,rz][,q1..qn as seeds] (Cartesian) or q1..qn / joint names (joint values)")
    p.add_argument("-o", "--out", default=None, help="output directory (default: PROGRAM's name + _compensated, here)")
    p.add_argument("--nominal", default=None, help="the nominal arm: a preset name or a robot file (default: the run's)")
    p.add_argument("--kind", choices=("auto", "joints", "cartesian"), default="auto",
                   help="read the program as joint values or Cartesian targets (auto: Cartesian if it has x, y, z)")
    p.add_argument("--length-unit", choices=("m", "mm"), default="m", help="positions and prismatic joints (default m)")
    p.add_argument("--angle-unit", choices=("rad", "deg"), default="rad", help="revolute joints and orientations (default rad)")
    p.add_argument("--orientation-convention", default=None, metavar="SEQ",
                   help="of rx, ry, rz: an Euler sequence (XYZ intrinsic, xyz extrinsic, ...) or rotvec; output: the same (default rotvec)")
    p.add_argument("--seed-q", type=_floats, default=None, metavar="Q",
                   help="first seed configuration of a Cartesian program without joint columns (program units)")
    p.add_argument("--tool", default=None, metavar="X,Y,Z",
                   help="targets of a tool point: its offset in the hand frame (program length unit), or 'calibration': "
                   "the point the run measured (default: the hand's end point)")
    p.add_argument("--position-only", action="store_true", help="match positions only (default: full poses for arms of six joints or more)")
    p.add_argument("--frame", choices=("base", "instrument"), default="base",
                   help="the frame of Cartesian targets: base (default) or the run's instrument frame (measured runs)")
    p.add_argument("--keep-unreachable", action="store_true", help="write unreachable targets as empty rows instead of stopping")
    p.add_argument("--sep", default=",", help="column separator (default ,)")
    p.add_argument("--decimal", default=".", help="decimal mark (default .)")
    args = p.parse_args(argv)
    from zrp_ga.compensation.compensate import compensate
    from zrp_ga.io.measurements import LENGTH

    out = Path(args.out) if args.out else Path(Path(args.program).stem + "_compensated")
    try:
        tool = args.tool
        if tool is not None and tool != "calibration":
            tool = np.asarray(_floats(tool)) * LENGTH[args.length_unit]
            if tool.shape != (3,):
                raise ValueError(f"--tool: expected 3 numbers or 'calibration', got {args.tool!r}")
        c = compensate(args.calibration, args.program, nominal=args.nominal, kind=args.kind, q_seed=args.seed_q, tool=tool,
                       position_only=args.position_only, frame=args.frame, length_unit=args.length_unit,
                       angle_unit=args.angle_unit, orientation_convention=args.orientation_convention, sep=args.sep,
                       decimal=args.decimal, unreachable="keep" if args.keep_unreachable else "error",
                       out=out)  # fmt: skip
    except (ValueError, argparse.ArgumentTypeError) as exc:
        print(f"zrp-ga-compensate: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    s = c.summary()
    print(f"compensated {s['reached']} of {s['rows']} {s['targets']} of {args.program} with {s['calibration']} -> "
          f"{out / 'joints.csv'}, {out / 'targets.csv'}, {out / 'compensation.json'}")  # fmt: skip
    st = s["stats"]
    if st["residual_mm"]:
        angle = f", {st['residual_deg']['max']:.3g} deg" if "residual_deg" in st else ""
        print(f"predicted residual: max {st['residual_mm']['max']:.3g} mm{angle}; uncompensated (as the calibrated model "
              f"predicts): RMS {st['uncompensated_mm']['rms']:.4g} mm, max {st['uncompensated_mm']['max']:.4g} mm")  # fmt: skip
        joints = f"joints up to {st['dq_deg']['max']:.4g} deg" + (f" and {st['dq_mm']['max']:.4g} mm" if "dq_mm" in st else "")
        print(f"correction: {joints}; Cartesian up to {st['dx_mm']['max']:.4g} mm and {st['dr_deg']['max']:.4g} deg")
    for line in s["unreachable"][:20]:
        print(f"unreachable: {line}")
    if len(s["unreachable"]) > 20:
        print(f"... {len(s['unreachable']) - 20} more unreachable targets (compensation.json)")
    for note in s["notes"]:
        print(f"note: {note}")
    return 0


def cli() -> None:
    sys.exit(main())


if __name__ == "__main__":
    cli()
