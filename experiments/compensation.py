"""Compensation: does a calibrated model make the arm reach its program? (zrp_ga.compensate)

(a) Simulated arms with known true errors, of three kinds: the PUMA 560 (6R), the Stanford arm
(joint 3 prismatic) and a 4-joint SCARA (RRPR, a modified DH table; positions only). Each is
calibrated by Levenberg-Marquardt (``zrp_ga.calibrate``, the simulated multi-pose problem) on
60 measured poses with laser-tracker noise; then a program of 200 targets never used for the
calibration (random joint values within the limits, off the singularities, their nominal poses
the targets) is compensated, and run on the TRUE arm: as written, with the corrected joint
values, and through a controller that knows only the nominal model and is sent the corrected
Cartesian targets (its inverse kinematics from the program's joints).

(b) The real UR10 data (Landgraf et al., IEEE CASE 2021; christianlandgraf/ipa-robot-accuracy,
MIT licence; shipped in zrp_ga/data/ur10_ipa): calibrated by LM on series B as
``zrp-ga problem=ur10_ipa algorithm=lm`` does, then series C's 2,773 joint configurations
compensated as a program (``zrp-ga-compensate RUN series_c_random_poses.csv --sep ';'
--decimal , --tool calibration --position-only``): the correction sizes and the predicted
residuals. There is no robot to run them on.

Run:

    python experiments/compensation.py [--out DIR]

Writes results/compensation.md.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

import zrp_ga
from zrp_ga.compensation import compensate as compensation
from zrp_ga.data import resolve
from zrp_ga.io import presets
from zrp_ga.model import kinematics, so3
from zrp_ga.model.robot import ZRPRobot

RESULTS = Path(__file__).parent / "results"
D = np.pi / 180
N_PROGRAM = 200
CONDITION = 0.05  # program rows need the nominal Jacobian's smallest singular value above this (m, or m and rad)
NOISE = {"position_noise": 2e-5, "orientation_noise": 2e-5, "joint_noise": 0.0}  # a laser tracker: 20 um, 20 urad
TRUE_ERRORS = {"axis_error": 0.002, "body_error": 0.001}  # U(+-2 mrad) on the axes, U(+-1 mm) on the body vectors


def scara() -> ZRPRobot:
    """A SCARA as a modified DH table (row i: a_{i-1}, alpha_{i-1}, d_i): two horizontal links of
    0.35 and 0.30 m, a quill sliding down 0 to 0.3 m, a gripper 40 mm off the last axis."""
    tool = np.eye(4)
    tool[:3, 3] = [0.04, 0.0, 0.08]
    return ZRPRobot.from_mdh(d=[0.4, 0, 0, 0], a=[0, 0.35, 0.3, 0], alpha=np.array([0, 0, 180, 0]) * D, joint_types="RRPR",
                             tool=tool, name="scara", joint_names=["j1", "j2", "j3", "j4"],
                             limits=[[-2.9, 2.9], [-2.5, 2.5], [0.0, 0.3], [-6, 6]])  # fmt: skip


ARMS = {"PUMA 560 (6R)": lambda: presets.get("puma560"), "Stanford arm (RRPRRR)": lambda: presets.get("stanford"),
        "SCARA (RRPR, 4 joints)": scara}  # fmt: skip


def program(arm: ZRPRobot, rng: np.random.Generator, M: int) -> np.ndarray:
    """M joint configurations within 90% of the limits, off the singularities (:data:`CONDITION`)."""
    lim = arm.joint_limits
    pad = 0.05 * (lim[:, 1] - lim[:, 0])
    rows = []
    while len(rows) < M:
        q = rng.uniform(lim[:, 0] + pad, lim[:, 1] - pad)
        J = compensation.forward_jacobian(arm, q)[2]
        if np.linalg.svd(J if arm.n >= 6 else J[3:], compute_uv=False)[-1] > CONDITION:
            rows.append(q)
    return np.array(rows)


def errors(arm: ZRPRobot, q: np.ndarray, R: np.ndarray | None, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (mm) and orientation (deg) errors of ``arm`` at ``q`` against the targets."""
    Rq, pq = kinematics.forward(arm, q)
    angle = np.zeros(len(q)) if R is None else np.degrees(np.linalg.norm(so3.log(Rq @ np.swapaxes(R, 1, 2)), axis=-1))
    return np.linalg.norm(pq - p, axis=1) * 1e3, angle


