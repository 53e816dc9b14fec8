"""Compensation (zrp_ga.compensation, zrp-ga-compensate), checked with a DH chain written in the
tests (tests/dh_reference.py): the corrected joints put the calibrated arm on the targets, the
corrected Cartesian targets are the nominal arm's poses there, limits hold, bad input is named."""

import csv

import numpy as np
import pytest
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga.cli.compensate import main
from zrp_ga.compensation.compensate import compensate
from zrp_ga.model.robot import ZRPRobot

D = np.pi / 180
PUMA = dict(d=[0.67183, 0, 0.15005, 0.4318, 0, 0], a=[0, 0.4318, 0.0203, 0, 0, 0],
            alpha=np.array([90, 0, -90, 90, -90, 0]) * D, joint_types="RRRRRR",
            limits=np.array([[-160, 160], [-110, 110], [-135, 135], [-266, 266], [-100, 100], [-266, 266]]) * D)  # fmt: skip
STANFORD = dict(d=[0.412, 0.154, 0, 0, 0, 0.263], a=[0, 0, 0.0203, 0, 0, 0], alpha=np.array([-90, 90, 0, -90, 90, 0]) * D,
                offset=[0, 0, -90 * D, 0, 0, 0], joint_types="RRPRRR",
                limits=[[-3, 3], [-3, 3], [0.3, 1.27], [-3, 3], [-1.5, 1.5], [-3, 3]])  # fmt: skip
# A SCARA as a modified DH table (row i: a_{i-1}, alpha_{i-1}, d_i): joint 3 slides down.
SCARA = dict(d=[0.4, 0, 0, 0.05], a=[0, 0.35, 0.3, 0], alpha=np.array([0, 0, 180, 0]) * D, joint_types="RRPR",
             limits=[[-2.9, 2.9], [-2.5, 2.5], [0.0, 0.3], [-6, 6]])  # fmt: skip


def perturbed(table, rng, length=1e-3, angle=5e-3):
    """The table with every a, d, alpha and joint offset moved: the 'calibrated' arm."""
    n = len(table["d"])
    out = dict(table)
    for key, size in (("d", length), ("a", length), ("alpha", angle), ("offset", angle)):
        out[key] = np.asarray(table.get(key, np.zeros(n)), dtype=float) + rng.uniform(-size, size, n)
    return out


def robot(table, modified=False, name="arm"):
    keys = {k: table[k] for k in ("d", "a", "alpha", "joint_types", "limits")}
    make = ZRPRobot.from_mdh if modified else ZRPRobot.from_dh
    return make(offset=table.get("offset"), name=name, **keys)


def programme(table, rng, M, keep=lambda q: True):
    lim = np.asarray(table["limits"], dtype=float)
    rows = []
    while len(rows) < M:
        q = rng.uniform(lim[:, 0] + 0.1 * np.ptp(lim, axis=1), lim[:, 1] - 0.1 * np.ptp(lim, axis=1))
        if keep(q):
            rows.append(q)
    return np.array(rows)


CASES = {
    "puma560": (PUMA, False, lambda q: abs(q[4]) > 0.3 and abs(q[2]) < 1.1),  # off the wrist and elbow singularities
    "stanford": (STANFORD, False, lambda q: abs(q[4]) > 0.3 and abs(q[1]) > 0.3),
    "scara": (SCARA, True, lambda q: abs(q[1]) > 0.3),
}


@pytest.mark.parametrize("arm", list(CASES))
def test_corrected_joints_put_the_calibrated_dh_chain_on_the_targets(arm):
    table, modified, keep = CASES[arm]
    rng = np.random.default_rng(7)
    true = perturbed(table, rng)
    q = programme(table, rng, 8, keep)
    c = compensate(robot(true, modified, "cal"), q, nominal=robot(table, modified), kind="joints")
    assert c.reached.all()
    lim = np.asarray(table["limits"])
    assert np.all((c.q >= lim[:, 0]) & (c.q <= lim[:, 1]))
    for k in range(len(q)):
        target = dh_fk(table, q[k], modified)
        reached = dh_fk(true, c.q[k], modified)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-9
        if len(q[k]) >= 6:  # full poses; the SCARA gets positions
            assert Rotation.from_matrix(reached[:3, :3] @ target[:3, :3].T).magnitude() < 1e-9
        # the corrected Cartesian target is the nominal arm's pose at the corrected joints
        sent = dh_fk(table, c.q[k], modified)
        assert np.allclose(c.p_corrected[k], sent[:3, 3], atol=1e-12)
        assert np.allclose(c.R_corrected[k], sent[:3, :3], atol=1e-12)
        # and the uncompensated program misses by what the calibrated chain says
        miss = np.linalg.norm(dh_fk(true, q[k], modified)[:3, 3] - target[:3, 3]) * 1e3
        assert c.uncompensated_mm[k] == pytest.approx(miss, rel=1e-9)
    assert c.uncompensated_mm.min() > 0.1  # the errors were worth correcting
    assert np.all(c.residual_mm < 1e-6)


