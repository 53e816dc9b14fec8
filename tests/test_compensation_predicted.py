"""How sure a compensation is, per row (zrp_ga.compensation.result.predicted): the predicted
1-sigma error at the program's point from the calibration's covariance, checked against the
covariance carried through a finite-difference Jacobian of that point (the arm rebuilt from each
perturbed genome, its chain written here), and where the corrected joints lie against the
calibration poses, checked against a brute-force nearest-pose search and the file's ranges."""

import json

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga.model.uncertainty import Uncertainty

LIMIT = np.radians([60, 60, 60, 120, 60, 120])  # the calibration poses' joints within +-LIMIT


def rodrigues(u, q):
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(q) * K + (1 - np.cos(q)) * K @ K


def chain(d: dict, q):
    """The ZRP arm of a YAML/dict (revolute joints): R = R_n R_h0, p = sum R_{i-1} b0_i."""
    u0, b0 = np.array(d["u0"]), np.array(d["b0"])
    R, p = np.eye(3), b0[0].copy()
    for i in range(len(u0)):
        R = R @ rodrigues(u0[i], q[i])
        p = p + R @ b0[i + 1]
    return R @ np.array(d["R_h0"]), p


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A PUMA 560 in a tracker's frame, probe 0.1 m off the flange, positions only, calibrated
    by LM on poses within +-LIMIT (a restricted cell) and written as zrp-ga writes a run."""
    root = tmp_path_factory.mktemp("predicted")
    base = np.eye(4)
    base[:3, :3] = Rotation.from_rotvec([0.2, 0.1, -0.6]).as_matrix()
    base[:3, 3] = [2.0, 0.5, -0.2]
    rng = np.random.default_rng(5)
    q_cal = rng.uniform(-LIMIT, LIMIT, (60, 6))
    sim = zrp_ga.simulate("puma560", q=q_cal, q_validation=rng.uniform(-LIMIT, LIMIT, (20, 6)), tool=[0.03, 0.0, 0.1],
                          base=base, noise=3e-5, units="mm,deg", seed=2, out=root / "data")  # fmt: skip
    zrp_ga.calibrate("puma560", sim.files["calibration"], validation=sim.files["validation"], algorithm="lm",
                     problem=sim.settings, out=root / "run")  # fmt: skip
    return root / "run", sim


def program(rng, M=8):
    """Joint targets, half inside the calibrated cell, half with joint 1 beyond it."""
    q = rng.uniform(-0.8 * LIMIT, 0.8 * LIMIT, (M, 6))
    q[:, 4] = np.where(np.abs(q[:, 4]) < 0.3, 0.5, q[:, 4])  # off the wrist singularity
    q[M // 2 :, 0] = np.radians([75, 90, -80, 100][: M - M // 2])
    return q


def test_per_row_sigma_is_the_covariance_through_a_finite_difference_jacobian(run, tmp_path):
    """At the flange (the program's point, 0.1 m from the measured probe): sqrt(tr(J C J^T)) for
    position and orientation, J by central differences of the rigid flange point and the hand
    rotation over the full genome, C the run's covariance (identified and left at nominal)."""
    out, _ = run
    q = program(np.random.default_rng(1))
    zrp_ga.compensate(out, q, kind="joints", out=tmp_path / "comp")
    table = pd.read_csv(tmp_path / "comp" / "joints.csv")
    assert {"sigma_mm", "sigma_deg", "outside", "distance_ratio", "beyond_range_deg"} <= set(table.columns)
    qc = table[[f"q{i}_rad" for i in range(1, 7)]].to_numpy()
    u = Uncertainty.read(out)
    C = u.cov_factor @ u.cov_factor.T + u.prior_factor @ u.prior_factor.T
    summary = json.loads((out / "summary.json").read_text())
    B = np.array(summary["calibrated_robot"]["base"])
    arm = json.loads(json.dumps(__import__("yaml").safe_load((out / "calibrated_robot.yaml").read_text())))
    h = 1e-7
    for m in range(len(qc)):
        R0, p0 = chain(u.robot(0).to_dict(), qc[m])  # the measured probe, the model's (tracker's) frame
        Rf, pf = chain(arm, qc[m])  # the flange, the base frame
        c = R0.T @ (B[:3, :3] @ pf + B[:3, 3] - p0)  # the flange from the probe, in the hand frame
        Jp, Jr = np.zeros((3, u.x.size)), np.zeros((3, u.x.size))
        for k in range(u.x.size):
            e = np.zeros(u.x.size)
            e[k] = h
            (Ra, pa), (Rb, pb) = (chain(u.layout.robot(u.nominal, u.x + s * e).to_dict(), qc[m]) for s in (1, -1))
            Jp[:, k] = ((pa + Ra @ c) - (pb + Rb @ c)) / (2 * h)
            Jr[:, k] = Rotation.from_matrix(Ra @ Rb.T).as_rotvec() / (2 * h)
        assert table["sigma_mm"][m] == pytest.approx(np.sqrt(np.trace(Jp @ C @ Jp.T)) * 1e3, rel=1e-4)
        assert table["sigma_deg"][m] == pytest.approx(np.degrees(np.sqrt(np.trace(Jr @ C @ Jr.T))), rel=1e-4)
    # the probe's own point (tool="calibration") has the run's own prediction there (no lever arm)
    at_probe = zrp_ga.compensate(out, q, kind="joints", tool="calibration")
    np.testing.assert_allclose(at_probe.predicted["sigma_mm"], u.predict(at_probe.q)["position_total_m"] * 1e3, rtol=1e-6)
    summary = json.loads((tmp_path / "comp" / "compensation.json").read_text())
    assert set(summary["predicted"]["columns"]) >= {"sigma_mm", "outside"}
    assert summary["predicted"]["share_outside"] == pytest.approx(table["outside"].mean())


def test_per_row_coverage_is_the_distance_to_the_calibration_poses(run, tmp_path):
    """Outside the calibrated joint ranges by as much as the corrected joints say (the ranges of
    the calibration file's joints), and the nearest calibration pose by a brute-force search."""
    out, sim = run
    q = program(np.random.default_rng(2))
    c = zrp_ga.compensate(out, q, kind="joints", out=tmp_path / "comp")
    table = pd.read_csv(tmp_path / "comp" / "joints.csv")
    qc = table[[f"q{i}_rad" for i in range(1, 7)]].to_numpy()
    qf = np.radians(pd.read_csv(sim.files["calibration"])[[f"q{i}" for i in range(1, 7)]].to_numpy())
    lo, hi = qf.min(axis=0), qf.max(axis=0)
    excess = np.degrees(np.maximum(lo - qc, 0) + np.maximum(qc - hi, 0)).max(axis=1)
    np.testing.assert_allclose(table["beyond_range_deg"], excess, rtol=1e-9, atol=1e-9)
    near = np.linalg.norm(qc[:, None, :] - qf[None, :, :], axis=2).min(axis=1)
    d = np.linalg.norm(qf[:, None, :] - qf[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    np.testing.assert_allclose(table["distance_ratio"], near / d.min(axis=1).max(), rtol=1e-9)
    assert table["outside"].tolist() == [bool(x) for x in (excess > 1e-9) | (near / d.min(axis=1).max() > 1)]
    assert table["outside"][4:].all() and (table["beyond_range_deg"][4:] > 10).all()
    # beyond the cell the predicted error grows
    assert table["sigma_mm"][4:].mean() > table["sigma_mm"][:4].mean()
    assert np.array_equal(c.predicted["outside"], table["outside"].to_numpy())


def test_the_calibration_object_and_its_directory_give_the_same_rows(run, tmp_path):
    out, _ = run
    q = program(np.random.default_rng(3))
    from_dir = zrp_ga.compensate(out, q, kind="joints")
    from_object = zrp_ga.compensate(zrp_ga.load(out), q, kind="joints")
    for k, v in from_dir.predicted.items():
        np.testing.assert_allclose(from_object.predicted[k], v, rtol=1e-12, err_msg=k)


def test_a_robot_file_alone_has_no_such_columns_and_says_why(run, tmp_path):
    out, _ = run
    q = program(np.random.default_rng(4), 2)
    alone = tmp_path / "arm.yaml"
    alone.write_text((out / "calibrated_robot.yaml").read_text())
    c = zrp_ga.compensate(alone, q, kind="joints", nominal="puma560", out=tmp_path / "c")
    assert c.predicted == {}
    assert "sigma_mm" not in pd.read_csv(tmp_path / "c" / "joints.csv").columns
    assert "carries no covariance" in json.loads((tmp_path / "c" / "compensation.json").read_text())["predicted"]["why_not"]


def test_the_command_line_says_how_sure_the_rows_are(run, tmp_path, capsys):
    from zrp_ga.cli.compensate import main

    out, _ = run
    q = program(np.random.default_rng(6), 4)
    prog = tmp_path / "prog.csv"
    pd.DataFrame({f"q{i + 1}_deg": np.degrees(q[:, i]) for i in range(6)}).to_csv(prog, index=False)
    assert main([str(out), str(prog), "-o", str(tmp_path / "c")]) == 0
    said = capsys.readouterr().out
    table = pd.read_csv(tmp_path / "c" / "joints.csv")
    assert f"RMS {np.sqrt(np.mean(table['sigma_mm'] ** 2)):.3g} mm" in said
    assert "50% of the rows outside the calibration poses' region" in said