def simulated(name: str, arm: ZRPRobot, seed: int) -> dict:
    position_only = arm.n < 6
    noise = {**NOISE, **({"orientation_noise": 0.0} if position_only else {})}
    settings = {"n_poses": 60, "n_validation": 200, "cost": "nonlinear", "identify_base": True, "position_only": position_only,
                **TRUE_ERRORS, **noise}  # fmt: skip
    t0 = time.perf_counter()
    cal = zrp_ga.calibrate(arm, algorithm="lm", seed=seed, problem=settings)
    truth = cal.task.calibrated_robot(cal.task.truth)
    q = program(arm, np.random.default_rng([seed, 7]), N_PROGRAM)
    comp = zrp_ga.compensate(cal, q, kind="joints", unreachable="keep")
    ok = comp.reached
    before = errors(truth, q, comp.R, comp.p)
    joints = errors(truth, comp.q[ok], None if comp.R is None else comp.R[ok], comp.p[ok])
    # a controller with the nominal model, sent the corrected Cartesian targets, starting from the program's joints
    sent = [compensation.solve(comp.arms.nominal, comp.p_corrected[k], None if comp.R is None else comp.R_corrected[k], q[k]).q
            for k in np.flatnonzero(ok)]  # fmt: skip
    cartesian = errors(truth, np.array(sent), None if comp.R is None else comp.R[ok], comp.p[ok])
    corr = comp.correction()
    return {"arm": name, "joints": arm.joint_types, "targets": "positions" if comp.R is None else "poses",
            "validation_rms_mm": cal.summary["validation_rms_mm"], "reached": int(ok.sum()), "rows": len(q),
            "before": before, "joints_route": joints, "cartesian_route": cartesian,
            "dq_deg": corr["dq_deg"][ok], "dq_mm": corr.get("dq_mm", np.zeros(len(q)))[ok], "dx_mm": corr["dx_mm"][ok],
            "residual_mm": comp.residual_mm[ok], "wall_s": time.perf_counter() - t0}  # fmt: skip


def ur10(root: Path) -> dict:
    run = root / "ur10_lm"
    t0 = time.perf_counter()
    cal = zrp_ga.calibrate("ur10", algorithm="lm", problem="ur10_ipa", out=run)
    calib_s = time.perf_counter() - t0
    series_c = resolve("pkg:ur10_ipa/series_c_random_poses.csv")
    t0 = time.perf_counter()
    comp = zrp_ga.compensate(run, series_c, sep=";", decimal=",", tool="calibration", position_only=True,
                             unreachable="keep", out=root / "ur10_compensated")  # fmt: skip
    corr = comp.correction()
    return {"validation": cal.summary["position_error_mm"]["validation"], "summary": comp.summary(), "dq_deg": corr["dq_deg"],
            "dx_mm": corr["dx_mm"], "dr_deg": corr["dr_deg"], "uncompensated_mm": comp.uncompensated_mm,
            "residual_mm": comp.residual_mm, "calib_s": calib_s, "comp_s": time.perf_counter() - t0}  # fmt: skip


def rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(v))))


