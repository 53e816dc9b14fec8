"""Compensation: does a calibrated model make the arm reach its program? (zrp_ga.compensate)

(a) Simulated arms with known true errors, of three kinds: the PUMA 560 (6R), the Stanford arm
(joint 3 prismatic) and a 4-joint SCARA (RRPR, a modified DH table; positions only). Each is
calibrated by Levenberg-Marquardt (``zrp_ga.calibrate``, the simulated multi-pose problem) on
60 measured poses with laser-tracker noise; then a program of 200 targets never used for the
calibration (random joint values within the limits, off the singularities, their nominal poses
the targets) is compensated, and run on the TRUE arm: as written, with the corrected joint
values, and through a controller that knows only the nominal model and is sent the corrected
Cartesian targets (its inverse kinematics from the program's joints).

(c) Frames programmers use, on a 6R arm of our own (a DH table written here, ``CELL``): a true
arm with DH errors, a laser tracker about 2.5 m away, a 6D probe on the flange (a known mount
``PROBE``), simulated measurement files in mm and degrees (60 calibration and 40 validation
poses, circles of joints 1 and 2 for a base setup, three points of a work object). Calibrated
by LM on positions only and on full poses (``zrp_ga.calibrate(arm, FILE, validation=FILE,
algorithm="lm", problem={"use_orientation": ...})``); then programs of 40 targets (CSV files in
mm and KUKA's A, B, C in degrees, each row with seed joints) compensated from the run directory:
flange targets in the robot's base frame (under each base and tool setup), TCP (probe) targets
in a work object measured as three points, and in the tracker's frame. Each is run on the TRUE
arm, in the frame a programmer means (the base frame the true arm's axes fix by the stated
convention, the true work object, the tracker), as written (the nominal model's joints) and
compensated; beside it, what ``compensation.json`` names as left open, with its size.

(b) The real UR10 data (Landgraf et al., IEEE CASE 2021; christianlandgraf/ipa-robot-accuracy,
MIT licence; shipped in zrp_ga/data/ur10_ipa): calibrated by LM on series B as
``zrp-ga problem=ur10_ipa algorithm=lm`` does, then series C's 2,773 joint configurations
compensated as a program (``zrp-ga-compensate RUN series_c_random_poses.csv --sep ';'
--decimal , --tool calibration --position-only``): the correction sizes and the predicted
residuals. There is no robot to run them on.

Run:

    python experiments/compensation.py [--out DIR] [--parts a b c]

Writes results/compensation.md (with ``--parts``, only those sections are replaced).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga.compensation import compensate as compensation
from zrp_ga.compensation import frames
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


# --- (c) frames programmers use ---------------------------------------------------------------------
CELL = dict(d=[0.675, 0, 0, 0.670, 0, 0.115], a=[0.260, 0.680, 0.035, 0, 0, 0],
            alpha=np.radians([-90, 0, 90, -90, 90, 0]), offset=np.radians([0, -90, 0, 0, 0, 0]),
            limits=np.radians([[-170, 170], [-140, -5], [-120, 150], [-185, 185], [-120, 120], [-350, 350]]))  # fmt: skip
CELL_ERRORS = {"d": 5e-4, "a": 5e-4, "alpha": 1e-3, "offset": 1e-3}  # N(0, s): m, m, rad, rad
TRACKER_M = 2.5
PROBE = frames.transform(Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(), [0.03, -0.02, 0.12])  # the probe in the flange
TRACKER_NOISE = {"mm": 0.02, "urad": 50.0}  # per coordinate; per axis of the 6D probe's orientation
N_TARGETS = 40


def cell_arm(table: dict, name: str) -> ZRPRobot:
    return ZRPRobot.from_dh(d=table["d"], a=table["a"], alpha=table["alpha"], offset=table["offset"], joint_types="RRRRRR",
                            limits=CELL["limits"], name=name)  # fmt: skip


def poses_of(robot: ZRPRobot, q: np.ndarray) -> np.ndarray:
    """Hand poses (M, 4, 4) of ``robot`` at ``q`` (M, n)."""
    R, p = kinematics.forward(robot, q)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = R, p
    return T


@dataclasses.dataclass
class Cell:
    """The simulated cell: the nominal and true arms (the true one in its mounting frame), the
    tracker (the mounting frame in the tracker's), and the frames a programmer means."""

    nominal: ZRPRobot
    true: ZRPRobot
    tracker: np.ndarray
    rng: np.random.Generator

    def probe(self, q: np.ndarray) -> np.ndarray:
        """The true probe's poses in the tracker's frame."""
        return self.tracker @ poses_of(self.true, q) @ PROBE

    def base(self) -> np.ndarray:
        """The base frame a programmer means, in the tracker's frame: the one the true arm's axes
        1 and 2 fix by the convention of zrp_ga.compensation.frames (what a base setup measures)."""
        return self.tracker @ frames.conventional_base(self.true, self.nominal)

    def measured(self, q: np.ndarray) -> pd.DataFrame:
        """The tracker's file of the probe at ``q``: joints in degrees, positions in mm, the
        orientation as XYZ Euler angles in degrees, with the tracker's noise."""
        T = self.probe(q)
        p = T[:, :3, 3] + self.rng.normal(0.0, TRACKER_NOISE["mm"] * 1e-3, (len(q), 3))
        R = Rotation.from_rotvec(self.rng.normal(0.0, TRACKER_NOISE["urad"] * 1e-6, (len(q), 3))).as_matrix() @ T[:, :3, :3]
        angles = Rotation.from_matrix(R).as_euler("XYZ", degrees=True)
        cols = {f"q{i + 1}": np.degrees(q[:, i]) for i in range(6)}
        cols.update({c: p[:, j] * 1e3 for j, c in enumerate("xyz")}, **{c: angles[:, j] for j, c in enumerate(("rx", "ry", "rz"))})
        return pd.DataFrame(cols)


def make_cell(seed: int = 31) -> Cell:
    rng = np.random.default_rng(seed)
    true = {k: np.asarray(CELL[k], dtype=float) + rng.normal(0.0, s, 6) for k, s in CELL_ERRORS.items()}
    direction = rng.normal(size=3)
    tracker = frames.transform(Rotation.random(random_state=rng).as_matrix(), TRACKER_M * direction / np.linalg.norm(direction))
    return Cell(cell_arm(CELL, "cell6"), cell_arm(true, "cell6 (true)"), tracker, rng)


def cell_program(cell: Cell, M: int, seed: int) -> np.ndarray:
    """M joint configurations within the limits less 5% of each range (wrist joints within +-180
    deg), off the singularities (:data:`CONDITION`)."""
    rng, lim = np.random.default_rng(seed), CELL["limits"]
    pad = 0.05 * (lim[:, 1] - lim[:, 0])
    rows = []
    while len(rows) < M:
        q = rng.uniform(lim[:, 0] + pad, lim[:, 1] - pad)
        q[3:] = np.clip(q[3:], -np.pi, np.pi)
        if np.linalg.svd(compensation.forward_jacobian(cell.nominal, q)[2], compute_uv=False)[-1] > CONDITION:
            rows.append(q)
    return np.array(rows)


def program_csv(path: Path, T: np.ndarray, seeds: np.ndarray) -> Path:
    """A Cartesian program as a KUKA programmer writes it: x_mm, y_mm, z_mm, A_deg, B_deg, C_deg
    (ZYX), and each row's seed joints q1_deg .. q6_deg."""
    abc = Rotation.from_matrix(T[:, :3, :3]).as_euler("ZYX", degrees=True)
    cols = {f"{c}_mm": T[:, j, 3] * 1e3 for j, c in enumerate("xyz")}
    cols.update({f"{c}_deg": abc[:, j] for j, c in enumerate("ABC")}, **{f"q{i + 1}_deg": np.degrees(seeds[:, i]) for i in range(6)})
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


def cell_files(cell: Cell, root: Path) -> dict[str, Path]:
    """The tracker's files: calibration, validation, circles of joints 1 and 2, three points of a work object."""
    root.mkdir(parents=True, exist_ok=True)
    files = {k: root / f"{k}.csv" for k in ("calibration", "validation", "circles", "work_object")}
    cell.measured(cell_program(cell, 60, 1)).to_csv(files["calibration"], index=False)
    cell.measured(cell_program(cell, 40, 2)).to_csv(files["validation"], index=False)
    home = np.radians([0.0, -90.0, 90.0, 0.0, 45.0, 0.0])
    turn1, turn2 = np.tile(home, (9, 1)), np.tile(home, (9, 1))
    turn1[:, 0] = np.radians(np.linspace(-60, 60, 9))
    turn2[:, 0], turn2[:, 1] = np.radians(20.0), np.radians(np.linspace(-120, -40, 9))
    cell.measured(np.vstack([turn1, turn2]))[[f"q{i + 1}" for i in range(6)] + list("xyz")].to_csv(files["circles"], index=False)
    W = work_object_true(cell)
    points = np.array([W[:3, 3], W[:3, 3] + 0.5 * W[:3, 0], W[:3, 3] + 0.4 * W[:3, 1] + 0.1 * W[:3, 0]])
    points += cell.rng.normal(0.0, TRACKER_NOISE["mm"] * 1e-3, points.shape)
    pd.DataFrame({"point": list("OXY"), **{f"{c}_mm": points[:, j] * 1e3 for j, c in enumerate("xyz")}}).to_csv(files["work_object"], index=False)
    return files


def work_object_true(cell: Cell) -> np.ndarray:
    """The work object (a table in front of the robot) in the tracker's frame."""
    return cell.tracker @ frames.transform(Rotation.from_rotvec([0.0, 0.0, 0.4]).as_matrix(), [0.9, -0.4, 0.3])


def pose_errors(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (mm) and orientation (deg) differences of poses (M, 4, 4)."""
    angle = np.linalg.norm(so3.log(np.swapaxes(A[:, :3, :3], 1, 2) @ B[:, :3, :3]), axis=-1)
    return np.linalg.norm(A[:, :3, 3] - B[:, :3, 3], axis=1) * 1e3, np.degrees(angle)


def named(notes: list[str]) -> str:
    """What compensation.json names as left open, one short phrase a note."""
    import re

    out = []
    for note in notes:
        head = note.split(":")[0]
        sizes = re.findall(r"about ([\d.e+-]+ (?:mm|deg|e)(?: and [\d.e+-]+ deg)?)", note) or re.findall(r"([\d.e+-]+ mm) \(at", note)
        if head in ("flange targets", "orientations", "base frame", "work object") and sizes:
            out.append(f"{head}: {', '.join(sizes)}")
        elif head == "tool orientation":
            out.append("tool orientation: the flange's (the probe's turn in its mount, not in the data)")
    return "; ".join(out) or "nothing"


def frames_case(cell: Cell, run: Path, program: Path, truth, kind: str, **settings) -> dict:
    """One program compensated from ``run`` and run on the true arm: ``truth(q)`` the true poses
    (M, 4, 4) in the program's frame at joints q, against the program's targets."""
    c = zrp_ga.compensate(run, program, unreachable="keep", **settings)
    ok = c.reached
    target = pd.read_csv(program)
    T = np.tile(np.eye(4), (len(target), 1, 1))
    T[:, :3, 3] = target[["x_mm", "y_mm", "z_mm"]].to_numpy() * 1e-3
    T[:, :3, :3] = Rotation.from_euler("ZYX", target[["A_deg", "B_deg", "C_deg"]].to_numpy(), degrees=True).as_matrix()
    before, after = pose_errors(truth(c.q_nominal[ok]), T[ok]), pose_errors(truth(c.q[ok]), T[ok])
    return {"kind": kind, "reached": f"{int(ok.sum())} of {len(ok)}", "before": before, "after": after,
            "named": named(c.summary()["notes"]), "setups": settings}  # fmt: skip


def frames_study(root: Path) -> tuple[list[dict], dict]:
    """Section (c): the calibrations and the rows of its table."""
    cell = make_cell()
    files = cell_files(cell, root)
    q = cell_program(cell, N_TARGETS, 7)
    base_inv = frames.inverse(cell.base())
    flange = program_csv(root / "flange_targets.csv", poses_of(cell.nominal, q), q)
    tcp_q = q + 0.02
    W = work_object_true(cell)
    tcp_tracker = program_csv(root / "tcp_tracker.csv", cell.probe(tcp_q), q)
    tcp_wo = program_csv(root / "tcp_work_object.csv", frames.inverse(W) @ cell.probe(tcp_q), q)
    in_base = lambda qq: base_inv @ cell.tracker @ poses_of(cell.true, qq)
    rows, calibrations = [], {}
    for data, orient in (("positions", False), ("poses (6D probe)", True)):
        run = root / f"run_{'poses' if orient else 'positions'}"
        t0 = time.perf_counter()
        cal = zrp_ga.calibrate(cell.nominal, files["calibration"], validation=files["validation"], algorithm="lm",
                               problem={"use_orientation": orient, "orientation_convention": "XYZ"}, out=run)  # fmt: skip
        calibrations[data] = {"validation": cal.summary["position_error_mm"]["validation"], "wall_s": time.perf_counter() - t0}
        mount = {} if orient else {"probe_in_flange": PROBE}  # positions only: the probe's mount gives the TCP's orientation
        cases = [
            ("flange, base frame", flange, in_base, {}),
            ("flange, base frame", flange, in_base, {"base_setup": "calibration"}),
            ("flange, base frame", flange, in_base, {"probe_in_flange": PROBE}),
            ("flange, base frame", flange, in_base, {"base_setup": files["circles"], "probe_in_flange": PROBE}),
            ("TCP, work object (3 measured points)", tcp_wo, lambda qq: frames.inverse(W) @ cell.probe(qq),
             {"work_object": files["work_object"], "tool": "calibration", **mount}),
            ("TCP, tracker frame", tcp_tracker, cell.probe, {"frame": "instrument", "tool": "calibration", **mount}),
        ]  # fmt: skip
        if not orient:  # the measured point has no orientation: without the mount, the TCP's is the flange's (named)
            cases.append(("TCP, tracker frame", tcp_tracker, cell.probe, {"frame": "instrument", "tool": "calibration"}))
        for kind, program, truth, settings in cases:
            rows.append({"data": data, **frames_case(cell, run, program, truth, kind, **settings)})
    wo_error = pose_errors(frames.inverse(W) @ cell.probe(tcp_q), frames.inverse(_measured_work_object(files)) @ cell.probe(tcp_q))
    return rows, {"calibrations": calibrations, "work_object_error": wo_error, "base_vs_mount": frames.pose_difference(cell.tracker, cell.base(), 1.0)}


def _measured_work_object(files: dict[str, Path]) -> np.ndarray:
    points = pd.read_csv(files["work_object"])[["x_mm", "y_mm", "z_mm"]].to_numpy() * 1e-3
    return frames.work_object(*points)


def setups_text(settings: dict) -> str:
    out = []
    base = settings.get("base_setup", "axes (default)")
    out.append(f"base: {'circles' if isinstance(base, Path) else base}" if "work_object" not in settings and settings.get("frame") != "instrument" else "")
    if "probe_in_flange" in settings:
        out.append("probe mount given")
    elif settings.get("tool") != "calibration":
        out.append("flange: the calibration's split")
    if settings.get("tool") == "calibration":
        out.append("tool: the measured probe")
    return ", ".join(o for o in out if o)


def frames_table(rows: list[dict]) -> list[str]:
    f = lambda v: f"{rms(v):.3f} / {np.max(v):.3f}"
    lines = ["| data | targets | setups | reached | TRUE arm as written: mm RMS / max; deg RMS | TRUE arm compensated: mm RMS / max | "
             "deg RMS / max | compensation.json names (size) |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        (bp, ba), (ap, aa) = r["before"], r["after"]
        lines.append(f"| {r['data']} | {r['kind']} | {setups_text(r['setups'])} | {r['reached']} | {f(bp)}; {rms(ba):.3f} | "
                     f"{f(ap)} | {rms(aa):.4f} / {np.max(aa):.4f} | {r['named']} |")  # fmt: skip
    return lines


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


def section_a() -> list[str]:
    rows = [simulated(name, make(), seed) for seed, (name, make) in enumerate(ARMS.items())]
    return [
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
    ]  # fmt: skip


def section_b(root: Path) -> list[str]:
    u = ur10(root)
    s, v = u["summary"], u["validation"]
    pct = lambda a, k: float(np.percentile(a, k))
    print(json.dumps({"ur10_notes": s["notes"], "unreachable": s["unreachable"][:5]}, indent=1))
    return [
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


def section_c(root: Path) -> list[str]:
    t0 = time.perf_counter()
    rows, info = frames_study(root / "cell")
    cal = info["calibrations"]
    val = "; ".join(f"{k}: {v['validation']['nominal']['rms']:.3f} -> {v['validation']['calibrated']['rms']:.4f} mm RMS" for k, v in cal.items())
    wo_mm, wo_deg = info["work_object_error"]
    base_m, base_rad = info["base_vs_mount"]
    return [
        "## (c) Frames programmers use: a 6R arm of our own, a tracker 2.5 m away, a 6D probe", "",
        f"The arm: the DH table `CELL` of experiments/compensation.py; the true arm has errors N(0, {CELL_ERRORS['d'] * 1e3:g} mm) on "
        f"d and a, N(0, {CELL_ERRORS['alpha'] * 1e3:g} mrad) on alpha and the joint offsets. The tracker stands {TRACKER_M} m away "
        f"and measures the probe ({np.linalg.norm(PROBE[:3, 3]) * 1e3:.0f} mm from the flange, turned "
        f"{np.degrees(np.linalg.norm(Rotation.from_matrix(PROBE[:3, :3]).as_rotvec())):.0f} deg) with N(0, {TRACKER_NOISE['mm']} mm) per "
        f"coordinate and N(0, {TRACKER_NOISE['urad']:g} urad) per orientation axis. Files: 60 calibration and 40 validation poses "
        "(joints in degrees, points in mm, orientations as XYZ Euler angles in degrees), 9 points on each of the circles of "
        "joints 1 and 2, three points O, X, Y of a work object (0.5 m apart). Validation (`zrp_ga.calibrate(arm, FILE, "
        f"validation=FILE, algorithm='lm', problem={{'use_orientation': ...}})`): {val}.", "",
        f"Programs: {N_TARGETS} targets each, CSV files in mm and KUKA's A, B, C in degrees with each row's seed joints, "
        "compensated by `zrp_ga.compensate(RUN, FILE, ...)` (the same as `zrp-ga-compensate RUN FILE ...`). Flange targets "
        "are the nominal arm's flange poses in the base frame; TCP targets are poses of the probe (the measured tool: "
        "`tool='calibration'`), in a work object given by its three measured points (`work_object=FILE`) or in the tracker's "
        "frame (`frame='instrument'`). Each is run on the TRUE arm and compared in the frame the programmer means: the base "
        "frame that the true arm's axes 1 and 2 fix by the stated convention (what a base setup measures; it lies "
        f"{base_m * 1e3:.2f} mm and {np.degrees(base_rad):.3f} deg from the true arm's mounting frame at 1 m, the joint-1 zero "
        "offset and the first link's error that no measurement of the arm's motion separates from the base), the true work "
        "object, the tracker. 'As written': the joints the nominal model gives with the same setups. 'Probe mount given': "
        "`probe_in_flange=PROBE` (the tool setup from a known transform). With positions only, TCP targets need the probe's "
        "mount for their orientation and it is given.", "",
        *frames_table(rows), "",
        f"The work object from three points measured with the tracker's noise is itself off by {rms(wo_mm):.3f} mm RMS "
        f"({np.max(wo_mm):.3f} max) and {rms(wo_deg):.4f} deg at these targets. Wall time of (c): {time.perf_counter() - t0:.0f} s.", "",
    ]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="where the runs and the compensated programs go (default: a temporary directory)")
    parser.add_argument("--parts", nargs="*", default=["a", "b", "c"], choices=["a", "b", "c"], help="sections to run (the others are kept)")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="zrp_ga_compensation_"))
    make = {"a": section_a, "b": lambda: section_b(root), "c": lambda: section_c(root)}
    path = RESULTS / "compensation.md"
    sections = _sections(path.read_text()) if path.exists() else {}
    for part in args.parts:
        sections[part] = "\n".join(make[part]())
    head = ["# Compensation: the calibrated model turned into a corrected program", "",
            "Command: `python experiments/compensation.py` (zrp_ga.compensate; the same as `zrp-ga-compensate`); a section can "
            "be run alone with `--parts`.", ""]  # fmt: skip
    RESULTS.mkdir(exist_ok=True)
    text = "\n".join(head + [sections[k] for k in sorted(sections)])
    path.write_text(text)
    print(text)


def _sections(text: str) -> dict[str, str]:
    """The sections ``## (a)`` ... of a results file, by letter."""
    out, key = {}, None
    for line in text.splitlines():
        if line.startswith("## ("):
            key = line[4]
            out[key] = []
        if key:
            out[key].append(line)
    return {k: "\n".join(v) for k, v in out.items()}


if __name__ == "__main__":
    main()
