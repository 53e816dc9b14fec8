"""``zrp-ga-compensate``: a calibration turned into a corrected robot program
(:func:`zrp_ga.compensation.compensate.compensate`). Bad input is one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

CONVENTIONS = ("an Euler sequence as scipy reads it (ZYX: KUKA's A, B, C; xyz: Fanuc's W, P, R; XYZ intrinsic: Staubli's), "
               "rotvec (Universal Robots' rx, ry, rz) or quaternion (ABB's q1..q4)")  # fmt: skip


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by spaces or commas, got {text!r}") from None


def parser() -> argparse.ArgumentParser:
    """The command line; every default said in a help text is the default."""
    p = argparse.ArgumentParser(
        prog="zrp-ga-compensate",
        description="Corrected joint values and Cartesian targets that bring the calibrated arm to a program's targets, "
        "written in the program's units and orientation convention.",
    )  # fmt: skip
    p.add_argument("calibration", help="a zrp-ga run directory, or a calibrated robot file (then give --nominal)")
    p.add_argument("program", help="CSV: x,y,z[,orientation][,q1..qn as seeds] (Cartesian) or q1..qn / joint names (joint "
                   "values); a column may name its unit: x_mm, q1_deg")  # fmt: skip
    p.add_argument("-o", "--out", default=None, help="output directory (default: PROGRAM's name + _compensated, here)")
    p.add_argument("--nominal", default=None, help="the nominal arm: a preset name or a robot file (default: the run's; "
                   "another arm than the run's is refused)")  # fmt: skip
    p.add_argument("--kind", choices=("auto", "joints", "cartesian"), default="auto",
                   help="read the program as joint values or Cartesian targets (default auto: Cartesian if it has x, y, z)")
    p.add_argument("--length-unit", choices=("auto", "m", "mm"), default="auto",
                   help="positions and prismatic joints (default auto: found from the data)")
    p.add_argument("--angle-unit", choices=("auto", "rad", "deg"), default="auto",
                   help="revolute joints and orientations (default auto: found from the data)")
    p.add_argument("--orientation-convention", default=None, metavar="SEQ",
                   help=f"of the orientation columns: {CONVENTIONS}. A, B, C and W, P, R name their convention; rx, ry, rz "
                   "need it stated. Outputs use the same (default: the one the columns name; rotvec for a program without "
                   "orientations)")  # fmt: skip
    p.add_argument("--seed-q", type=_floats, default=None, metavar="Q",
                   help="first seed configuration of a Cartesian program without joint columns (the program's joint units; "
                   "default: the middle of the joint limits)")  # fmt: skip
    p.add_argument("--tool", default=None, metavar="X,Y,Z[,R1,R2,R3]",
                   help="targets of a tool: its offset (and orientation) in the flange frame, in the program's units and "
                   "convention, or 'calibration': the point the run measured (default: the flange)")  # fmt: skip
    p.add_argument("--probe-in-flange", default=None, metavar="X,Y,Z[,R1,R2,R3]",
                   help="tool setup: the run's measured probe in the flange frame (program units), which fixes the flange "
                   "(default: the calibration's split, whose size is said)")  # fmt: skip
    p.add_argument("--position-only", action="store_true", help="match positions only (default: full poses for arms of six joints or more)")
    p.add_argument("--frame", choices=("base", "instrument", "work-object"), default=None,
                   help="the frame of Cartesian targets (default: work-object with --work-object, else base)")
    p.add_argument("--work-object", default=None, metavar="FILE|O;X;Y",
                   help="a work object: a CSV of three points O, X, Y (or of one pose) with columns x, y, z, or nine numbers "
                   "(program units)")  # fmt: skip
    p.add_argument("--work-object-frame", choices=("instrument", "base"), default=None,
                   help="where the work object was measured (default: instrument for a measured run, else base)")
    p.add_argument("--base-setup", default="auto", metavar="auto|axes|calibration|FILE",
                   help="the robot's base frame: axes (by convention from the calibrated axes 1 and 2), calibration (as the "
                   "run exported it), a measurement file of circles of joints 1 and 2 (default auto: axes for a measured run, "
                   "else calibration)")  # fmt: skip
    p.add_argument("--keep-unreachable", action="store_true", help="write unreachable targets as empty rows instead of stopping")
    p.add_argument("--sep", default=",", help="column separator (default ,)")
    p.add_argument("--decimal", default=".", help="decimal mark (default .)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    from zrp_ga.compensation.compensate import compensate

    out = Path(args.out) if args.out else Path(Path(args.program).stem + "_compensated")
    say = lambda line: print(f"zrp-ga-compensate: {line}", flush=True)
    try:
        c = compensate(args.calibration, args.program, nominal=args.nominal, kind=args.kind, q_seed=args.seed_q, tool=args.tool,
                       position_only=args.position_only, frame=args.frame, work_object=args.work_object,
                       work_object_frame=args.work_object_frame, base_setup=args.base_setup, probe_in_flange=args.probe_in_flange,
                       length_unit=args.length_unit, angle_unit=args.angle_unit, orientation_convention=args.orientation_convention,
                       sep=args.sep, decimal=args.decimal, unreachable="keep" if args.keep_unreachable else "error", out=out,
                       say=say)  # fmt: skip
    except (ValueError, TypeError, argparse.ArgumentTypeError) as exc:
        print(f"zrp-ga-compensate: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    report(c.summary(), args.program, out)
    return 0


def report(s: dict, program: str, out: Path) -> None:
    """What was done, the residuals and corrections, the unreachable targets and the notes."""
    u = s["units"]
    print(f"compensated {s['reached']} of {s['rows']} {s['targets']} of {program} with {s['calibration']} "
          f"({u['length']}, {u['joint_angle']}, {u['orientation_convention']}) -> "
          f"{out / 'joints.csv'}, {out / 'targets.csv'}, {out / 'compensation.json'}")  # fmt: skip
    st = s["stats"]
    if st["residual_mm"]:
        angle = f", {st['residual_deg']['max']:.3g} deg" if "residual_deg" in st else ""
        print(f"predicted residual: max {st['residual_mm']['max']:.3g} mm{angle}; uncompensated (as the calibrated model "
              f"predicts): RMS {st['uncompensated_mm']['rms']:.4g} mm, max {st['uncompensated_mm']['max']:.4g} mm")  # fmt: skip
        joints = f"joints up to {st['dq_deg']['max']:.4g} deg" + (f" and {st['dq_mm']['max']:.4g} mm" if "dq_mm" in st else "")
        print(f"correction: {joints}; Cartesian up to {st['dx_mm']['max']:.4g} mm and {st['dr_deg']['max']:.4g} deg")
    line = predicted_line(s.get("predicted") or {})
    if line:
        print(line)
    if "work_object_in_base" in s:
        pose = ", ".join(f"{k} {v:.6g}" for k, v in s["work_object_in_base"]["pose"].items())
        print(f"work object in the base frame (enter it in the controller): {pose}")
    for line in s["unreachable"][:20]:
        print(f"unreachable: {line}")
    if len(s["unreachable"]) > 20:
        print(f"... {len(s['unreachable']) - 20} more unreachable targets (compensation.json)")
    for note in s["notes"]:
        print(f"note: {note}")


def predicted_line(p: dict) -> str:
    """One line on how sure the corrected rows are (the calibration's covariance) and how many
    lie outside the calibration poses' region; empty when the calibration carries neither."""
    parts = []
    if p.get("sigma_mm"):
        parts.append(f"predicted 1-sigma error of the calibrated model at the corrected rows: RMS {p['sigma_mm']['rms']:.3g} mm, "
                     f"max {p['sigma_mm']['max']:.3g} mm (sigma_mm)")  # fmt: skip
    if p.get("share_outside") is not None:
        parts.append(f"{p['share_outside']:.0%} of the rows outside the calibration poses' region (outside, beyond_range_deg)")
    return "; ".join(parts)


def cli() -> None:
    sys.exit(main())


if __name__ == "__main__":
    cli()