def table(rows: list[dict]) -> list[str]:
    f = lambda v: f"{rms(v):.4f} / {np.max(v):.4f}"
    lines = ["| arm | targets | reached | calibrated model on 200 unseen poses, RMS mm (nominal) | TRUE arm, program as written: RMS / max mm | "
             "TRUE arm, corrected joints: RMS / max mm | TRUE arm, corrected Cartesian targets via the nominal controller: RMS / max mm | "
             "orientation as written -> corrected joints: RMS deg | correction: joints max deg (prismatic mm), Cartesian RMS / max mm | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        v = r["validation_rms_mm"]
        orient = f"{rms(r['before'][1]):.4f} -> {rms(r['joints_route'][1]):.2e}" if r["targets"] == "poses" else "n/a (positions)"
        pri = f" ({np.max(r['dq_mm']):.3f} mm)" if "P" in r["joints"] else ""
        lines.append(f"| {r['arm']} | {r['targets']} | {r['reached']} of {r['rows']} | {v['calibrated']:.4f} ({v['nominal']:.3f}) | "
                     f"{f(r['before'][0])} | {f(r['joints_route'][0])} | {f(r['cartesian_route'][0])} | {orient} | "
                     f"{np.max(r['dq_deg']):.3f}{pri}, {rms(r['dx_mm']):.3f} / {np.max(r['dx_mm']):.3f} | {r['wall_s']:.1f} |")  # fmt: skip
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="where the UR10 run and its compensated program go (default: a temporary directory)")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_compensation_"))
    rows = [simulated(name, make(), seed) for seed, (name, make) in enumerate(ARMS.items())]
    u = ur10(root)
    s, v = u["summary"], u["validation"]
    pct = lambda a, k: float(np.percentile(a, k))
    lines = [
        "# Compensation: the calibrated model turned into a corrected program", "",
        "Command: `python experiments/compensation.py` (zrp_ga.compensate; the same as `zrp-ga-compensate`).", "",
        "## (a) Simulated arms, known true errors", "",
        f"True errors U(+-{TRUE_ERRORS['axis_error'] * 1e3:g} mrad) on the axes and U(+-{TRUE_ERRORS['body_error'] * 1e3:g} mm) on "
        "the body vectors and the base point; calibration by LM (`zrp_ga.calibrate(arm, algorithm='lm', problem={n_poses: 60, "
        "cost: nonlinear, identify_base: true, ...})`) on 60 poses measured with Gaussian noise of "
        f"{NOISE['position_noise'] * 1e3:g} mm and {NOISE['orientation_noise'] * 1e6:g} urad (the SCARA: positions only), no joint "
        f"noise. Program: {N_PROGRAM} random joint configurations within the limits (5% margin), the nominal Jacobian's smallest "
        f"singular value above {CONDITION}, never used for the calibration; their nominal poses are the targets. The TRUE "
        "arm runs the program as written, the corrected joint values, and the joint values a controller with the nominal model "
        "computes (its inverse kinematics from the program's joints) from the corrected Cartesian targets.", "",
        *table(rows), "",
        "## (b) The real UR10 (series B calibrates, series C is the program)", "",
        "Data: Landgraf, Ernst, Schleth, Fabritius and Huber, IEEE CASE 2021 (christianlandgraf/ipa-robot-accuracy, MIT licence; "
        "zrp_ga/data/ur10_ipa). Calibration: `zrp-ga problem=ur10_ipa algorithm=lm` (positions of the T-Mac probe in the "
        "tracker's frame). Program: series C's joint configurations, compensated for the measured probe point as positions "
        "(`zrp-ga-compensate RUN zrp_ga/data/ur10_ipa/series_c_random_poses.csv --sep ';' --decimal , --tool calibration "
        "--position-only`): the calibration measured positions only, so its orientations are not all identified. "
        "**There is no robot to run the compensated program on**: the residuals below are what the calibrated model predicts.", "",
        "| | value |", "|---|---|",
        f"| targets (series C rows) reached | {s['reached']} of {s['rows']} |",
        f"| predicted residual, max | {np.max(u['residual_mm']):.2e} mm |",
        f"| error of the program as written, as the calibrated model predicts: RMS / max | {rms(u['uncompensated_mm']):.3f} / {np.max(u['uncompensated_mm']):.3f} mm |",
        f"| correction, joints (largest joint change per target): median / 95% / max | {pct(u['dq_deg'], 50):.3f} / {pct(u['dq_deg'], 95):.3f} / {np.max(u['dq_deg']):.3f} deg |",
        f"| correction, Cartesian position: median / 95% / max | {pct(u['dx_mm'], 50):.3f} / {pct(u['dx_mm'], 95):.3f} / {np.max(u['dx_mm']):.3f} mm |",
        f"| correction, Cartesian orientation (free with position targets): median / 95% / max | {pct(u['dr_deg'], 50):.3f} / {pct(u['dr_deg'], 95):.3f} / {np.max(u['dr_deg']):.3f} deg |",
        f"| series C measured against the registered nominal arm: RMS / max | {v['nominal']['rms']:.3f} / {v['nominal']['max']:.3f} mm |",
        f"| series C measured against the calibrated arm (what the compensated program would miss by, if the model holds): RMS / max | {v['calibrated']['rms']:.3f} / {v['calibrated']['max']:.3f} mm |",
        f"| wall time: calibration / compensation of {s['rows']} targets | {u['calib_s']:.1f} / {u['comp_s']:.1f} s |",
        "",
    ]  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "compensation.md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(json.dumps({"ur10_notes": s["notes"], "unreachable": s["unreachable"][:5]}, indent=1))


if __name__ == "__main__":
    main()
