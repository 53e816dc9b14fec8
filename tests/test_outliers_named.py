"""Three points of a measurement file moved by 5 mm: the warning a user reads (the console's
line, ``summary["warnings"]``) names the file and the three file lines, counted here from the
file itself (the header is line 1), and the robust fit stays within 10 % of the clean file's
validation error (issue 29, Must show)."""

from __future__ import annotations

import re

import numpy as np

import zrp_ga

LINES = (5, 33, 59)  # file lines (1: the header)


def test_the_warning_names_the_file_and_the_lines_moved(tmp_path):
    sim = zrp_ga.simulate("stanford", 60, 60, tool=[0.05, -0.02, 0.1], base=[1.5, 0.3, 0.0], noise=2e-5, seed=4,
                          out=tmp_path / "clean")  # fmt: skip
    text = sim.files["calibration"].read_text().splitlines()
    columns = text[0].split(",")
    xyz = [columns.index(c) for c in ("x", "y", "z")]
    d = np.random.default_rng(1).normal(size=(3, 3))
    d = 5e-3 * d / np.linalg.norm(d, axis=1, keepdims=True)  # 5 mm each (the file is in m)
    for line, move in zip(LINES, d):
        row = text[line - 1].split(",")
        for i, dx in zip(xyz, move):
            row[i] = f"{float(row[i]) + dx:.9f}"
        text[line - 1] = ",".join(row)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(text) + "\n")
    lines = list(LINES)
    val = sim.files["validation"]
    clean = zrp_ga.calibrate("stanford", sim.files["calibration"], validation=val, algorithm="lm", problem=sim.settings)
    robust = zrp_ga.calibrate("stanford", bad, validation=val, algorithm="lm", problem={**sim.settings, "loss": "soft_l1"})
    said = [w for w in robust.summary["warnings"] if "lie far beyond the noise" in w]
    assert len(said) == 1 and str(bad) in said[0], robust.summary["warnings"]
    assert sorted(int(n) for n in re.findall(r"line (\d+) \(", said[0])) == lines, said[0]
    v_clean, v_robust = clean.summary["validation_rms_mm"]["calibrated"], robust.summary["validation_rms_mm"]["calibrated"]
    assert v_robust < 1.1 * v_clean, (v_robust, v_clean)
