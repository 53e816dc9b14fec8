"""Measured data: registration in a foreign frame, calibration there with one or several tool
points, validation in the same frame, in a moved frame or with a known other tool point, the
calibrated arm out as robot files, data-derived gene ranges, the nominal arm kept when a result
is worse, and bad input refused in one line before any work."""

import json
import sys

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.spatial.transform import Rotation
from urdf_reference import urdf_fk

from zrp_ga import config, robots
from zrp_ga.cli import main as cli_main
from zrp_ga.io import robot_files
from zrp_ga.model import error_model, kinematics, metrics, registration
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.model.simulation import random_joints, simulate
from zrp_ga.problems.measured import gene_half_widths
from zrp_ga.run import build, execute

NOISE = 5e-5  # m, standard deviation per axis of the simulated tracker
TOOL = np.array([0.012, -0.02, 0.105])
TOOLS = {"A": np.array([0.06, 0.0, 0.03]), "B": np.array([-0.03, 0.052, 0.03]), "C": np.array([-0.03, -0.052, 0.03])}
FRAME = (Rotation.from_rotvec([0.3, -1.2, 2.0]).as_matrix(), np.array([0.4, -3.2, -0.9]))


def _true_arm(rng, kinematic_errors=True, axis_error=0.002, body_error=5e-4):
    """A UR10 with small errors (in its base frame), or the nominal one."""
    arm = robots.get("ur10")
    if not kinematic_errors:
        return arm
    return simulate(arm, Layout(6, base=True), rng, axis_error=axis_error, body_error=body_error).truth


def _measure(truth, q, rng, tools=None, frame=FRAME):
    """Tracker rows (DataFrame, mm) of ``truth`` at q with each tool of ``tools`` (name -> offset
    in the hand frame, m; default the single probe TOOL), in ``frame``, with noise."""
    tools = tools or {None: TOOL}
    rows = []
    for name, offset in tools.items():
        p = kinematics.forward(truth.with_tool(offset).transformed(*frame), q)[1] + rng.normal(scale=NOISE, size=(len(q), 3))
        df = pd.DataFrame(q, columns=[f"q{i}" for i in range(1, 7)])
        df[["x", "y", "z"]] = p * 1e3
        if name is not None:
            df["tool"] = name
        rows.append(df)
    return pd.concat(rows, ignore_index=True)


def _files(tmp_path, rng, truth, n_cal=200, n_val=100, tools=None, val_tools=None, val_frame=FRAME):
    cal, val = tmp_path / "cal.csv", tmp_path / "val.csv"
    _measure(truth, random_joints(truth, n_cal, rng), rng, tools).to_csv(cal, index=False)
    _measure(truth, random_joints(truth, n_val, rng), rng, val_tools or tools, val_frame).to_csv(val, index=False)
    return cal, val


def _over(cal, val=None, *more):
    return ["problem=measured", "robot=ur10", f"problem.calibration_file={cal}",
            *([f"problem.validation_file={val}"] if val else []), "progress=false", *more]  # fmt: skip


def _run(tmp_path, over, name="run"):
    execute.run(config.load(over), tmp_path / name)
    return json.loads((tmp_path / name / "summary.json").read_text())


# --- registration ---------------------------------------------------------------------------------
def test_registration_recovers_base_and_tool_to_the_noise(rng):
    arm = robots.get("ur10")
    q = random_joints(arm, 300, rng)
    _, p = kinematics.forward(arm.with_tool(TOOL).transformed(*FRAME), q)
    reg = registration.register(arm, q, p + rng.normal(scale=NOISE, size=p.shape))
    assert np.degrees(Rotation.from_matrix(reg.R @ FRAME[0].T).magnitude()) < 1e-3
    assert np.linalg.norm(reg.t - FRAME[1]) < 1e-4 and np.linalg.norm(reg.tool - TOOL) < 1e-4
    assert reg.rms == pytest.approx(NOISE * np.sqrt(3), rel=0.15)  # what is left is the noise


