"""A calibration kept and used after the fact (issue 31 item 5, issue 29 item 3's compensation
part), through the public API only: zrp_ga.simulate makes a tracker cell's files, zrp_ga.calibrate
fits them, Calibration.save / zrp_ga.load keep it, .predict and .export use it, zrp_ga.compensate
corrects a program with per-row predicted errors and coverage; each figure against the true arm
the simulation drew.

    python experiments/kept_calibration.py OUT     (writes OUT/... and prints the table;
                                                     experiments/results/kept_calibration.md)

The cell: a PUMA 560 seen by a tracker 2 m away, a probe 0.1 m off the flange, positions only
(0.02 mm noise per coordinate), 60 calibration poses with every joint within +-60 deg (joints 4
and 6 +-120 deg): a restricted cell. The program: 40 probe targets in the tracker's frame from
joint values inside the cell and 40 with joint 1 at 70-110 deg (outside it).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

import zrp_ga
from zrp_ga import kinematics

LIMIT = np.radians([60, 60, 60, 120, 60, 120])


def main(out: Path) -> str:
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(31)
    base = np.eye(4)
    base[:3, :3] = Rotation.from_rotvec([0.2, 0.1, -0.6]).as_matrix()
    base[:3, 3] = [2.0, 0.5, -0.2]
    sim = zrp_ga.simulate("puma560", q=rng.uniform(-LIMIT, LIMIT, (60, 6)), q_validation=rng.uniform(-LIMIT, LIMIT, (30, 6)),
                          tool=[0.03, 0.0, 0.1], base=base, noise=2e-5, units="mm,deg", seed=1, out=out / "data")  # fmt: skip
    cal = zrp_ga.calibrate("puma560", sim.files["calibration"], validation=sim.files["validation"], algorithm="lm",
                           problem=sim.settings)  # fmt: skip
    back = zrp_ga.load(cal.save(out / "run"))
    q = rng.uniform(-LIMIT, LIMIT, (200, 6))
    a, b = cal.predict(q), back.predict(q)
    rows = [("save -> load: largest position difference of predict (200 poses)", f"{np.abs(a.p - b.p).max():.2g} m"),
            ("save -> load: largest relative difference of the predicted sigma", f"{np.max(np.abs(a.position_mm / b.position_mm - 1)):.2g}")]  # fmt: skip

    def seen(qq):  # the true probe in the tracker's frame
        R, p = kinematics.forward(sim.truth, qq)
        return (p + R @ sim.tools[""][:3, 3]) @ base[:3, :3].T + base[:3, 3]

    inside = rng.uniform(-0.8 * LIMIT, 0.8 * LIMIT, (40, 6))
    outside = rng.uniform(-0.8 * LIMIT, 0.8 * LIMIT, (40, 6))
    outside[:, 0] = np.radians(rng.uniform(70, 110, 40))
    prog = np.vstack([inside, outside])
    prog[:, 4] = np.where(np.abs(prog[:, 4]) < 0.3, 0.5, prog[:, 4])
    targets = seen(prog)  # targets the true probe reaches at the program's joints
    program = pd.DataFrame({**{f"{k}_mm": targets[:, j] * 1e3 for j, k in enumerate("xyz")},
                            **{f"q{i + 1}_deg": np.degrees(prog[:, i]) for i in range(6)}})  # each row seeded by its joints
    program.to_csv(out / "program.csv", index=False)
    c = zrp_ga.compensate(out / "run", out / "program.csv", kind="cartesian", frame="instrument", tool="calibration",
                          out=out / "compensated")  # fmt: skip
    actual = np.linalg.norm(seen(c.q) - targets, axis=1) * 1e3
    sigma, flagged = c.predicted["sigma_mm"], c.predicted["outside"]
    for name, k in (("inside the cell", slice(0, 40)), ("joint 1 beyond the cell", slice(40, 80))):
        rows.append((f"program rows {name}: flagged outside", f"{int(flagged[k].sum())} of 40"))
        rows.append((f"program rows {name}: true probe error after compensation, RMS", f"{np.sqrt(np.mean(actual[k] ** 2)):.3g} mm"))
        rows.append((f"program rows {name}: predicted sigma_mm, RMS", f"{np.sqrt(np.mean(sigma[k] ** 2)):.3g} mm"))
    rows.append(("validation RMS (calibration's own summary)", f"{cal.summary['validation_rms_mm']['calibrated']:.3g} mm"))
    table = "| what | value |\n| --- | --- |\n" + "\n".join(f"| {k} | {v} |" for k, v in rows)
    return table


if __name__ == "__main__":
    text = main(Path(sys.argv[1] if len(sys.argv) > 1 else "outputs/kept_calibration"))
    print(text)
