"""DH-parameter masks (``problem.fixed=[dh_theta_1, dh_d_3]`` for an arm read from a DH table
file): the genome is z with x = N z, N the null space of the fixed DH parameters' Jacobian.

The true arm is a DH table perturbed here in every parameter but the fixed ones, its poses come
from a DH chain written here (``Rz Tz Tx Rx Ry``), and the calibrated arm's table is compared
with the perturbed one; the fit is scipy's Levenberg-Marquardt on the problem's residual and
Jacobian (so that a wrong chain rule through N fails it)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import least_squares

import zrp_ga
from zrp_ga import robots
from zrp_ga.io.robot_files import read_robot
from zrp_ga.model import dh, simulation
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout, dh_mask
from zrp_ga.model.poses import Measurements

# PUMA 560, standard DH (Corke), m and deg
PUMA = dict(a=[0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0], alpha=[90, 0, -90, 90, -90, 0], d=[0.67183, 0.0, 0.15005, 0.4318, 0.0, 0.1],
            theta=[0, 0, 0, 0, 0, 0])  # fmt: skip
FIXED = ["dh_theta_1", "dh_d_3"]


def write_puma(path) -> None:
    rows = "\n".join(f"  - {{type: R, a: {a}, alpha: {al}, d: {d}, theta: {t}}}" for a, al, d, t in zip(*PUMA.values()))
    path.write_text(f"name: puma_file\nconvention: dh\nunits: {{length: m, angle: deg}}\njoints:\n{rows}\n")


def chain(a, alpha, d, theta, beta, q):
    """Hand poses (M, 4, 4) of a standard DH table with Hayati tilts, written out here."""
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    for i in range(len(a)):
        t = theta[i] + q[:, i]
        ct, st, ca, sa, cb, sb = np.cos(t), np.sin(t), np.cos(alpha[i]), np.sin(alpha[i]), np.cos(beta[i]), np.sin(beta[i])
        A = np.zeros((len(q), 4, 4))
        Rz = np.zeros((len(q), 3, 3))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = ct, -st, st, ct, 1.0
        Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
        A[:, :3, :3] = Rz @ Rx @ Ry
        A[:, :3, 3] = Rz @ np.array([a[i], 0.0, 0.0]) + np.array([0.0, 0.0, d[i]])
        A[:, 3, 3] = 1.0
        T = T @ A
    return T


def true_table(rng):
    """The PUMA table with every parameter moved by up to 1 mm / 1 mrad but theta_1 and d_3;
    rows 2-3 (parallel axes) tilt by Hayati's beta_2 (alpha_2 stays 0, d_2 0, as the DH reading
    of nearly parallel axes has them)."""
    a, d = np.array(PUMA["a"]), np.array(PUMA["d"])
    alpha, theta = np.radians(PUMA["alpha"]), np.radians(PUMA["theta"])
    beta = np.zeros(6)
    a = a + rng.uniform(-1e-3, 1e-3, 6)
    alpha = alpha + rng.uniform(-1e-3, 1e-3, 6) * (np.arange(6) != 1)
    d = d + rng.uniform(-1e-3, 1e-3, 6) * ~np.isin(np.arange(6), [1, 2])
    theta = theta + rng.uniform(-1e-3, 1e-3, 6) * (np.arange(6) != 0)
    beta[1] = 8e-4
    return a, alpha, d, theta, beta


def fit(problem):
    z = least_squares(problem.residual, np.zeros(problem.layout.size), jac=lambda z: -problem.jacobian(z), method="lm",
                      xtol=1e-15, ftol=1e-15, gtol=1e-15).x  # fmt: skip
    return problem.layout.robot(problem.nominal, z)


def test_fixed_dh_parameters_stay_and_the_free_ones_are_recovered(tmp_path):
    write_puma(tmp_path / "puma.yaml")
    nominal = read_robot(tmp_path / "puma.yaml")
    rng = np.random.default_rng(3)
    a, alpha, d, theta, beta = true_table(rng)
    q = rng.uniform(-np.pi, np.pi, (40, 6))
    T = chain(a, alpha, d, theta, beta, q)
    data = Measurements(q=q, p=T[:, :3, 3], R=T[:, :3, :3], source="test")
    layout = dh_mask(Layout(6, hand=True), nominal, "dh", FIXED)
    assert layout.size == 6 * 6 + 3 - 2 - 5 and layout.blocks == {"z": slice(0, layout.size)}  # less 2 DH, 5 slides (axes 2..6)
    problem = CalibrationProblem(nominal, data, layout, -np.ones(layout.size), np.ones(layout.size), cost="nonlinear")
    arm = fit(problem)

    base_x = [1.0, 0.0, 0.0]
    want = {f"dh_{k}_{i + 1}": v[i] for k, v in zip(dh.DH_KINDS, (a, alpha, d, theta, beta)) for i in range(6)}
    got, start = dh.parameters(arm, "dh", base_x), dh.parameters(nominal, "dh", base_x)
    for name in FIXED:  # held to first order: second-order small
        assert abs(got[name] - start[name]) < 2e-6, (name, got[name] - start[name])
    moved = [k for k in want if k not in FIXED and k != "dh_theta_6" and abs(want[k] - start[k]) > 1e-4]
    assert len(moved) > 15
    for name in moved:  # recovered (the data leave them only second-order errors)
        assert abs(got[name] - want[name]) < 2e-5 * max(1.0, abs(want[name])), (name, got[name], want[name])
    R, p = zrp_ga.model.kinematics.forward(arm, q)
    assert np.abs(p - data.p).max() < 1e-5


def test_the_basis_spans_the_null_space_of_finite_differences(tmp_path):
    write_puma(tmp_path / "puma.yaml")
    nominal = read_robot(tmp_path / "puma.yaml")
    layout = dh_mask(Layout(6), nominal, "dh", FIXED)
    full, h, base_x = layout.unmasked, 1e-6, [1.0, 0.0, 0.0]
    rng = np.random.default_rng(0)
    for _ in range(3):  # along a genome direction the fixed parameters do not move to first order
        v = layout.matrix @ rng.normal(size=layout.size)
        up, down = (dh.parameters(full.robot(nominal, s * h * v), "dh", base_x) for s in (1, -1))
        assert all(abs(up[k] - down[k]) / (2 * h) < 1e-6 for k in FIXED)
    v = rng.normal(size=full.size)  # a generic direction does move them
    up, down = (dh.parameters(full.robot(nominal, s * h * v), "dh", base_x) for s in (1, -1))
    assert max(abs(up[k] - down[k]) / (2 * h) for k in FIXED) > 1e-2
    np.testing.assert_allclose(layout.matrix.T @ layout.matrix, np.eye(layout.size), atol=1e-12)
    z = rng.normal(size=layout.size) * 1e-6
    arm = layout.robot(nominal, z)  # pack inverts robot up to the axes' lengths (normalised away)
    back = layout.robot(nominal, layout.pack(nominal, arm))
    np.testing.assert_allclose(np.vstack([back.u0, back.b0, back.R_h0]), np.vstack([arm.u0, arm.b0, arm.R_h0]), atol=1e-12)
    with pytest.raises(ValueError, match="outside the genome's subspace"):
        layout.pack(nominal, full.robot(nominal, 1e-4 * v))


def test_summary_reports_the_fixed_dh_parameters_change(tmp_path):
    write_puma(tmp_path / "puma.yaml")
    cal = zrp_ga.calibrate(
        tmp_path / "puma.yaml", algorithm="lm", problem={"n_poses": 20, "cost": "nonlinear", "fixed": "[dh_theta_1,dh_d_3,u0_4]"}
    )
    summary = cal.summary
    assert summary["problem"]["fixed"] == ["u0_4", "dh_theta_1", "dh_d_3"]
    change = summary["dh_fixed_change"]
    assert set(change) == set(FIXED) and all(abs(v) < 1e-4 for v in change.values())
    assert np.array_equal(cal.robot.u0[3], read_robot(tmp_path / "puma.yaml").u0[3])


@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_bad_dh_names_are_refused(tmp_path):
    write_puma(tmp_path / "puma.yaml")
    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", f"robot.file={tmp_path / 'puma.yaml'}", "problem.fixed=[dh_theta_9]",
                           f"hydra.run.dir={tmp_path}/run", "progress=false"], capture_output=True, text=True, cwd=tmp_path)  # fmt: skip
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "problem.fixed: 'dh_theta_9' is not a DH parameter of this arm" in lines[0]
    zrp = tmp_path / "zrp.yaml"
    read_robot(tmp_path / "puma.yaml").to_yaml(zrp)  # the same arm as a ZRP file: no DH table
    with pytest.raises(ValueError, match="'dh_d_3' names a DH parameter, but the arm .* was not read from a DH table file"):
        zrp_ga.calibrate(zrp, algorithm="lm", problem={"fixed": "[dh_d_3]"})
    with pytest.raises(ValueError, match="problem.free: 'dh_d_3': DH parameters are named in problem.fixed only"):
        zrp_ga.calibrate(tmp_path / "puma.yaml", algorithm="lm", problem={"free": "[dh_d_3]"})
    robot = robots.get("puma560")  # a measured problem: not supported, said so
    rng = np.random.default_rng(1)
    data = simulation.measure(robot, simulation.random_joints(robot, 12, rng), rng, position_only=True)
    with pytest.raises(ValueError, match="'dh_d_3': DH parameters can be fixed in simulated problems only"):
        zrp_ga.calibrate(robot, data, algorithm="lm", problem={"fixed": "[dh_d_3]"})
    with pytest.raises(ValueError, match="dh_theta_6 is not a smooth function"):
        zrp_ga.calibrate("puma560", algorithm="lm", problem={"fixed": "[dh_theta_6]"})