def test_registration_with_several_tools_finds_each_offset(rng):
    arm = robots.get("ur10")
    q = random_joints(arm, 100, rng)
    k = rng.integers(0, 3, size=100)
    offsets = np.array(list(TOOLS.values()))
    points = np.array([kinematics.forward(arm.with_tool(offsets[j]).transformed(*FRAME), qi)[1] for qi, j in zip(q, k)])
    reg = registration.register(arm, q, points + rng.normal(scale=NOISE, size=points.shape), tools=k, tool_names=tuple(TOOLS))
    assert np.abs(reg.tools - offsets).max() < 1e-4 and reg.to_dict()["tools_m"].keys() == TOOLS.keys()
    assert reg.rms == pytest.approx(NOISE * np.sqrt(3), rel=0.2)


def test_registration_finds_the_tool_rotation_from_measured_orientations(rng):
    arm = robots.get("ur10")
    world = arm.with_tool(TOOL).transformed(*FRAME)
    turn = Rotation.from_rotvec([0.1, -0.2, np.pi / 2]).as_matrix()  # a probe frame turned on the hand
    q = random_joints(arm, 100, rng)
    R_meas, p = kinematics.forward(world.replace(R_h0=world.R_h0 @ turn), q)
    noisy = Rotation.from_rotvec(rng.normal(scale=1e-4, size=(100, 3))).as_matrix() @ R_meas
    reg = registration.register(arm, q, p, rotations=noisy)
    assert np.degrees(Rotation.from_matrix(reg.tool_rotation @ turn.T).magnitude()) < 0.01
    assert reg.rms_angle < 3e-4 and reg.max_angle < 1e-3
    R_model, _ = kinematics.forward(reg.apply(arm), q)  # the registered model predicts the orientations
    assert np.max(Rotation.from_matrix(np.swapaxes(R_model, 1, 2) @ R_meas).magnitude()) < 1e-3


