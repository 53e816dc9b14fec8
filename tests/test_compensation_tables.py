"""What a programmer pastes (zrp_ga.compensation.writing, program, configuration, orientation):
units in every header, orientation columns under their convention's own names, branch numbers,
units found from the data, the size of prismatic corrections and the seed's units; each against
a DH chain or a formula written in the test."""

import argparse
import re

import numpy as np
import pandas as pd
import pytest
from dh_reference import dh_fk
from test_compensation import PUMA, STANFORD, perturbed, programme, robot

import zrp_ga
from zrp_ga.cli.compensate import parser

D = np.pi / 180
KEEP = lambda q: abs(q[4]) > 0.3 and abs(q[2]) < 1.1


def kuka(A, B, C):
    """KUKA's A, B, C (deg): Rz(A) Ry(B) Rx(C), written out."""
    a, b, c = np.radians([A, B, C])
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return Rz @ Ry @ Rx


def quaternion(w, x, y, z):
    """The rotation of a unit quaternion (w, x, y, z), the textbook formula."""
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])  # fmt: skip


def abc_of(R):
    """A, B, C (deg) of a rotation, by hand from Rz(A) Ry(B) Rx(C)'s entries (B within +-90 deg)."""
    return np.degrees([np.arctan2(R[1, 0], R[0, 0]), -np.arcsin(R[2, 0]), np.arctan2(R[2, 1], R[2, 2])])


@pytest.fixture(scope="module")
def puma_case():
    rng = np.random.default_rng(3)
    true = perturbed(PUMA, rng)
    return true, programme(PUMA, rng, 5, KEEP)


def test_kuka_program_in_mm_and_degrees_pastes_back(tmp_path, puma_case):
    """A KUKA program (x_mm .., A_deg, B_deg, C_deg, joints in degrees as seeds): the corrected
    targets come back under the same names and units; read with the written-out Rz Ry Rx they
    are the nominal arm's poses at the corrected joints, which put the true arm on the targets."""
    true, q = puma_case
    T = [dh_fk(PUMA, qk) for qk in q]
    rows = [[*(t[:3, 3] * 1e3), *abc_of(t[:3, :3]), *np.degrees(qk)] for t, qk in zip(T, q)]
    cols = ["x_mm", "y_mm", "z_mm", "A_deg", "B_deg", "C_deg"] + [f"q{i}_deg" for i in range(1, 7)]
    pd.DataFrame(rows, columns=cols).to_csv(tmp_path / "prog.csv", index=False)
    c = zrp_ga.compensate(robot(true), tmp_path / "prog.csv", nominal=robot(PUMA), out=tmp_path / "out")
    assert (c.program.length_unit, c.program.angle_unit, c.program.convention) == ("mm", "deg", "ZYX")
    joints, targets = pd.read_csv(tmp_path / "out" / "joints.csv"), pd.read_csv(tmp_path / "out" / "targets.csv")
    assert list(targets.columns[:8]) == ["line", "status", "x_mm", "y_mm", "z_mm", "A_deg", "B_deg", "C_deg"]
    for k in range(len(q)):
        qc = np.radians(joints.loc[k, [f"q{i}_deg" for i in range(1, 7)]].to_numpy(float))
        reached = dh_fk(true, qc)
        assert np.linalg.norm(reached[:3, 3] - T[k][:3, 3]) < 1e-9
        sent = dh_fk(PUMA, qc)
        assert np.allclose(targets.loc[k, ["x_mm", "y_mm", "z_mm"]].to_numpy(float), sent[:3, 3] * 1e3, atol=1e-9)
        assert np.allclose(kuka(*targets.loc[k, ["A_deg", "B_deg", "C_deg"]].to_numpy(float)), sent[:3, :3], atol=1e-12)


