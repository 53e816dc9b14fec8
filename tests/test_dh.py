"""to_dh and DHTable against the independent DH chain of tests/dh_reference.py."""

import numpy as np
import pytest
from dh_reference import dh_fk
from scipy.spatial.transform import Rotation

from zrp_ga import robots
from zrp_ga.io.robot_files import dh_to_yaml, read_dh, read_robot
from zrp_ga.model import kinematics
from zrp_ga.model.dh import DHTable, to_dh
from zrp_ga.model.robot import ZRPRobot


def reference_fk(table: DHTable, q):
    """base @ (DH or MDH chain of tests/dh_reference.py) @ tool."""
    rows = dict(d=table.d, a=table.a, alpha=table.alpha, offset=table.theta, joint_types=table.joint_types)
    return table.base @ dh_fk(rows, q, modified=table.convention == "mdh") @ table.tool


def random_q(robot, rng, M=20):
    limits = robot.joint_limits
    return rng.uniform(limits[:, 0], limits[:, 1], size=(M, robot.n))


def random_arm(rng, types):
    """An arm with random axes and body vectors: no two axes parallel."""
    n = len(types)
    return ZRPRobot(
        u0=rng.normal(size=(n, 3)), b0=rng.uniform(-0.4, 0.4, size=(n + 1, 3)),
        R_h0=Rotation.random(random_state=int(rng.integers(1000))).as_matrix(), joint_types=types, normalize=True,
    )