# --- one tool: calibration and the robot files out -------------------------------------------------
def test_calibration_in_the_instruments_frame_and_the_robot_files_out(tmp_path, rng):
    truth = _true_arm(rng)
    cal, val = _files(tmp_path, rng, truth, n_cal=120, n_val=60)
    s = _run(tmp_path, _over(cal, val, "population.generations=15"))
    out = tmp_path / "run"
    err = s["position_error_mm"]["validation"]
    assert err["nominal"]["rms"] > 1.0  # the kinematic errors show after registration alone
    assert err["calibrated"]["rms"] < 1.5 * NOISE * np.sqrt(3) * 1e3  # calibrated: down to the noise
    assert s["problem"]["units"] == {"length": "mm", "joint_angle": "rad"} and s["returned"] == "optimiser"
    data = pd.read_csv(val)
    q, measured = data[[f"q{i}" for i in range(1, 7)]].to_numpy(), data[["x", "y", "z"]].to_numpy() * 1e-3
    poses = pd.read_csv(out / "pose_errors.csv")
    assert list(poses.columns) == ["set", "line", "nominal_mm", "calibrated_mm"] and len(poses) == 180
    reported = poses[poses["set"] == "validation"]["calibrated_mm"].to_numpy()
    assert list(poses[poses["set"] == "validation"]["line"]) == list(range(2, 62))  # the file's lines
    # the model in the instrument's frame loads back and predicts as reported
    model = ZRPRobot.from_yaml(out / "calibrated_in_instrument.yaml")
    np.testing.assert_allclose(np.linalg.norm(kinematics.forward(model, q)[1] - measured, axis=1) * 1e3, reported, atol=1e-9)
    # the URDF (the robot alone, from its own base frame) read by an independent walk
    # (tests/urdf_reference.py), with the frames file's base and tool, predicts the same
    frames = yaml.safe_load((out / "calibrated_robot_frames.yaml").read_text())
    base, tool = (np.array(frames[k]["matrix"]) for k in ("base", "tool"))
    names = robots.get("ur10").joint_names
    assert "world" not in (out / "calibrated_robot.urdf").read_text()
    for k in range(0, 60, 7):
        T = base @ urdf_fk(out / "calibrated_robot.urdf", dict(zip(names, q[k])), "base_link", "hand") @ tool
        assert np.linalg.norm(T[:3, 3] - measured[k]) * 1e3 == pytest.approx(reported[k], abs=1e-9)
    # base and tool transforms: 4x4 and xyz + quaternion say the same; base @ arm @ tool is the model
    for entry in (frames["base"], frames["tool"]):
        T = np.array(entry["matrix"])
        np.testing.assert_allclose(Rotation.from_quat(entry["quaternion_xyzw"]).as_matrix(), T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(entry["xyz"], T[:3, 3], atol=0)
    arm = ZRPRobot.from_yaml(out / "calibrated_robot.yaml")
    R_arm, p_arm = kinematics.forward(arm, q)
    np.testing.assert_allclose(base[:3, :3] @ (p_arm + R_arm @ tool[:3, 3])[..., None] + base[:3, 3:4],
                               kinematics.forward(model, q)[1][..., None], atol=1e-12)  # fmt: skip
    # the DH table re-read predicts within its stated mismatch
    mismatch = s["calibrated_robot"]["dh_mismatch"]
    table = robot_files.read_dh(out / "calibrated_robot_dh.yaml").to_robot()
    gap = np.abs(kinematics.forward(table, q)[1] - p_arm).max() * 1e3
    assert gap <= 2 * mismatch["position_mm"] + 1e-9 and mismatch["position_mm"] < 1e-3  # a sampled largest


def test_validation_split_by_fraction(tmp_path, rng):
    cal, _ = _files(tmp_path, rng, _true_arm(rng), n_cal=120)
    task = build.prepare(config.load(_over(cal, None, "problem.validation_fraction=0.25", "algorithm=lm")), tmp_path / "r").task
    assert task.problem.data.M == 90 and task.judge.validation.M == 30
    assert sorted(np.r_[task.sets["calibration"].lines, task.sets["validation"].lines]) == list(range(2, 122))


# --- several tools -------------------------------------------------------------------------------
def _tool_problem(rng, noise=0.0):
    """A multi-tool problem in the instrument's frame (nominal registered by hand from the
    truth's frame and offsets), exact data of a true arm, and the true genome."""
    arm = robots.get("ur10")
    sim = simulate(arm, Layout(6, base=True), rng, axis_error=0.002, body_error=5e-4)
    nominal = arm.with_tool(TOOLS["A"]).transformed(*FRAME)
    offsets = [TOOLS[k] - TOOLS["A"] for k in "BC"]
    layout = Layout(6, base=True, tools=tuple(map(tuple, offsets)))
    q = random_joints(arm, 60, rng)
    k = np.arange(60) % 3
    worlds = [sim.truth.with_tool(TOOLS[t]).transformed(*FRAME) for t in "ABC"]
    p = np.array([kinematics.forward(worlds[j], qi)[1] for qi, j in zip(q, k)]) + rng.normal(scale=noise, size=(60, 3))
    data = Measurements(q, p, tool=k, tool_names=("A", "B", "C"))
    true_x = layout.pack(nominal, worlds[0], ends=[w.b0[-1] for w in worlds[1:]])
    problem = CalibrationProblem(nominal, data, layout, -np.full(layout.size, 0.05), np.full(layout.size, 0.05))
    return problem, true_x, worlds


def test_several_tools_share_one_arm_in_the_cost(rng):
    problem, true_x, worlds = _tool_problem(rng)
    assert problem.layout.size == 6 * 6 + 3 + 6 and problem.names[-3:] == ["b0_7x_tool3", "b0_7y_tool3", "b0_7z_tool3"]
    assert problem.costs(true_x)[0] < 1e-12 and problem.costs(np.zeros(problem.layout.size))[0] > 1e-3
    for k, world in enumerate(worlds):  # the genome's robot of each tool is that tool's true arm
        np.testing.assert_allclose(problem.layout.robot(problem.nominal, true_x, tool=k).b0, world.b0, atol=1e-14)
    x = true_x + rng.normal(scale=1e-3, size=true_x.size)
    np.testing.assert_allclose(problem.residual(x), problem._residual(x))
    h, J = 1e-7, problem.jacobian(x)
    fd = np.column_stack([(problem.residual(x - h * e) - problem.residual(x + h * e)) / (2 * h) for e in np.eye(x.size)])
    np.testing.assert_allclose(J, fd, atol=1e-6)  # residual(x + d) ~ residual(x) - J d
    canonical = error_model.canonical(problem.layout, problem.nominal, x)  # slides move every tool's end too
    assert problem.costs(canonical)[0] == pytest.approx(problem.costs(x)[0], rel=1e-9)
    assert np.linalg.norm(canonical - x) > 1e-4


def test_several_tools_calibrate_one_arm_and_leave_as_robot_files(tmp_path, rng):
    truth = _true_arm(rng)
    cal, val = _files(tmp_path, rng, truth, n_cal=80, n_val=30, tools=TOOLS)
    s = _run(tmp_path, _over(cal, val, "algorithm=lm"))
    assert s["problem"]["tools"] == ["A", "B", "C"] and len(s["best_genome"]) == 6 * 6 + 3 + 6
    assert s["position_error_mm"]["validation"]["calibrated"]["rms"] < 1.5 * NOISE * np.sqrt(3) * 1e3
    # the tool points' offsets from one another, in the instrument's frame, are the true ones
    frames = yaml.safe_load((tmp_path / "run" / "calibrated_robot_frames.yaml").read_text())
    tools = {k: np.array(v["matrix"]) for k, v in frames["tools"].items()}
    true_hand = truth.transformed(*FRAME).R_h0
    base = np.array(frames["base"]["matrix"])
    arm = ZRPRobot.from_yaml(tmp_path / "run" / "calibrated_robot.yaml")
    for a, b in (("A", "B"), ("A", "C")):
        found = base[:3, :3] @ arm.R_h0 @ (tools[b][:3, 3] - tools[a][:3, 3])
        np.testing.assert_allclose(found, true_hand @ (TOOLS[b] - TOOLS[a]), atol=2e-4)
    # an independent walk (tests/urdf_reference.py): base (frames file) and base_link -> hand, then each row's tool
    # transform, predicts the validation points as reported
    names = robots.get("ur10").joint_names
    data = pd.read_csv(val)
    poses = pd.read_csv(tmp_path / "run" / "pose_errors.csv")
    reported = poses[poses["set"] == "validation"].reset_index(drop=True)
    assert list(reported["tool"]) == list(data["tool"])
    for k in range(0, len(data), 7):
        hand = base @ urdf_fk(tmp_path / "run" / "calibrated_robot.urdf", dict(zip(names, data.loc[k, [f"q{i}" for i in range(1, 7)]].to_numpy(float))), "base_link", "hand")
        p = (hand @ tools[data.loc[k, "tool"]])[:3, 3] * 1e3
        assert np.linalg.norm(p - data.loc[k, ["x", "y", "z"]].to_numpy(float)) == pytest.approx(reported["calibrated_mm"][k], abs=1e-8)


# --- validation: another frame, a known other tool point ------------------------------------------
def test_rigid_registration_of_predictions_removes_a_moved_frame_only(rng):
    arm = robots.get("ur10")
    q = random_joints(arm, 30, rng)
    layout = Layout(6)
    moved = Rotation.from_rotvec([0.2, 0.1, -0.4]).as_matrix() @ kinematics.forward(arm, q)[1].T + np.array([[1.0], [-2.0], [0.5]])
    data = Measurements(q, moved.T)
    assert metrics.position_errors(layout, arm, np.zeros(36), data).min() > 0.5
    assert metrics.position_errors(layout, arm, np.zeros(36), data, "rigid").max() < 1e-12
    stretched = Measurements(q, moved.T * 1.001)  # not rigid: left in the errors
    assert metrics.position_errors(layout, arm, np.zeros(36), stretched, "rigid").max() > 1e-4


def test_validation_in_another_instrument_frame(tmp_path, rng):
    truth = _true_arm(rng)
    moved = (Rotation.from_rotvec([0.0, 0.1, 2.5]).as_matrix(), np.array([-2.0, 1.0, 0.3]))
    cal, val = _files(tmp_path, rng, truth, n_cal=150, n_val=50, val_frame=moved)
    rigid = _run(tmp_path, _over(cal, val, "algorithm=lm", "problem.validation_registration=rigid"))
    err = rigid["position_error_mm"]["validation"]
    assert err["nominal"]["rms"] > 1.0 and err["calibrated"]["rms"] < 1.5 * NOISE * np.sqrt(3) * 1e3
    task = build.prepare(config.load(_over(cal, val, "algorithm=lm")), tmp_path / "plain").task
    assert task.judge.validation_errors(np.zeros(task.problem.layout.size))[0][0] > 1.0  # metres off without it


def test_known_tools_are_predicted_from_the_hand(rng):
    arm = robots.get("ur10")
    d1, dv = TOOLS["A"], np.array([0.01, 0.02, 0.15])
    nominal = arm.with_tool(d1)
    layout = Layout(6, known_tools=(tuple(dv - d1),))
    q = random_joints(arm, 10, rng)
    data = Measurements(q, kinematics.forward(arm.with_tool(dv), q)[1], tool=np.ones(10, dtype=int), tool_names=("A", "D"))
    assert metrics.position_errors(layout, nominal, np.zeros(layout.size), data).max() < 1e-14


def test_validation_with_a_known_other_tool_point(tmp_path, rng):
    truth = _true_arm(rng, kinematic_errors=False)  # the hand frame is the nominal one: the known offset holds
    tools = {k: TOOLS[k] for k in "AB"}
    cal, val = _files(tmp_path, rng, truth, n_cal=60, n_val=40, tools=tools, val_tools={"D": np.array([0.0, 0.0, 0.08])})
    s = _run(tmp_path, _over(cal, val, "algorithm=lm", "problem.known_tools={D:[0,0,80]}"))
    assert s["problem"]["known_tools"] == {"D": [0.0, 0.0, 0.08]}  # mm in the file's unit -> m
    assert s["position_error_mm"]["validation"]["calibrated"]["rms"] < 2.0 * NOISE * np.sqrt(3) * 1e3
    with pytest.raises(ValueError, match=r"val\.csv, line 2, column 'tool': tool 'D' is neither"):
        build.prepare(config.load(_over(cal, val, "algorithm=lm")), tmp_path / "unknown")


# --- gene ranges from the data, and what is returned ------------------------------------------------
def test_data_gene_ranges_follow_the_residuals_and_the_axes_levers(tmp_path, rng):
    cal, _ = _files(tmp_path, rng, _true_arm(rng), n_cal=40)
    task = build.prepare(config.load(_over(cal, None, "algorithm=lm")), tmp_path / "r").task
    p, reg, c = task.problem, task.registration, config.MeasuredConf(search_scale=5.0)
    e = reg.max
    np.testing.assert_allclose(p.upper[p.layout.blocks["b0"]], 5.0 * e)
    np.testing.assert_allclose(p.upper[p.layout.blocks["base"]], 5.0 * e)
    # the lever of axis 2: how far the end point moves per radian of tilt, by finite differences
    h, levers = 1e-7, []
    for qi in task.problem.data.q:
        D = []
        for t in np.eye(3):
            bent = p.nominal.replace(u0=p.nominal.u0 + np.outer(np.eye(6)[1], h * t), normalize=True)
            D.append((kinematics.forward(bent, qi)[1] - kinematics.forward(p.nominal, qi)[1]) / h)
        levers.append(np.linalg.svd(np.array(D).T, compute_uv=False)[0])
    lever = np.median(levers)
    assert p.upper[3] == pytest.approx(5.0 * e / lever, rel=1e-4)
    np.testing.assert_allclose(gene_half_widths(p.layout, p.nominal, p.data.q, reg, c), p.upper)


def test_ranges_wide_enough_for_large_errors_and_a_warning_when_held(tmp_path, rng):
    truth = _true_arm(rng, axis_error=0.01, body_error=0.01)  # 1 cm, 10 mrad: beyond the paper's ranges
    cal, val = _files(tmp_path, rng, truth, n_cal=100, n_val=30)
    wide = _run(tmp_path, _over(cal, val, "population.generations=20"), "wide")
    assert not [w for w in wide["warnings"] if "range bounds" in w]
    assert wide["position_error_mm"]["validation"]["calibrated"]["rms"] < 2.0 * NOISE * np.sqrt(3) * 1e3
    held = _run(tmp_path, _over(cal, val, "population.generations=3", "problem.ranges=fixed", "problem.body_error=0.0005",
                                "problem.search_scale=1"), "held")  # fmt: skip
    assert any("sit on their range bounds" in w for w in held["warnings"])


def test_a_result_worse_than_the_nominal_arm_is_not_returned(tmp_path, rng):
    cal, val = _files(tmp_path, rng, _true_arm(rng, kinematic_errors=False), n_cal=60, n_val=20)
    s = _run(tmp_path, _over(cal, val, "population.mu=2", "population.lambda_=2", "population.generations=1", "refine=none"))
    assert s["returned"] == "nominal" and s["optimiser_cost"] > s["nominal_cost"] == s["final_cost"]
    assert set(s["best_genome"].values()) == {0.0}
    assert any("the nominal arm is returned instead" in w for w in s["warnings"])
    model = ZRPRobot.from_yaml(tmp_path / "run" / "calibrated_in_instrument.yaml")
    task = build.prepare(config.load(_over(cal, val)), tmp_path / "again").task
    np.testing.assert_allclose(model.b0, task.problem.nominal.b0, atol=1e-15)


# --- what the settings ask of the data ------------------------------------------------------------
@pytest.mark.parametrize(
    "extra, message",
    [
        (["problem.use_orientation=true"], "problem.orientation_convention: state the convention"),
        (["problem.use_weights=true"], "problem.use_weights: "),
        (["problem.orientation_convention=XXZ"], "problem.orientation_convention: 'XXZ' is neither"),
        (["problem.length_unit=km"], "problem.length_unit: must be m, mm or auto"),
        (["problem.known_tools={D:[0,1]}"], "problem.known_tools.D: must be a list of 3 finite numbers"),
    ],
)
def test_settings_the_data_cannot_serve(tmp_path, rng, extra, message):
    cal = tmp_path / "cal.csv"
    df = _measure(robots.get("ur10"), random_joints(robots.get("ur10"), 30, rng), rng)
    df[["rx", "ry", "rz"]] = 0.0
    df.to_csv(cal, index=False)
    with pytest.raises(ValueError, match=message):
        build.prepare(config.load(_over(cal, None, "algorithm=lm", *extra)), tmp_path / "r")


def test_orientations_with_several_tools_are_refused(tmp_path, rng):
    cal, _ = _files(tmp_path, rng, robots.get("ur10"), n_cal=20, tools=TOOLS)
    df = pd.read_csv(cal)
    df[["rx", "ry", "rz"]] = 0.0
    df.to_csv(cal, index=False)
    over = _over(cal, None, "algorithm=lm", "problem.use_orientation=true", "problem.orientation_convention=rotvec")
    with pytest.raises(ValueError, match="measures 3 tool points; orientations are supported with one tool"):
        build.prepare(config.load(over), tmp_path / "r")


@pytest.mark.parametrize("rows, message", [(1, "a single pose; a calibration of ur10 needs at least 9 measured points "
                                                  "(3 rows each for the 27 parameter combinations"),
                                           (5, "5 distinct measured points in 5 poses; a calibration of ur10 needs at least 9")])  # fmt: skip
def test_too_few_points_say_how_many_are_needed(tmp_path, rng, rows, message):
    """UR10, positions, base point identified: rank 33 of 39 (experiments/README.md), of which
    the 6 unit rows give 6: 27 combinations, 3 position rows per point, 9 points."""
    cal = tmp_path / "cal.csv"
    _measure(robots.get("ur10"), random_joints(robots.get("ur10"), rows, rng), rng).to_csv(cal, index=False)
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        build.prepare(config.load(_over(cal, None, "problem.length_unit=mm")), tmp_path / "r")


def test_ur10_ipa_is_the_measured_problem_with_its_files_and_robot_wins():
    files = ["problem.format=ur10_ipa", "problem.calibration_file=pkg:ur10_ipa/series_b_joint_configurations.csv",
             "problem.validation_file=pkg:ur10_ipa/series_c_random_poses.csv"]  # fmt: skip
    preset, generic = config.load(["problem=ur10_ipa"]), config.load(["problem=measured", "robot=ur10", *files])
    assert preset.problem == generic.problem and preset.robot == generic.robot
    assert config.load(["problem=ur10_ipa", "robot=puma560"]).robot.name == "puma560"


# --- the command line: one line, exit code 2, no run directory, for every class of bad input ---------
def _cli(monkeypatch, capsys, args):
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    monkeypatch.setattr(sys, "argv", ["zrp-ga", *args])
    monkeypatch.setenv("HYDRA_FULL_ERROR", "0")
    with pytest.raises(SystemExit) as info:
        cli_main.cli()
    GlobalHydra.instance().clear()
    return info.value.code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda d, df: d / "missing.csv", "missing.csv: no such file"),
        (lambda d, df: d, "is a directory, expected a measurement file"),
        (lambda d, df: df.assign(x=df["x"].where(df.index != 4, 1e300)), "line 6, column 'x': 1e+300 mm is absurd"),
        (lambda d, df: df.head(4), "4 distinct measured points in 4 poses; a calibration of ur10 needs at least 9"),
        (lambda d, df: df.head(1), "a single pose; a calibration of ur10 needs at least 9"),
        (lambda d, df: pd.concat([df, df.head(2)]), "2 rows repeat earlier rows exactly (first: line 32 repeats line 2)"),
    ],
)
def test_bad_input_from_the_command_line_is_one_line(tmp_path, rng, monkeypatch, capsys, make, message):
    df = _measure(robots.get("ur10"), random_joints(robots.get("ur10"), 30, rng), rng)
    made = make(tmp_path, df)
    if isinstance(made, pd.DataFrame):
        made.to_csv(tmp_path / "cal.csv", index=False)
        made = tmp_path / "cal.csv"
    code, err = _cli(monkeypatch, capsys, _over(made, None, f"hydra.run.dir={tmp_path / 'run'}"))
    assert code == 2 and not (tmp_path / "run").exists()
    assert len(err) == 1 and err[0].startswith("zrp-ga: error: ") and message in err[0]


def test_the_modified_dh_file_re_read_predicts_within_its_mismatch(tmp_path, rng):
    cal, _ = _files(tmp_path, rng, _true_arm(rng), n_cal=60)
    s = _run(tmp_path, _over(cal, None, "algorithm=lm"))
    out = tmp_path / "run"
    arm = ZRPRobot.from_yaml(out / "calibrated_robot.yaml")
    q = random_joints(arm, 50, rng)
    for kind in ("dh", "mdh"):
        table = robot_files.read_dh(out / f"calibrated_robot_{kind}.yaml")
        assert table.convention == kind
        gap = np.abs(kinematics.forward(table.to_robot(), q)[1] - kinematics.forward(arm, q)[1]).max() * 1e3
        assert gap <= 2 * s["calibrated_robot"][f"{kind}_mismatch"]["position_mm"] + 1e-9  # the mismatch is a sampled largest
