"""Frames programmers use (zrp_ga.compensation.frames, setups), checked against hand
computations and a DH chain written in the tests (tests/dh_reference.py): work objects from
three points, the base frame by convention and from measured circles, targets in the tracker's
frame with their orientations, flange targets with the probe's mount given, and what is named
when the data cannot determine it."""

import json

import numpy as np
import pytest
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga.compensation import frames, setups
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot

D = np.pi / 180
# A 6R arm of our own (standard DH): axes 1 and 2 do not meet (a1 = 0.26 m).
CELL = dict(d=[0.675, 0, 0, 0.670, 0, 0.115], a=[0.260, 0.680, 0.035, 0, 0, 0], alpha=np.array([-90, 0, 90, -90, 90, 0]) * D,
            offset=np.array([0, -90, 0, 0, 0, 0]) * D, joint_types="RRRRRR",
            limits=np.array([[-170, 170], [-140, -5], [-120, 150], [-185, 185], [-120, 120], [-350, 350]]) * D)  # fmt: skip
DELTA, EPS = 0.004, 0.0012  # the true arm's joint-1 zero offset (rad) and first link's length error (m)


def Rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def Tz(d):
    T = np.eye(4)
    T[2, 3] = d
    return T


def robot(table, name="arm"):
    return ZRPRobot.from_dh(d=table["d"], a=table["a"], alpha=table["alpha"], offset=table["offset"],
                            joint_types=table["joint_types"], limits=table["limits"], name=name)  # fmt: skip


def true_table(rng=None):
    """The true arm: joint 1's zero off by DELTA, the first link longer by EPS, and (with rng)
    every other row's a, d, alpha and offset off too."""
    t = {k: np.array(v, dtype=float) if k != "joint_types" else v for k, v in CELL.items()}
    t["offset"][0] += DELTA
    t["d"][0] += EPS
    if rng is not None:
        for k, s in (("d", 3e-4), ("a", 3e-4), ("alpha", 5e-4), ("offset", 5e-4)):
            t[k][1:] += rng.normal(0, s, 5)
    return t


TRACKER = np.eye(4)
TRACKER[:3, :3] = Rotation.from_rotvec([0.3, -0.5, 2.0]).as_matrix()
TRACKER[:3, 3] = [1.8, -1.2, 0.9]  # the arm's mounting frame in the tracker's, 2.3 m away


def test_work_object_from_three_points_by_hand():
    """O, X on the x axis, Y anywhere in the xy plane on the side of +y: the frame's axes are the
    ones written out, its origin O; the points given in any frame map as that frame does."""
    o, x, y = np.array([0.5, -0.2, 0.3]), np.array([0.6, 0.8, 0.0]), np.array([0.0, 0.0, 1.0])
    z = np.cross(x, y)  # by hand: (0.6, 0.8, 0) x (0, 0, 1) = (0.8, -0.6, 0)
    assert np.allclose(z, [0.8, -0.6, 0.0])
    W = frames.work_object(o, o + 0.5 * x, o + 0.3 * y + 0.7 * x)
    assert np.allclose(W[:3, 0], x) and np.allclose(W[:3, 1], y) and np.allclose(W[:3, 2], z) and np.allclose(W[:3, 3], o)
    # the same points seen from the tracker: the tracker's transform times W
    seen = [TRACKER[:3, :3] @ p + TRACKER[:3, 3] for p in (o, o + 0.5 * x, o + 0.3 * y + 0.7 * x)]
    assert np.allclose(frames.work_object(*seen), TRACKER @ W, atol=1e-12)
    with pytest.raises(ValueError, match="lie on one line"):
        frames.work_object(o, o + x, o + 2 * x)


def test_base_frame_by_convention_is_the_joint_1_offset_and_the_first_links_error():
    """By hand: for a DH arm, axes 1 and 2 are z0 and z1; their common normal is x1 at height d1
    along z0, along sign(sin alpha1) (cos theta1, sin theta1, 0). The true arm's convention
    frame against the nominal's is therefore Rz(DELTA) Tz(EPS), wherever the arm stands."""
    nominal, true = robot(CELL), robot(true_table(np.random.default_rng(1)))
    assert np.allclose(frames.conventional_base(nominal, nominal), np.eye(4), atol=1e-12)
    assert np.allclose(frames.conventional_base(true, nominal), Rz(DELTA) @ Tz(EPS), atol=1e-12)
    seen = true.transformed(TRACKER[:3, :3], TRACKER[:3, 3])
    assert np.allclose(frames.conventional_base(seen, nominal), TRACKER @ Rz(DELTA) @ Tz(EPS), atol=1e-12)


def probe_points(table, q, probe):
    """The probe's points (M, 3) in the tracker's frame, from the DH chain."""
    return np.array([(TRACKER @ dh_fk(table, qk) @ np.append(probe, 1.0))[:3] for qk in q])


