"""Simulated laser-tracker measurements of an ABB IRB 140 that is not a preset (the worked example).

Writes into this folder (every number from one seeded random stream, so the files are the same
on every run):

- ``irb140.urdf``: the arm of ``irb140.yaml`` (standard DH) as a URDF in the style DH exports
  take (each joint frame a DH frame, axes along z, ``rpy`` origins), written here with scipy
  and checked against the DH table's own forward kinematics;
- ``calibration.csv``: 60 poses, each measured at three reflectors A, B, C on the flange;
- ``validation.csv``: 40 other poses, same reflectors, same tracker position;
- ``validation_moved.csv``: 40 other poses after the tracker was moved (another frame);
- ``validation_tool_d.csv``: 40 other poses of a fourth reflector D at a known place on the
  flange (``problem.known_tools={D:[0,0,80]}``, mm), never seen in the calibration;
- ``truth.json``: what the simulation used (errors, frames, tools, noise), for the record.

The true arm differs from the DH table as a real one does: link lengths and offsets by
N(0, 0.2 mm), twists by N(0, 0.3 mrad), joint zero offsets by N(0, 0.5 mrad), and axis 3 is
tilted 0.3 mrad out of parallel with axis 2 (an error no DH table can hold). The controller
reports joint angles in degrees, the tracker millimetres; the joints bend under gravity
(joint 2 by 40 urad x cos q2, joint 3 by 30 urad x cos(q2 + q3)) and their encoders read with
N(0, 20 urad) noise; the tracker measures with N(0, 0.02 mm) per axis. The tracker stands about
3 m from the base. Run:

    python experiments/own_arm/make_data.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from zrp_ga.io import robot_files
from zrp_ga.model import dh, kinematics

HERE = Path(__file__).parent
TOOLS_MM = {"A": [60.0, 0.0, 30.0], "B": [-30.0, 52.0, 30.0], "C": [-30.0, -52.0, 30.0]}
KNOWN_TOOL_MM = {"D": [0.0, 0.0, 80.0]}
NOISE_MM = 0.02
ENCODER_RAD = 2e-5
GRAVITY_RAD = (4e-5, 3e-5)  # joint 2, joint 3


def urdf_text(table: dh.DHTable) -> str:
    """A URDF of a standard DH table in the DH-export style (module docstring): link_i turns
    with joint i about z of DH frame i-1; joint i+1 sits at row i's fixed part
    ``Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; the fixed joint ``flange_joint`` carries the last row."""
    def origin(i: int) -> str:
        if i < 0:
            return '<origin xyz="0 0 0" rpy="0 0 0"/>'
        R = Rotation.from_euler("z", table.theta[i]) * Rotation.from_euler("x", table.alpha[i])
        xyz = Rotation.from_euler("z", table.theta[i]).apply([table.a[i], 0.0, table.d[i]])
        rpy = R.as_euler("xyz")  # URDF: extrinsic roll, pitch, yaw
        return f'<origin xyz="{" ".join(map(repr, xyz.tolist()))}" rpy="{" ".join(map(repr, rpy.tolist()))}"/>'

    parts = [f'<?xml version="1.0"?>\n<robot name="{table.name}">', '  <link name="base_link"/>']
    parent = "base_link"
    for i, name in enumerate(table.joint_names):
        lower, upper = (float(v) for v in table.limits[i])
        parts += [f'  <link name="link_{i + 1}"/>',
                  f'  <joint name="{name}" type="revolute">\n    <parent link="{parent}"/>\n    <child link="link_{i + 1}"/>\n'
                  f'    {origin(i - 1)}\n    <axis xyz="0 0 1"/>\n'
                  f'    <limit lower="{lower!r}" upper="{upper!r}" effort="0" velocity="0"/>\n  </joint>']  # fmt: skip
        parent = f"link_{i + 1}"
    parts += ['  <link name="flange"/>',
              f'  <joint name="flange_joint" type="fixed">\n    <parent link="{parent}"/>\n    <child link="flange"/>\n'
              f'    {origin(table.n - 1)}\n  </joint>', "</robot>\n"]  # fmt: skip
    return "\n".join(parts)


def true_arm(table: dh.DHTable, rng: np.random.Generator):
    """The real arm: the table with DH parameter errors, axis 3 tilted out of parallel (a ZRP
    robot), and the errors drawn."""
    errors = {"a_m": rng.normal(0, 2e-4, 6), "d_m": rng.normal(0, 2e-4, 6), "alpha_rad": rng.normal(0, 3e-4, 6),
              "theta_rad": rng.normal(0, 5e-4, 6)}  # fmt: skip
    bent = dh.DHTable("dh", table.a + errors["a_m"], table.alpha + errors["alpha_rad"], table.d + errors["d_m"],
                      table.theta + errors["theta_rad"], table.joint_types, name="irb140 (true)",
                      joint_names=table.joint_names, limits=table.limits).to_robot()  # fmt: skip
    normal = np.cross(bent.u0[1], [0.0, 0.0, 1.0])
    u0 = bent.u0.copy()
    u0[2] = Rotation.from_rotvec(3e-4 * normal / np.linalg.norm(normal)).apply(u0[2])
    errors["axis_3_tilt_rad"] = 3e-4
    return bent.replace(u0=u0), errors


def tracker(rng: np.random.Generator, distance_m: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """A tracker frame about ``distance_m`` from the base: the base-to-tracker rotation and translation."""
    R = Rotation.random(random_state=rng).as_matrix()
    direction = rng.normal(size=3)
    return R, distance_m * direction / np.linalg.norm(direction)  # t: the base's origin in the tracker frame


def poses(table: dh.DHTable, M: int, rng: np.random.Generator) -> np.ndarray:
    """M joint configurations (rad) uniform within the limits (wrist joints within +-180 deg)."""
    low, high = table.limits[:, 0].copy(), table.limits[:, 1].copy()
    low[3:], high[3:] = np.maximum(low[3:], -np.pi), np.minimum(high[3:], np.pi)
    return rng.uniform(low, high, size=(M, 6))


def measure(arm, q: np.ndarray, tools: dict[str, list[float]], frame, rng: np.random.Generator) -> pd.DataFrame:
    """Every pose measured at every tool: the controller's joint values (deg) and the tracker's
    points (mm), with gravity bending, encoder and tracker noise."""
    R, t = frame
    rows = []
    for qi in q:
        actual = qi + rng.normal(0, ENCODER_RAD, 6)
        actual[1] += GRAVITY_RAD[0] * np.cos(qi[1])
        actual[2] += GRAVITY_RAD[1] * np.cos(qi[1] + qi[2])
        for name, offset in tools.items():
            p = kinematics.forward(arm.with_tool(np.array(offset) * 1e-3).transformed(R, t), actual)[1] * 1e3
            p += rng.normal(0, NOISE_MM, 3)
            rows.append({**{f"q{j + 1}": round(float(np.degrees(qi[j])), 4) for j in range(6)},
                         **dict(zip("xyz", np.round(p, 4).tolist())), "tool": name})  # fmt: skip
    return pd.DataFrame(rows)


def main() -> None:
    rng = np.random.default_rng(140)
    table = robot_files.read_dh(HERE / "irb140.yaml")
    nominal = table.to_robot()
    urdf = urdf_text(table)
    (HERE / "irb140.urdf").write_text(urdf)
    check = robot_files.read_robot(HERE / "irb140.urdf")
    q = poses(table, 50, rng)
    gap = np.abs(np.array(kinematics.forward(check, q)[1]) - kinematics.forward(nominal, q)[1]).max()
    assert gap < 1e-12, f"the URDF and the DH table differ by {gap} m"
    arm, errors = true_arm(table, rng)
    here, moved = tracker(rng), tracker(rng)
    files = {"calibration.csv": (60, TOOLS_MM, here), "validation.csv": (40, TOOLS_MM, here),
             "validation_moved.csv": (40, TOOLS_MM, moved), "validation_tool_d.csv": (40, KNOWN_TOOL_MM, here)}  # fmt: skip
    for name, (M, tools, frame) in files.items():
        measure(arm, poses(table, M, rng), tools, frame, rng).to_csv(HERE / name, index=False)
    truth = {"errors": {k: np.asarray(v).tolist() for k, v in errors.items()}, "tools_mm": {**TOOLS_MM, **KNOWN_TOOL_MM},
             "tracker": {"R": here[0].tolist(), "t_m": here[1].tolist()},
             "tracker_moved": {"R": moved[0].tolist(), "t_m": moved[1].tolist()},
             "noise": {"tracker_mm": NOISE_MM, "encoder_rad": ENCODER_RAD, "gravity_rad": list(GRAVITY_RAD)},
             "true_arm_in_base_frame": arm.to_dict()}  # fmt: skip
    (HERE / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    print(f"wrote {', '.join(files)}, irb140.urdf and truth.json in {HERE}")


if __name__ == "__main__":
    main()