def write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def puma_files(tmp_path, rng):
    """The calibrated and nominal PUMA as robot files (ZRP YAML)."""
    cal, nominal = tmp_path / "cal.yaml", tmp_path / "nominal.yaml"
    true = perturbed(PUMA, rng)
    robot(true, name="cal").to_yaml(cal)
    robot(PUMA, name="puma").to_yaml(nominal)
    return true, cal, nominal


def test_cli_cartesian_program_in_mm_and_degrees_with_seeds(tmp_path, capsys):
    rng = np.random.default_rng(3)
    true, cal, nominal = puma_files(tmp_path, rng)
    q = programme(PUMA, rng, 5, CASES["puma560"][2])
    poses = [dh_fk(PUMA, qk) for qk in q]
    rows = [[*(T[:3, 3] * 1e3), *Rotation.from_matrix(T[:3, :3]).as_euler("XYZ", degrees=True), *np.degrees(qk + 0.02)]
            for T, qk in zip(poses, q)]  # fmt: skip
    prog = tmp_path / "prog.csv"
    write_csv(prog, ["x", "y", "z", "rx", "ry", "rz"] + [f"q{i}" for i in range(1, 7)], rows)
    out = tmp_path / "out"
    code = main([str(cal), str(prog), "--nominal", str(nominal), "--length-unit", "mm", "--angle-unit", "deg",
                 "--orientation-convention", "XYZ", "-o", str(out)])  # fmt: skip
    assert code == 0
    assert "compensated 5 of 5 poses" in capsys.readouterr().out
    joints, targets = read_csv(out / "joints.csv"), read_csv(out / "targets.csv")
    assert [r["line"] for r in joints] == ["2", "3", "4", "5", "6"]
    for k, (j, t) in enumerate(zip(joints, targets)):
        qc = np.radians([float(j[f"q{i}_deg"]) for i in range(1, 7)])
        assert np.abs(qc - q[k]).max() < 0.2  # the seed's branch
        reached = dh_fk(true, qc)
        assert np.linalg.norm(reached[:3, 3] - poses[k][:3, 3]) < 1e-9
        assert Rotation.from_matrix(reached[:3, :3] @ poses[k][:3, :3].T).magnitude() < 1e-9
        sent = dh_fk(PUMA, qc)
        assert np.allclose([float(t[f"{c}_mm"]) for c in "xyz"], sent[:3, 3] * 1e3, atol=1e-9)
        R_sent = Rotation.from_euler("XYZ", [float(t[c]) for c in ("X1_deg", "Y2_deg", "Z3_deg")], degrees=True).as_matrix()
        assert np.allclose(R_sent, sent[:3, :3], atol=1e-12)
        dx = np.linalg.norm(sent[:3, 3] - poses[k][:3, 3]) * 1e3
        assert float(t["dx_mm"]) == pytest.approx(dx, rel=1e-9)
        assert float(j["dq_deg"]) == pytest.approx(np.degrees(np.abs(qc - q[k]).max()), rel=1e-6)


def test_cartesian_program_without_seeds_follows_the_previous_row():
    """A path in small steps, only the first row seeded: every row stays on the path's branch."""
    q0 = np.array([0.3, -0.6, 0.5, 0.4, 0.8, -0.2])
    q = q0 + np.linspace(0, 1, 12)[:, None] * np.array([0.8, 0.3, -0.4, 0.6, 0.3, 0.9])
    poses = np.array([dh_fk(PUMA, qk) for qk in q])
    true = perturbed(PUMA, np.random.default_rng(5))
    c = compensate(robot(true), poses, nominal=robot(PUMA), kind="cartesian", q_seed=q0 + 0.05)
    assert np.abs(c.q_nominal - q).max() < 1e-8  # the nominal IK found the path's own joints
    assert np.abs(c.q - q).max() < 0.1
    for k in range(len(q)):
        assert np.linalg.norm(dh_fk(true, c.q[k])[:3, 3] - poses[k][:3, 3]) < 1e-9