def circles(table, probe, noise=0.0, rng=None):
    """Measured circles: joint 1 turning from -60 to 60 deg, then joint 2 from -120 to -40 deg
    with joint 1 at 20 deg, the others held; rows shuffled."""
    home = np.array([0.0, -90.0, 90.0, 0.0, 45.0, 0.0]) * D
    one, two = np.tile(home, (7, 1)), np.tile(home, (7, 1))
    one[:, 0] = np.linspace(-60, 60, 7) * D
    two[:, 0], two[:, 1] = 20 * D, np.linspace(-120, -40, 7) * D
    q = np.vstack([one, two])[np.random.default_rng(5).permutation(14)]
    p = probe_points(table, q, probe)
    if noise:
        p = p + rng.normal(0, noise, p.shape)
    return Measurements(q=q, p=p, source="circles")


def test_fit_circle_gives_the_axis_its_sense_and_the_centre():
    """Points on a circle of radius 0.3 m about the line through c along u, turning right-handed
    about u with q: the fit returns u (not -u), a point on the line and the radius."""
    u = np.array([1.0, 2.0, 2.0]) / 3.0
    e1 = np.cross(u, [0, 0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    c, q = np.array([0.2, -0.1, 0.4]), np.linspace(-1.0, 0.7, 6)
    P = c + 0.3 * (np.cos(q)[:, None] * e1 + np.sin(q)[:, None] * e2)  # e1 x e2 = u: right-handed about u
    line, radius, rms = frames.fit_circle(P, q)
    assert np.allclose(line.direction, u) and radius == pytest.approx(0.3) and rms < 1e-12
    assert np.linalg.norm(np.cross(line.point - c, u)) < 1e-12  # on the line
    back, *_ = frames.fit_circle(P, -q)
    assert np.allclose(back.direction, -u)


def test_base_setup_from_circles_is_the_convention_on_the_true_axes():
    """Exact circles of the true arm give Rz(DELTA) Tz(EPS) in the tracker's frame; with the
    tracker's noise, within a few hundredths of a millimetre over a metre."""
    nominal, table = robot(CELL), true_table(np.random.default_rng(2))
    probe = np.array([0.03, -0.02, 0.12])
    B, said = setups.circles_base(circles(table, probe), nominal)
    assert np.allclose(B, TRACKER @ Rz(DELTA) @ Tz(EPS), atol=1e-10)
    assert "circles of joints 1 and 2" in said
    rng = np.random.default_rng(3)
    noisy, _ = setups.circles_base(circles(table, probe, 2e-5, rng), nominal)
    assert frames.pose_difference(noisy, B, 1.0)[0] < 2e-4
    only_one = circles(table, probe)
    rows = np.flatnonzero(np.isclose(only_one.q[:, 1], -90 * D))  # joint 1's circle alone
    with pytest.raises(ValueError, match="no circle of joint 2"):
        setups.circles_base(Measurements(q=only_one.q[rows], p=only_one.p[rows]), nominal)


# --- a measured run, made by hand --------------------------------------------------------------------
PROBE = np.eye(4)
PROBE[:3, :3] = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()
PROBE[:3, 3] = [0.03, -0.02, 0.12]
GAUGE = 0.003  # rad: the registration's base turned about z against the convention's (a joint-1 offset it kept)


def run_dir(tmp_path, table):
    """A measured run's directory as zrp-ga writes one: the true arm (here the calibration found
    it exactly) in a registration base frame turned by GAUGE about axis 1 and EPS off, the base
    transform, the probe in the flange, the nominal arm recorded."""
    nominal, true = robot(CELL, "cell6"), robot(table, "cell6 calibrated")
    registration = TRACKER @ Rz(-GAUGE)
    seen = true.transformed(TRACKER[:3, :3], TRACKER[:3, 3])
    inv = np.linalg.inv(registration)
    run = tmp_path / "run"
    run.mkdir()
    seen.transformed(inv[:3, :3], inv[:3, 3]).to_yaml(run / "calibrated_robot.yaml")
    summary = {"robot_model": nominal.to_dict(), "config": {"problem": {"use_orientation": True}},
               "calibrated_robot": {"base": registration.tolist(), "tools": {"probe": PROBE.tolist()}},
               "position_error_mm": {"calibration": {"calibrated": {"rms": 0.02 * np.sqrt(3)}}}}  # fmt: skip
    (run / "summary.json").write_text(json.dumps(summary))
    return run


def program(rng, M=6):
    lim = CELL["limits"]
    q = rng.uniform(lim[:, 0] + 0.2 * np.ptp(lim, axis=1), lim[:, 1] - 0.2 * np.ptp(lim, axis=1), (M, 6))
    q[:, 4] = np.where(np.abs(q[:, 4]) < 0.3, 0.5, q[:, 4])  # off the wrist singularity
    return q


def test_orientation_targets_in_the_tracker_frame_are_reached_by_the_true_probe(tmp_path):
    """Probe poses given in the tracker's frame: the corrected joints put the true probe (the
    DH chain, its mount, the tracker) on them, position and orientation."""
    table = true_table(np.random.default_rng(4))
    run = run_dir(tmp_path, table)
    q = program(np.random.default_rng(5))
    targets = np.array([TRACKER @ dh_fk(table, qk + 0.03) @ PROBE for qk in q])
    c = zrp_ga.compensate(run, targets, kind="cartesian", frame="instrument", tool="calibration", q_seed=q[0])
    for k in range(len(q)):
        got = TRACKER @ dh_fk(table, c.q[k]) @ PROBE
        assert np.linalg.norm(got[:3, 3] - targets[k, :3, 3]) < 1e-9
        assert Rotation.from_matrix(got[:3, :3] @ targets[k, :3, :3].T).magnitude() < 1e-9


def test_flange_targets_in_the_base_frame_with_the_probe_mount_given(tmp_path):
    """Flange targets in the base frame the true arm's axes fix (Rz(DELTA) Tz(EPS) in its
    mounting frame, by hand): with the probe's mount given they are reached exactly; the
    registration's base frame (base_setup='calibration') misses by the gauge it kept, and
    compensation.json names that size; without the mount, the split is named."""
    table = true_table(np.random.default_rng(6))
    run = run_dir(tmp_path, table)
    base = Rz(DELTA) @ Tz(EPS)  # in the true arm's mounting frame, by hand
    q = program(np.random.default_rng(7))
    nominal = robot(CELL)
    targets = np.array([dh_fk(CELL, qk) for qk in q])  # the nominal flange poses: a program in the base frame
    c = zrp_ga.compensate(run, targets, kind="cartesian", probe_in_flange=PROBE, q_seed=q[0], out=tmp_path / "out")
    for k in range(len(q)):
        got = np.linalg.inv(base) @ dh_fk(table, c.q[k])
        assert np.linalg.norm(got[:3, 3] - targets[k, :3, 3]) < 1e-9
        assert Rotation.from_matrix(got[:3, :3] @ targets[k, :3, :3].T).magnitude() < 1e-9
    written = json.loads((tmp_path / "out" / "compensation.json").read_text())
    assert written["base_setup"]["setup"] == "axes" and not any(n.startswith("flange targets") for n in written["notes"])
    kept = zrp_ga.compensate(run, targets, kind="cartesian", probe_in_flange=PROBE, q_seed=q[0], base_setup="calibration")
    miss = [np.linalg.norm((np.linalg.inv(base) @ dh_fk(table, qk))[:3, 3] - t[:3, 3]) for qk, t in zip(kept.q, targets)]
    reach = float(np.linalg.norm(nominal.b0[1:], axis=1).sum())
    named = (GAUGE + DELTA) * reach + EPS  # the registration's frame: turned by GAUGE + DELTA, EPS along axis 1 from the convention's
    assert 0.2 * named < max(miss) < named
    note = next(n for n in kept.summary()["notes"] if n.startswith("base frame"))
    assert f"{named * 1e3:.3g} mm (at {reach:.3g} m)" in note
    split = zrp_ga.compensate(run, targets, kind="cartesian", q_seed=q[0])
    assert any(n.startswith("flange targets: the data do not determine") for n in split.summary()["notes"])


def test_targets_in_a_work_object_measured_as_three_points(tmp_path):
    """Probe positions given in a work object of three tracker points: the true probe reaches
    the work object's targets; the note gives how the points' errors move them, by hand."""
    table = true_table(np.random.default_rng(8))
    run = run_dir(tmp_path, table)
    W = TRACKER @ frames.transform(Rotation.from_rotvec([0, 0, 0.4]).as_matrix(), [0.9, -0.4, 0.3])
    points = np.array([W[:3, 3], W[:3, 3] + 0.5 * W[:3, 0], W[:3, 3] + 0.4 * W[:3, 1] + 0.1 * W[:3, 0]])
    (tmp_path / "wo.csv").write_text("point,x_mm,y_mm,z_mm\n" + "\n".join(
        f"{n},{float(p[0]) * 1e3!r},{float(p[1]) * 1e3!r},{float(p[2]) * 1e3!r}" for n, p in zip("YOX", points[[2, 0, 1]])) + "\n")  # fmt: skip
    q = program(np.random.default_rng(9))
    in_wo = np.array([(np.linalg.inv(W) @ TRACKER @ dh_fk(table, qk) @ PROBE)[:3, 3] for qk in q])
    c = zrp_ga.compensate(run, in_wo, kind="cartesian", work_object=tmp_path / "wo.csv", tool="calibration", q_seed=q[0])
    got = np.array([(np.linalg.inv(W) @ TRACKER @ dh_fk(table, qk) @ PROBE)[:3, 3] for qk in c.q])
    assert np.abs(got - in_wo).max() < 1e-9
    r, d = np.linalg.norm(in_wo, axis=1).max(), 0.4  # Y lies 0.4 m off the x axis, X 0.5 m from O
    k = np.sqrt(1 + 2 * (r / d) ** 2)
    note = next(n for n in c.summary()["notes"] if n.startswith("work object"))
    assert f"about {k:.3g} e (about {k * 0.02:.3g} mm for points measured as the calibration's" in note


def test_command_line_with_the_mount_in_the_programs_units(tmp_path, capsys):
    """zrp-ga-compensate with a KUKA program in mm and degrees and --probe-in-flange in the same
    units and convention (x, y, z, A, B, C): flange targets reached exactly by the true arm."""
    from zrp_ga.cli.compensate import main

    table = true_table(np.random.default_rng(6))
    run = run_dir(tmp_path, table)
    q = program(np.random.default_rng(10), 4)
    T = np.array([dh_fk(CELL, qk) for qk in q])
    abc = Rotation.from_matrix(T[:, :3, :3]).as_euler("ZYX", degrees=True)
    rows = [[*(t[:3, 3] * 1e3), *a, *np.degrees(qk)] for t, a, qk in zip(T, abc, q)]
    head = "x_mm,y_mm,z_mm,A_deg,B_deg,C_deg," + ",".join(f"q{i}_deg" for i in range(1, 7))
    (tmp_path / "prog.csv").write_text("\n".join([head, *(",".join(map(repr, map(float, r))) for r in rows)]) + "\n")
    mount = [*(PROBE[:3, 3] * 1e3), *Rotation.from_matrix(PROBE[:3, :3]).as_euler("ZYX", degrees=True)]
    code = main([str(run), str(tmp_path / "prog.csv"), "--probe-in-flange", ",".join(map(repr, map(float, mount))),
                 "-o", str(tmp_path / "out")])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0 and "compensated 4 of 4 poses" in out and "(mm, deg, ZYX)" in out
    import pandas as pd

    joints = pd.read_csv(tmp_path / "out" / "joints.csv")
    base = Rz(DELTA) @ Tz(EPS)
    for k in range(len(q)):
        got = np.linalg.inv(base) @ dh_fk(table, np.radians(joints.loc[k, [f"q{i}_deg" for i in range(1, 7)]].to_numpy(float)))
        assert np.linalg.norm(got[:3, 3] - T[k, :3, 3]) < 1e-8


def test_probe_targets_of_a_positions_only_run_name_the_probes_unknown_turn(tmp_path):
    """A positions-only run measured a point: its tool has no orientation, so probe poses in the
    tracker's frame with tool='calibration' are solved as if the probe were turned as the flange.
    The true probe (turned 21 deg in its mount) then misses the targets' orientation by that turn,
    by hand; compensation.json must name it (the note), and the mount given removes both."""
    table = true_table(np.random.default_rng(4))
    run = run_dir(tmp_path, table)
    summary = json.loads((run / "summary.json").read_text())
    summary["config"]["problem"]["use_orientation"] = False
    summary["calibrated_robot"]["tools"] = {"probe": frames.transform(np.eye(3), PROBE[:3, 3]).tolist()}  # a point
    (run / "summary.json").write_text(json.dumps(summary))
    q = program(np.random.default_rng(5))
    targets = np.array([TRACKER @ dh_fk(table, qk + 0.03) @ PROBE for qk in q])
    c = zrp_ga.compensate(run, targets, kind="cartesian", frame="instrument", tool="calibration", q_seed=q[0],
                          unreachable="keep")  # the flange turned as the probe is may lie beyond the limits
    turn = np.degrees(Rotation.from_matrix(PROBE[:3, :3]).magnitude())  # 21.4 deg
    assert np.isfinite(c.q[0]).all()
    got = TRACKER @ dh_fk(table, c.q[0]) @ PROBE
    assert abs(np.degrees(Rotation.from_matrix(got[:3, :3].T @ targets[0, :3, :3]).magnitude()) - turn) < 0.01
    note = next((n for n in c.summary()["notes"] if n.startswith("tool orientation")), None)
    assert note is not None and "the flange's" in note and "--probe-in-flange" in note
    given = zrp_ga.compensate(run, targets, kind="cartesian", frame="instrument", tool="calibration", q_seed=q[0],
                              probe_in_flange=PROBE)  # fmt: skip
    assert not any(n.startswith("tool orientation") for n in given.summary()["notes"])
    got = TRACKER @ dh_fk(table, given.q[0]) @ PROBE
    assert Rotation.from_matrix(got[:3, :3].T @ targets[0, :3, :3]).magnitude() < 1e-9