@pytest.mark.parametrize("name", robots.names())
def test_to_dh_recovers_the_preset_tables(name, rng):
    robot, published = robots.get(name), read_dh(robots.path(name))
    table, mismatch = to_dh(robot)
    for field in ("a", "alpha", "d", "theta"):
        np.testing.assert_allclose(getattr(table, field), getattr(published, field), atol=1e-12, err_msg=field)
    np.testing.assert_allclose(table.base, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(table.tool, np.eye(4), atol=1e-12)
    assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12 and mismatch.notes == ()
    assert table.joint_names == robot.joint_names and np.array_equal(table.limits, robot.limits)
    for q in random_q(robot, rng, 5):
        np.testing.assert_allclose(table.forward(q), reference_fk(published, q), atol=1e-12)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("name", robots.names())
def test_table_forward_kinematics_equal_the_zrp_model(name, convention, rng):
    robot = robots.get(name)
    table, mismatch = to_dh(robot, convention)
    assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12
    q = random_q(robot, rng)
    R, p = kinematics.forward(robot, q)
    for m in range(len(q)):
        T = reference_fk(table, q[m])
        np.testing.assert_allclose(T[:3, :3], R[m], atol=1e-12)
        np.testing.assert_allclose(T[:3, 3], p[m], atol=1e-12)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("types", ["RRRRRR", "RPRRPR", "PRR"])
def test_general_axes_admit_dh_exactly(types, convention, rng):
    robot = random_arm(rng, types)
    table, mismatch = to_dh(robot, convention)
    assert mismatch.position_m < 1e-12 and mismatch.orientation_rad < 1e-12 and mismatch.notes == ()
    q = random_q(robot, rng, 10)
    R, p = kinematics.forward(robot, q)
    for m in range(len(q)):
        np.testing.assert_allclose(reference_fk(table, q[m])[:3, 3], p[m], atol=1e-12)
    np.testing.assert_allclose(kinematics.forward(table.to_robot(), q)[1], p, atol=1e-12)


# --- calibrated arms: nearly parallel axes get Hayati rows ----------------------------------------
KR6 = dict(  # a KUKA KR 6 R900-like standard-DH table: axes 2 and 3 parallel, a2 = 0.455 m
    a=[0.025, 0.455, 0.035, 0.0, 0.0, 0.0], alpha=np.radians([-90, 0, 90, -90, 90, 0]),
    d=[0.4, 0.0, 0.0, 0.42, 0.0, 0.08], offset=[0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0], joint_types="RRRRRR",
)
SCARA = dict(  # axes 1, 2, 3 (prismatic, pointing down) and 4 all vertical
    a=[0.35, 0.3, 0.0, 0.0], alpha=[0.0, np.pi, 0.0, 0.0], d=[0.4, 0.0, 0.1, 0.05],
    offset=[0.0, 0.0, 0.0, 0.0], joint_types="RRPR", limits=[[-2.5, 2.5], [-2.5, 2.5], [0.0, 0.2], [-3.0, 3.0]],
)


def calibrated_like(table, rng, scale=1e-3):
    """The arm of a DH table with its axes tilted and its body vectors moved by about ``scale``."""
    arm = ZRPRobot.from_dh(**table)
    return arm.replace(u0=arm.u0 + rng.normal(scale=scale, size=arm.u0.shape),
                       b0=arm.b0 + rng.normal(scale=scale, size=arm.b0.shape), normalize=True)  # fmt: skip


def hayati_fk(table: DHTable, q):
    """base @ (the chain of tests/dh_reference.py, Hayati's beta included) @ tool."""
    rows = dict(d=table.d, a=table.a, alpha=table.alpha, offset=table.theta, beta=table.beta, joint_types=table.joint_types)
    return table.base @ dh_fk(rows, q, modified=table.convention == "mdh") @ table.tool


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize(("arm", "pairs"), [("kr6", [(2, 3)]), ("scara", [(1, 2), (2, 3), (3, 4)]), ("ur10", [(2, 3), (3, 4)])])
def test_calibrated_parallel_axes_give_exact_hayati_rows_of_the_arms_size(arm, pairs, convention, rng):
    for scale in (1e-5, 1e-4, 1e-3):  # calibrated axes: tilts of 0.001 to 0.1 degree
        robot = calibrated_like(KR6, rng, scale) if arm == "kr6" else calibrated_like(SCARA, rng, scale) if arm == "scara" else None
        if arm == "ur10":
            ur10 = robots.get("ur10")
            robot = ur10.replace(u0=ur10.u0 + rng.normal(scale=scale, size=(6, 3)), normalize=True)
        table, mismatch = to_dh(robot, convention)
        q = random_q(robot, rng, 50)
        R, p = kinematics.forward(robot, q)
        for m in range(len(q)):  # the table's chain, written in tests/dh_reference.py, is the arm
            T = hayati_fk(table, q[m])
            np.testing.assert_allclose(T[:3, 3], p[m], atol=1e-9)
            np.testing.assert_allclose(T[:3, :3], R[m], atol=1e-9)
        assert mismatch.position_m < 1e-9 and mismatch.orientation_rad < 1e-9
        size = np.linalg.norm(robot.b0, axis=1).sum()
        assert np.abs(table.a).max() < size and np.abs(table.d).max() < size  # no metre-scale offsets
        # the Hayati rows are those of the parallel pairs, each named in the notes
        rows = [i if convention == "dh" else j for i, j in pairs]
        assert list(np.flatnonzero(table.beta) + 1) == rows
        assert [note.split(" (")[0] for note in mismatch.notes] == [f"row {r}" for r in rows]
        assert all("Hayati's parameterisation" in note and f"axes {i} and {j} are" in note for note, (i, j) in zip(mismatch.notes, pairs))
        assert np.abs(table.beta).max() < 5 * scale + 1e-12


@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_hayati_tables_round_trip_through_the_file(tmp_path, convention, rng):
    robot = calibrated_like(SCARA, rng)
    table, _ = to_dh(robot, convention)
    path = tmp_path / "scara.yaml"
    dh_to_yaml(table, path, length="mm", angle="deg")
    assert "# Hayati row" in path.read_text() and "beta:" in path.read_text()
    back = read_dh(path)
    np.testing.assert_allclose(back.beta, table.beta, rtol=1e-14, atol=1e-17)
    q = random_q(robot, rng, 20)
    np.testing.assert_allclose(kinematics.forward(back.to_robot(), q)[1], kinematics.forward(robot, q)[1], atol=1e-12)


def test_a_hand_written_hayati_row_reads_as_the_reference_chain(tmp_path, rng):
    path = tmp_path / "two.yaml"
    path.write_text("convention: dh\nunits: {length: mm, angle: deg}\njoints:\n"
                    "  - {type: R, a: 300, alpha: 0.5, d: 0, theta: 10, beta: 1.5}\n"
                    "  - {type: R, a: 250, alpha: 0, d: 20}\n")  # fmt: skip
    rows = dict(a=[0.3, 0.25], alpha=np.radians([0.5, 0]), d=[0.0, 0.02], offset=np.radians([10, 0]),
                beta=np.radians([1.5, 0]), joint_types="RR")  # fmt: skip
    robot = read_robot(path)
    for q in rng.uniform(-3, 3, size=(10, 2)):
        R, p = kinematics.forward(robot, q)
        np.testing.assert_allclose(p, dh_fk(rows, q)[:3, 3], atol=1e-12)
        np.testing.assert_allclose(R, dh_fk(rows, q)[:3, :3], atol=1e-12)


def test_plain_dh_of_a_calibrated_kr6_would_put_the_common_normal_metres_away(rng):
    """Why Hayati: with the threshold at 0 and the arm's size unbounded, the plain table is exact too
    but its offsets are the far-away common normals."""
    robot = calibrated_like(KR6, rng)
    table, mismatch = to_dh(robot, parallel_tol=0.0, max_offset=np.inf)
    assert mismatch.position_m < 1e-9 and not table.beta.any()
    assert np.abs(table.d).max() > 10.0


def test_unknown_convention_is_refused():
    with pytest.raises(ValueError, match="convention: 'craig', expected one of dh, mdh"):
        to_dh(robots.get("puma560"), "craig")