def test_quaternion_program_is_abbs_q1_to_q4(tmp_path, puma_case):
    """q1..q4 (w first, ABB's order): the targets read with the textbook formula, the corrected
    ones written so (w >= 0), joint seeds then need their unit in the name (q1_deg)."""
    true, q = puma_case
    T = [dh_fk(PUMA, qk) for qk in q]
    from scipy.spatial.transform import Rotation

    quats = [np.roll(Rotation.from_matrix(t[:3, :3]).as_quat(), 1) for t in T]  # (w, x, y, z)
    assert all(np.allclose(quaternion(*qt), t[:3, :3]) for qt, t in zip(quats, T))
    rows = [[*(t[:3, 3]), *qt, *np.degrees(qk)] for t, qt, qk in zip(T, quats, q)]
    cols = ["x", "y", "z", "q1", "q2", "q3", "q4"] + [f"q{i}_deg" for i in range(1, 7)]
    pd.DataFrame(rows, columns=cols).to_csv(tmp_path / "prog.csv", index=False)
    c = zrp_ga.compensate(robot(true), tmp_path / "prog.csv", nominal=robot(PUMA), orientation_convention="quaternion",
                          out=tmp_path / "out")  # fmt: skip
    targets = pd.read_csv(tmp_path / "out" / "targets.csv")
    assert {"x_m", "q1", "q4"} <= set(targets.columns) and "q1_deg" not in targets.columns
    for k in range(len(q)):
        w, x, y, z = targets.loc[k, ["q1", "q2", "q3", "q4"]].to_numpy(float)
        assert w >= 0 and np.allclose(quaternion(w, x, y, z), dh_fk(PUMA, c.q[k])[:3, :3], atol=1e-12)
        assert np.linalg.norm(dh_fk(true, c.q[k])[:3, 3] - T[k][:3, 3]) < 1e-9


def test_every_header_names_its_unit(tmp_path, puma_case):
    """Every column of a number carries its unit, except line, status, the branch numbers and
    quaternions; joint columns are the program's (joint names stay)."""
    true, q = puma_case
    zrp_ga.compensate(robot(true), q.tolist(), nominal=robot(PUMA), kind="joints", out=tmp_path / "out")  # a list: SI units
    for name in ("joints.csv", "targets.csv"):
        cols = pd.read_csv(tmp_path / "out" / name).columns
        bare = [c for c in cols if not re.search(r"_(mm|m|deg|rad)$", c)]
        assert set(bare) <= {"line", "status", "shoulder", "elbow", "wrist", *(f"cf{i}" for i in range(1, 7))}, bare
    assert list(pd.read_csv(tmp_path / "out" / "joints.csv").columns[2:8]) == [f"q{i}_rad" for i in range(1, 7)]


def test_units_found_from_the_data(tmp_path, puma_case):
    """The same program in m and rad, in mm and deg (auto): the same corrected joints; a joint
    program in degrees whose values all lie within one turn is found by the joints' limits."""
    true, q = puma_case
    T = np.array([dh_fk(PUMA, qk) for qk in q])
    abc = np.array([abc_of(t[:3, :3]) for t in T])
    si = pd.DataFrame({"x": T[:, 0, 3], "y": T[:, 1, 3], "z": T[:, 2, 3], "A": np.radians(abc[:, 0]), "B": np.radians(abc[:, 1]),
                       "C": np.radians(abc[:, 2]), **{f"q{i + 1}": q[:, i] for i in range(6)}})  # fmt: skip
    shop = si.copy()
    shop[["x", "y", "z"]] *= 1e3
    shop[["A", "B", "C", *(f"q{i}" for i in range(1, 7))]] = np.degrees(shop[["A", "B", "C", *(f"q{i}" for i in range(1, 7))]])
    a = zrp_ga.compensate(robot(true), si, nominal=robot(PUMA))
    b = zrp_ga.compensate(robot(true), shop, nominal=robot(PUMA))
    assert (b.program.length_unit, b.program.angle_unit, b.program.orientation_unit) == ("mm", "deg", "deg")
    assert (a.program.length_unit, a.program.angle_unit) == ("m", "rad") and np.allclose(a.q, b.q, atol=1e-9)
    small = np.array([[1.0, -2.0, 3.0, 0.5, 1.0, -1.0]])  # deg; as radians joint 2 (-2 rad) is beyond its 110 deg
    frame = pd.DataFrame(small, columns=[f"q{i}" for i in range(1, 7)])
    d = zrp_ga.compensate(robot(true), frame, nominal=robot(PUMA), kind="joints", unreachable="keep")
    assert d.program.angle_unit == "deg" and np.allclose(d.q_nominal, np.radians(small))