def test_limits_respected_a_target_beyond_them_named():
    """The SCARA's elbow at its limit: the calibrated arm, whose elbow zero is 0.01 rad off, would
    need the elbow beyond it; the row is refused and the joint named (or kept empty on request)."""
    true = dict(SCARA, offset=[0, -0.01, 0, 0])
    q = np.array([[0.2, 1.0, 0.1, 0.0], [0.2, 2.5, 0.1, 0.0]])
    cal, nominal = robot(true, True, "cal"), robot(SCARA, True, "scara")
    with pytest.raises(ValueError, match=r"row 1: target not reached: beyond the joint limits \(joint 2 at its limit"):
        compensate(cal, q, nominal=nominal, kind="joints")
    c = compensate(cal, q, nominal=nominal, kind="joints", unreachable="keep")
    assert c.reached.tolist() == [True, False]
    assert np.isnan(c.q[1]).all() and c.q[1].shape == (4,)
    assert "joint 2 at its limit [-143.239, 143.239] deg" in c.unreachable[0]
    assert np.linalg.norm(dh_fk(true, c.q[0], True)[:3, 3] - dh_fk(SCARA, q[0], True)[:3, 3]) < 1e-9


def test_target_out_of_reach_named_by_line(tmp_path, capsys):
    rng = np.random.default_rng(4)
    _, cal, nominal = puma_files(tmp_path, rng)
    prog = tmp_path / "prog.csv"
    write_csv(prog, ["x", "y", "z"], [[0.4, 0.1, 0.9], [], [3.0, 0.0, 1.0]])  # a blank line: line 3
    assert main([str(cal), str(prog), "--nominal", str(nominal), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"{prog}, line 4: target not reached: out of reach (3.162 m from the base point, cal reaches" in err
    assert main([str(cal), str(prog), "--nominal", str(nominal), "-o", str(tmp_path / "o"), "--keep-unreachable"]) == 0
    rows = read_csv(tmp_path / "o" / "joints.csv")
    assert rows[0]["status"] == "ok" and rows[1]["status"].startswith("unreachable: out of reach")
    assert rows[1]["q1_rad"] == ""
    assert "unreachable: line 4: out of reach" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("header", "rows", "extra", "message"),
    [
        (["x", "y"], [[0.1, 0.2]], [], "prog.csv: missing joint columns q1 .. q6"),
        (["x", "y", "z"], [[0.1, 0.2, 0.3], [0.4, "nan", 0.5]], [], "prog.csv, line 3, column 'y': 'nan' is not a finite number"),
        (["x", "y", "z"], [[0.1, "", 0.3]], [], "prog.csv, line 2, column 'y': empty"),
        (["q1", "q2", "q3"], [[0, 0, 0]], [], "joint columns q1, q2, q3, but puma has 6 joints"),
        (["q1", "q2", "q3", "q4", "q5", "q6"], [[0, 0, 0, 0, 0, 0], [0, 0, 90, 0, 0, 0]], ["--angle-unit", "rad"],
         "prog.csv, line 3, column 'q3': 90 rad is outside joint 3's limits [-2.35619, 2.35619] rad; in degrees? "
         "angle_unit (--angle-unit) deg"),
        (["x", "y", "z", "rx", "ry", "rz"], [[0.4, 0.1, 0.9, 0, 0, 0]], [], "columns rx, ry, rz need their orientation convention"),
        (["x", "y", "z"], [[0.4, 0.1, 0.9]], ["--frame", "instrument"], "has no base transform"),
        (["x", "y", "z", "rx", "rz"], [[0.4, 0.1, 0.9, 0, 0]], ["--orientation-convention", "XYZ"], "prog.csv: missing column 'ry'"),
        (["x", "y", "z"], [], [], "prog.csv: no program rows"),
    ],
)  # fmt: skip
def test_cli_bad_program_one_line_exit_2(tmp_path, capsys, header, rows, extra, message):
    _, cal, nominal = puma_files(tmp_path, np.random.default_rng(1))
    prog = tmp_path / "prog.csv"
    write_csv(prog, header, rows)
    assert main([str(cal), str(prog), "--nominal", str(nominal), "-o", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("zrp-ga-compensate: error: ") and err.count("\n") == 1
    assert message in err
    assert not (tmp_path / "o").exists()


def test_cli_bad_calibration_one_line_exit_2(tmp_path, capsys):
    prog = tmp_path / "prog.csv"
    write_csv(prog, ["x", "y", "z"], [[0.4, 0.1, 0.9]])
    (tmp_path / "empty").mkdir()
    assert main([str(tmp_path / "empty"), str(prog)]) == 2
    assert "empty: not a calibration run directory (no calibrated_robot.yaml)" in capsys.readouterr().err
    _, cal, _ = puma_files(tmp_path, np.random.default_rng(1))
    assert main([str(cal), str(prog)]) == 2
    assert "cal.yaml: no nominal robot with it; give the nominal arm" in capsys.readouterr().err
    assert main([str(cal), str(prog), "--nominal", "stanford"]) == 2
    assert "the calibrated arm has joints RRRRRR, the nominal stanford RRPRRR: not the same arm" in capsys.readouterr().err


def test_position_targets_for_an_arm_that_cannot_orient_only():
    q = programme(SCARA, np.random.default_rng(2), 2, CASES["scara"][2])
    poses = np.array([dh_fk(SCARA, qk, True) for qk in q])
    arm = robot(SCARA, True)
    with pytest.raises(ValueError, match="has 4 joints and cannot reach arbitrary orientations"):
        compensate(arm, poses, nominal=arm, kind="cartesian")
    c = compensate(arm, poses[:, :3, 3], nominal=arm, kind="cartesian", q_seed=q[0])
    assert c.R is None and np.all(c.residual_mm < 1e-9)


def test_run_directory_compensation_on_the_true_arm(tmp_path):
    """A simulated calibration run (nominal arm from its summary.json): its compensated program
    misses far less on the true arm than the program as written."""
    cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear", "joint_noise": 0.0}, algorithm="lm",
                           out=tmp_path / "run")  # fmt: skip
    truth = cal.task.calibrated_robot(cal.task.truth)
    q = programme(PUMA, np.random.default_rng(11), 6, CASES["puma560"][2])
    c = zrp_ga.compensate(tmp_path / "run", q, kind="joints", out=tmp_path / "comp")
    urdf = zrp_ga.compensate(tmp_path / "run" / "calibrated_robot.urdf", q, kind="joints")  # the arm in its base frame too
    assert urdf.arms.nominal.name == "puma560" and np.allclose(urdf.q, c.q, rtol=0, atol=1e-12)
    assert c.arms.nominal.name == "puma560"
    from zrp_ga.model import kinematics

    _, target = kinematics.forward(robot(PUMA), q)
    _, before = kinematics.forward(truth, q)
    _, after = kinematics.forward(truth, c.q)
    before, after = np.linalg.norm(before - target, axis=1), np.linalg.norm(after - target, axis=1)
    assert before.min() > 1e-3 and after.max() < 1e-6
    assert (tmp_path / "comp" / "compensation.json").is_file()


def test_measured_run_frames(tmp_path):
    """Measured in an instrument frame with a probe on the flange: targets in the instrument's
    frame (frame='instrument', tool='calibration') come out as joints that put the true probe there."""
    from zrp_ga.model.poses import Measurements

    rng = np.random.default_rng(9)
    true = perturbed(PUMA, rng, length=5e-4, angle=2e-3)
    probe = np.array([0.01, -0.02, 0.1])
    Rb, tb = Rotation.from_rotvec([0.1, -0.2, 0.8]).as_matrix(), np.array([2.0, -1.0, 0.3])

    def seen(q):  # the true probe in the instrument's frame
        T = np.array([dh_fk(true, qk) for qk in np.atleast_2d(q)])
        return (T[:, :3, :3] @ probe + T[:, :3, 3]) @ Rb.T + tb

    q_cal = programme(PUMA, rng, 60, CASES["puma560"][2])
    data = Measurements(q=q_cal, p=seen(q_cal), source="tracker")
    zrp_ga.calibrate("puma560", data, algorithm="lm", out=tmp_path / "run")
    q = programme(PUMA, rng, 5, CASES["puma560"][2])
    c = zrp_ga.compensate(tmp_path / "run", seen(q + 0.01), kind="cartesian", frame="instrument", tool="calibration")
    assert c.reached.all()
    assert np.abs(seen(c.q) - seen(q + 0.01)).max() < 1e-6
