"""A calibration you keep (zrp_ga.run.calibration): saved, loaded, exported, predicting; and
zrp_ga.simulate's measurement files. Every number is checked against a chain written here (plain
numpy: Rodrigues' ZRP product, the standard DH product), a library's reading of the file
(yourdfpy, xacro) or finite differences."""

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import robots


# --- chains written here -----------------------------------------------------------------------
def rodrigues(u, q):
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(q) * K + (1 - np.cos(q)) * K @ K


def zrp_chain(d: dict, q: np.ndarray):
    """The ZRP file's arm (u0, b0, R_h0, joint types as written) at joint values q (n,):
    p = sum_i R_{i-1} b0_i (+ q_i u_i for prismatic), R = R_n R_h0."""
    u0, b0, Rh = np.array(d["u0"]), np.array(d["b0"]), np.array(d["R_h0"])
    R, p = np.eye(3), b0[0].copy()
    for i, t in enumerate(d["joint_types"]):
        if t == "P":
            p = p + q[i] * (R @ u0[i])
        else:
            R = R @ rodrigues(u0[i], q[i])
        p = p + R @ b0[i + 1]
    return R @ Rh, p


def dh_chain(d: dict, q: np.ndarray) -> np.ndarray:
    """A standard-DH table file (m and deg, or as its units say) at q: base, Rz(theta + q) Tz(d)
    Tx(a) Rx(alpha) [Ry(beta): a Hayati row] per joint, tool."""
    units = d.get("units") or {}
    L = {"m": 1.0, "mm": 1e-3}[units.get("length", "m")]
    A = {"deg": np.pi / 180, "rad": 1.0}[units.get("angle", "deg")]

    def rot(axis, a):
        return np.block([[Rotation.from_euler(axis, a).as_matrix(), np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]])

    def trans(v):
        T = np.eye(4)
        T[:3, 3] = v
        return T

    def pose(entry):
        if entry is None:
            return np.eye(4)
        if "matrix" in entry:
            T = np.array(entry["matrix"], dtype=float)
            T[:3, 3] *= L
            return T
        T = trans(np.array(entry.get("xyz", [0, 0, 0]), dtype=float) * L)
        return T @ rot("xyz", np.array(entry.get("rpy", [0, 0, 0]), dtype=float) * A)

    T = pose(d.get("base"))
    for i, j in enumerate(d["joints"]):
        theta = j.get("theta", 0) * A + (q[i] if j.get("type", "R") == "R" else 0.0)
        dd = j.get("d", 0) * L + (q[i] if j.get("type") == "P" else 0.0)
        T = T @ rot("z", theta) @ trans([0, 0, dd]) @ trans([j.get("a", 0) * L, 0, 0]) @ rot("x", j.get("alpha", 0) * A)
        if j.get("beta"):
            T = T @ rot("y", j["beta"] * A)
    return T @ pose(d.get("tool"))