def test_prismatic_correction_size_is_the_slide_in_mm():
    """The Stanford arm whose sliding joint reads 1.5 mm short: the corrected program slides 1.5
    mm further and turns no joint; dq_mm says 1.5, dq_deg 0."""
    cal = dict(STANFORD, d=np.array(STANFORD["d"], dtype=float))
    cal["d"][2] -= 1.5e-3  # zero offset of the slide (joint 3: theta fixed, d = d3 + q3)
    q = np.array([[0.3, 0.8, 0.6, 0.2, 0.7, -0.3], [-0.5, 1.1, 0.9, -0.4, 0.5, 0.6]])
    c = zrp_ga.compensate(robot(cal), q, nominal=robot(STANFORD), kind="joints")
    assert np.allclose(c.q[:, 2] - q[:, 2], 1.5e-3, atol=1e-12)
    corr = c.correction()
    assert np.allclose(corr["dq_mm"], 1.5, atol=1e-8) and np.allclose(corr["dq_deg"], 0.0, atol=1e-7)


def test_the_seed_is_read_in_the_programs_joint_units():
    """A target reached by two wrist branches (q5 and -q5, q4 and q6 turned half a turn): the
    seed given in degrees picks the flipped one, the default the other."""
    q = np.array([0.3, -0.5, 0.4, 0.6, 0.8, -0.5])
    flipped = q + np.array([0, 0, 0, np.pi, 0, np.pi]) * [0, 0, 0, 1, 0, 1]
    flipped[4] = -q[4]
    flipped[3], flipped[5] = q[3] - np.pi, q[5] + np.pi
    T = dh_fk(PUMA, q)
    assert np.allclose(dh_fk(PUMA, flipped), T)  # by hand: the other wrist branch
    arm = robot(PUMA)
    seed = np.degrees(flipped) + 2.0  # deg, a little off
    frame = pd.DataFrame([[*(T[:3, 3] * 1e3), *abc_of(T[:3, :3])]], columns=["x_mm", "y_mm", "z_mm", "A_deg", "B_deg", "C_deg"])
    c = zrp_ga.compensate(arm, frame, nominal=arm, q_seed=seed)
    assert np.allclose(c.q_nominal[0], flipped, atol=1e-8)
    d = zrp_ga.compensate(arm, frame, nominal=arm, q_seed=np.degrees(q) + 2.0)
    assert np.allclose(d.q_nominal[0], q, atol=1e-8)


def test_branch_numbers_against_the_dh_frames():
    """cf_j = floor(q_j / 90 deg), and the branch signs from the DH chain's own frames (axes z_i,
    points o_i, the wrist point o_4 of the PUMA's spherical wrist): two wrist branches of one
    target differ in the wrist sign only."""
    from zrp_ga.compensation import configuration

    def frames(qk):
        T, out = np.eye(4), [np.eye(4)]
        for i in range(6):
            T = T @ (dh_fk({k: (v[i : i + 1] if k != "joint_types" else v[i]) for k, v in PUMA.items()
                            if k in ("d", "a", "alpha", "joint_types")}, qk[i : i + 1]))  # fmt: skip
            out.append(T)
        return out

    arm = robot(PUMA)
    for qk in programme(PUMA, np.random.default_rng(3), 6, KEEP):
        F = frames(qk)
        z, o, w = [f[:3, 2] for f in F], [f[:3, 3] for f in F], F[4][:3, 3]
        shoulder = np.sign(np.dot(w - o[0], np.cross(z[0], z[1])))
        elbow = np.sign(np.dot(z[1], np.cross(o[2] - o[1], w - o[2])))
        wrist = np.sign(np.dot(z[3], np.cross(z[4], z[5])))
        assert configuration.signs(arm, qk).tolist() == [shoulder, elbow, wrist]
        assert configuration.quadrants(qk[None], arm.prismatic)[0].tolist() == [int(np.floor(np.degrees(v) / 90)) for v in qk]
    q = np.array([0.3, -0.5, 0.4, 0.6, 0.8, -0.5])
    flipped = np.array([0.3, -0.5, 0.4, 0.6 - np.pi, -0.8, -0.5 + np.pi])
    a, b = configuration.signs(arm, q), configuration.signs(arm, flipped)
    assert a[:2].tolist() == b[:2].tolist() and a[2] == -b[2] != 0


def test_help_says_the_true_defaults():
    """Every '(default X' in zrp-ga-compensate --help is the option's default."""
    for action in parser()._actions:
        said = re.search(r"\(default:? ([^,;:)]+)", action.help or "")
        if said is None or action.default in (None, argparse.SUPPRESS, False):
            continue
        assert str(said.group(1)).split()[0] == str(action.default), (action.dest, action.help)
    conv = next(a for a in parser()._actions if a.dest == "orientation_convention")
    assert "default rotvec)" not in conv.help and "need it stated" in conv.help