@pytest.fixture(scope="module")
def puma_run(tmp_path_factory):
    """A PUMA 560 calibrated by LM on the simulated 30-pose problem, written by the run itself."""
    out = tmp_path_factory.mktemp("puma") / "run"
    cal = zrp_ga.calibrate("puma560", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm", out=out)
    return cal, out


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    """A measured cell: a PUMA 560 seen by a tracker 2 m away, a probe 0.1 m off the flange,
    positions and ZYX orientations in mm and degrees, calibrated by LM (in memory)."""
    root = tmp_path_factory.mktemp("cell")
    base = np.eye(4)
    base[:3, :3] = Rotation.from_rotvec([0.1, -0.2, 0.7]).as_matrix()
    base[:3, 3] = [2.0, -0.5, 0.3]
    probe = np.eye(4)
    probe[:3, 3] = [0.02, -0.01, 0.1]
    sim = zrp_ga.simulate("puma560", 60, 30, tool=probe, base=base, noise={"position_m": 2e-5, "orientation_rad": 1e-4},
                          units="mm,deg", orientation="ZYX", seed=3, out=root / "data")  # fmt: skip
    cal = zrp_ga.calibrate("puma560", sim.files["calibration"], validation=sim.files["validation"], algorithm="lm",
                           problem=sim.settings)  # fmt: skip
    return sim, cal, root


# --- save, load, predict ------------------------------------------------------------------------
def test_save_load_predict_equals_the_calibration_in_memory(puma_run, tmp_path, rng):
    cal, _ = puma_run
    back = zrp_ga.load(cal.save(tmp_path / "kept"))
    assert back.task is None and back.result is None
    q = rng.uniform(-1.5, 1.5, (25, 6))
    a, b = cal.predict(q), back.predict(q)
    np.testing.assert_allclose(b.p, a.p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.R, a.R, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.position_mm, a.position_mm, rtol=1e-9)
    np.testing.assert_allclose(b.orientation_mrad, a.orientation_mrad, rtol=1e-9)
    assert np.array_equal(b.outside, a.outside) and np.allclose(b.distance_ratio, a.distance_ratio, rtol=1e-12)
    assert back.summary["final_cost"] == cal.summary["final_cost"]
    pd.testing.assert_frame_equal(back.history[["gen", "nevals", "best"]], cal.history[["gen", "nevals", "best"]])
    # a directory holding another run is refused (saving where it already is: nothing to do); a loaded one copies it
    with pytest.raises(ValueError, match="already holds a run"):
        cal.save(puma_run[1])
    assert cal.save(tmp_path / "kept") == tmp_path / "kept"
    again = zrp_ga.load(back.save(tmp_path / "copy"))
    np.testing.assert_array_equal(again.predict(q).p, b.p)


@pytest.mark.parametrize("which", ["puma_run", "cell"])
def test_predicted_sigma_is_the_covariance_through_a_finite_difference_jacobian(which, request, rng):
    """The 1-sigma radius at the hand: sqrt(tr(J C J^T)) with J the central finite differences
    of the hand position over the full genome (the arm rebuilt from each perturbed genome; in the
    measured cell the hand is a rigid point 0.1 m from the measured probe, whose arm the genome
    describes), C the covariance (identified and left at nominal)."""
    fixture = request.getfixturevalue(which)
    cal = fixture[0] if which == "puma_run" else fixture[1]
    u = cal.uncertainty
    q = rng.uniform(-1.0, 1.0, (4, 6))
    C = u.cov_factor @ u.cov_factor.T + u.prior_factor @ u.prior_factor.T
    B = np.eye(4) if cal.base is None else cal.base
    h = 1e-7
    expected = []
    for qq in q:
        R0, p0 = zrp_chain(u.robot(0).to_dict(), qq)  # the measured point (the hand without a probe)
        _, ph = zrp_chain(cal.arm.to_dict(), qq)  # the hand, in the base frame
        c = R0.T @ (B[:3, :3] @ ph + B[:3, 3] - p0)  # the hand from the measured point, in the hand frame
        J = np.zeros((3, u.x.size))
        for k in range(u.x.size):
            e = np.zeros(u.x.size)
            e[k] = h
            (Ra, pa), (Rb, pb) = (zrp_chain(u.layout.robot(u.nominal, u.x + s * e).to_dict(), qq) for s in (1, -1))
            J[:, k] = ((pa + Ra @ c) - (pb + Rb @ c)) / (2 * h)
        expected.append(np.sqrt(np.trace(J @ C @ J.T)) * 1e3)
    np.testing.assert_allclose(cal.predict(q, tool="hand").position_mm, expected, rtol=1e-5)


def test_a_run_directory_loaded_has_the_forward_kinematics_of_its_own_files(puma_run, rng):
    """``zrp_ga.load`` on what ``zrp-ga`` wrote: its forward kinematics is the ZRP file's chain
    and the DH file's chain (both written here), to round-off."""
    _, out = puma_run
    back = zrp_ga.load(out)
    zrp, dh = (yaml.safe_load((out / f).read_text()) for f in ("calibrated_robot.yaml", "calibrated_robot_dh.yaml"))
    q = rng.uniform(-2, 2, (10, 6))
    pr = back.predict(q, tool="hand", frame="base")
    for m in range(len(q)):
        R, p = zrp_chain(zrp, q[m])
        np.testing.assert_allclose(pr.p[m], p, atol=1e-12)
        np.testing.assert_allclose(pr.R[m], R, atol=1e-12)
        T = dh_chain(dh, q[m])
        np.testing.assert_allclose(pr.p[m], T[:3, 3], atol=1e-9)  # the DH file: 1e-12 mm mismatch, decimal text
        np.testing.assert_allclose(pr.R[m], T[:3, :3], atol=1e-9)
    assert back.predict(q).position_mm is not None and (back.predict(q).position_mm < 1.0).all()


def test_a_measured_calibration_predicts_what_the_tracker_sees(cell, tmp_path, rng):
    """In the instrument's frame at the probe, the calibrated arm is the true one (the chain
    written here, through the tracker's pose and the probe) to well within a tenth of a mm; in
    the base frame at the hand, the same point through the calibration's base and probe; save
    and load keep it."""
    sim, cal, _ = cell
    q = rng.uniform(-1.0, 1.0, (15, 6))
    pr = cal.predict(q)
    truth = [zrp_chain(sim.truth.to_dict(), qq) for qq in q]
    B, t = sim.base, sim.tools[""][:3, 3]
    seen = np.array([B[:3, :3] @ (p + R @ t) + B[:3, 3] for R, p in truth])
    err_mm = np.linalg.norm(pr.p - seen, axis=1) * 1e3
    assert err_mm.max() < 0.1 and (pr.position_mm > 0).all()
    hand = cal.predict(q, tool="hand", frame="base")
    Bc, tc = cal.base, next(iter(cal.tools.values()))[:3, 3]
    np.testing.assert_allclose((hand.p + hand.R @ tc) @ Bc[:3, :3].T + Bc[:3, 3], pr.p, atol=1e-12)
    back = zrp_ga.load(cal.save(tmp_path / "cell"))
    np.testing.assert_allclose(back.predict(q).p, pr.p, atol=1e-12)
    np.testing.assert_allclose(back.predict(q).position_mm, pr.position_mm, rtol=1e-9)
    np.testing.assert_allclose(back.predict(q, tool="hand").position_mm, cal.predict(q, tool="hand").position_mm, rtol=1e-9)


def test_load_refuses_what_is_not_a_run(puma_run, tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="not a calibration run directory"):
        zrp_ga.load(tmp_path / "empty")
    with pytest.raises(ValueError, match="not a directory"):
        zrp_ga.load(tmp_path / "nothing")
    import shutil

    shutil.copytree(puma_run[1], tmp_path / "sweep" / "0")
    with pytest.raises(ValueError, match=r"a sweep directory\? give one of its jobs"):
        zrp_ga.load(tmp_path / "sweep")
    rows = (tmp_path / "sweep" / "0" / "convergence.csv").read_text().splitlines(keepends=True)
    (tmp_path / "sweep" / "0" / "convergence.csv").write_text("".join(rows[:-1]))
    with pytest.raises(ValueError, match="not a finished run: .*convergence.csv ends before the run did"):
        zrp_ga.load(tmp_path / "sweep" / "0")


# --- exports ---------------------------------------------------------------------------------------
def test_exports_read_back_by_yourdfpy_and_as_tables(puma_run, tmp_path, rng):
    yourdfpy = pytest.importorskip("yourdfpy")
    cal, _ = puma_run
    back = zrp_ga.load(puma_run[1])
    for c, where in ((cal, "in memory"), (back, "loaded")):
        d = tmp_path / where.replace(" ", "_")
        paths = c.export(urdf=d / "arm.urdf", dh=d / "arm_dh.yaml", mdh=d / "arm_mdh.yaml", zrp=d / "arm.yaml")
        run = puma_run[1]  # the run's own files, in the nominal table's conventions: the same, but for their names
        for kind in ("dh", "mdh"):
            own = (run / f"calibrated_robot_{kind}.yaml").read_text()
            assert paths[kind].read_text() == own.replace(f"calibrated_robot_{kind}_corrections", f"arm_{kind}_corrections")
            assert paths[f"{kind}_corrections"].read_text() == (run / f"calibrated_robot_{kind}_corrections.csv").read_text()
        assert paths["urdf"].read_text() == (run / "calibrated_robot.urdf").read_text()
        urdf = yourdfpy.URDF.load(str(paths["urdf"]), build_scene_graph=True, load_meshes=False)
        dh = yaml.safe_load(paths["dh"].read_text())
        q = rng.uniform(-2, 2, (6, 6))
        pr = c.predict(q, tool="hand", frame="base")
        for m in range(len(q)):
            urdf.update_cfg(dict(zip(urdf.actuated_joint_names, q[m])))
            T = urdf.get_transform(_tip(urdf), urdf.base_link)
            np.testing.assert_allclose(T[:3, 3], pr.p[m], atol=1e-12, err_msg=where)
            np.testing.assert_allclose(dh_chain(dh, q[m])[:3, 3], pr.p[m], atol=1e-9, err_msg=where)
    with pytest.raises(ValueError, match="not a Universal Robots arm"):
        cal.export(ur=tmp_path / "ur.yaml")


def _tip(urdf) -> str:
    """The URDF's one leaf link."""
    parents = {j.parent for j in urdf.robot.joints}
    leaves = [link.name for link in urdf.robot.links if link.name not in parents]
    assert len(leaves) == 1, leaves
    return leaves[0]


def test_a_calibrated_ur10_exported_as_default_kinematics_is_read_back_by_ur_description(tmp_path, rng):
    pytest.importorskip("yourdfpy")
    pytest.importorskip("xacro")
    from ur_description_reference import ur_description_urdf

    from zrp_ga.io import ros_calibration

    cal = zrp_ga.calibrate("ur10", problem={"n_poses": 30, "cost": "nonlinear"}, algorithm="lm")
    back = zrp_ga.load(cal.save(tmp_path / "run"))
    path = back.export(ur=tmp_path / "default_kinematics.yaml")["ur"]
    urdf = ur_description_urdf(tmp_path, path)
    k = ros_calibration.ur_kinematics(back.arm)
    q = rng.uniform(-np.pi, np.pi, (10, 6))
    pr = back.predict(q, tool="hand", frame="base")
    for m in range(len(q)):
        urdf.update_cfg(dict(zip(ros_calibration.UR_JOINTS, q[m])))
        T = urdf.get_transform(frame_to="tool0", frame_from="base_link_inertia") @ k.tcp
        np.testing.assert_allclose(T[:3, 3], pr.p[m], atol=1e-12)
        np.testing.assert_allclose(T[:3, :3], pr.R[m], atol=1e-12)


# --- simulate ---------------------------------------------------------------------------------------
def test_simulated_files_are_the_true_arm_plus_the_stated_noise(tmp_path):
    """Read back with pandas: positions (mm) and ZYX angles (deg) against the truth's chain
    written here, through the base and the tools; the residuals' mean and spread are the noise's."""
    base = np.eye(4)
    base[:3, :3] = Rotation.from_rotvec([0.0, 0.3, 1.0]).as_matrix()
    base[:3, 3] = [1.5, 0.2, -0.4]
    tools = {"A": [0.05, 0.0, 0.1], "B": [-0.05, 0.02, 0.1]}
    sd = 5e-5
    sim = zrp_ga.simulate("puma560", 400, 10, tool=tools, base=base, noise=sd, units="mm,deg", orientation="ZYX",
                          std=True, seed=7, out=tmp_path)  # fmt: skip
    f = pd.read_csv(sim.files["calibration"])
    assert list(f.columns) == [*(f"q{i}" for i in range(1, 7)), "x", "y", "z", "rx", "ry", "rz", "sx", "sy", "sz", "tool"]
    assert len(f) == 800 and list(f["tool"][:4]) == ["A", "B", "A", "B"]
    truth = yaml.safe_load(sim.files["truth"].read_text())
    q = np.radians(f[[f"q{i}" for i in range(1, 7)]].to_numpy())
    res, turn = [], []
    for k, row in f.iterrows():
        R, p = zrp_chain(truth, q[k])
        expect = base[:3, :3] @ (p + R @ np.array(tools[row["tool"]])) + base[:3, 3]
        res.append(row[["x", "y", "z"]].to_numpy(float) * 1e-3 - expect)
        R_file = Rotation.from_euler("ZYX", row[["rx", "ry", "rz"]].to_numpy(float), degrees=True).as_matrix()
        turn.append(np.linalg.norm(Rotation.from_matrix(R_file.T @ base[:3, :3] @ R).as_rotvec()))
    res = np.array(res)
    assert np.max(turn) < 1e-12  # no orientation noise stated
    assert np.abs(res.mean(axis=0)).max() < 4 * sd / np.sqrt(len(res))
    np.testing.assert_allclose(res.std(axis=0, ddof=1), sd, rtol=0.15)
    np.testing.assert_allclose(f[["sx", "sy", "sz"]].to_numpy(), sd * 1e3)
    # the truth differs from the nominal arm by the default errors: up to 1 mrad, 0.5 mm
    nominal = robots.get("puma560")
    assert 0 < np.abs(np.array(truth["b0"])[1:] - nominal.b0[1:]).max() <= 5e-4
    # and the files are what zrp-ga reads: the settings in simulation.json
    assert sim.overrides[0] == "problem=measured" and "problem.length_unit=mm" in sim.overrides


def test_simulated_files_calibrate_to_the_truth(cell):
    sim, cal, _ = cell
    v = cal.summary["validation_rms_mm"]
    assert v["calibrated"] < 0.1 < v["nominal"]


def test_simulate_refuses_bad_settings_in_one_line():
    with pytest.raises(ValueError, match="units 'cm,deg'"):
        zrp_ga.simulate("puma560", units="cm,deg")
    with pytest.raises(ValueError, match="noise: unknown key"):
        zrp_ga.simulate("puma560", noise={"position": 1e-5})
    with pytest.raises(ValueError, match="tool: an offset"):
        zrp_ga.simulate("puma560", tool=[1.0, 2.0])


def test_simulated_files_read_by_zrp_ga_give_the_calibration_calibrate_gives(cell, tmp_path, rng):
    """The overrides ``simulate`` states, run as ``zrp-ga`` runs them (config composed by Hydra,
    the run layer writing its directory): loaded, the same calibration as ``calibrate`` on the
    same files (LM: deterministic)."""
    from zrp_ga import config
    from zrp_ga.run import execute

    sim, cal, _ = cell
    over = ["robot=puma560", "algorithm=lm", "progress=false", *sim.overrides]
    execute.run(config.load(over), tmp_path / "run")
    back = zrp_ga.load(tmp_path / "run")
    q = rng.uniform(-1.0, 1.0, (10, 6))
    np.testing.assert_allclose(back.predict(q).p, cal.predict(q).p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.predict(q).position_mm, cal.predict(q).position_mm, rtol=1e-9)


def test_plot_without_a_convergence_history_says_so():
    """A calibration without its convergence history (loaded from files without
    ``convergence.csv``) cannot be plotted: one ValueError naming what is missing."""
    from zrp_ga.io import presets
    from zrp_ga.run.calibration import Calibration

    arm = presets.get("puma560")
    with pytest.raises(ValueError, match=r"^plot: this calibration has no convergence history"):
        Calibration(arm, {"instance": "puma560"}, arm).plot()
