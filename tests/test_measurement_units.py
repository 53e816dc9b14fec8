"""Every length a measurement file holds leaves the reader in metres: positions, standard
deviations and prismatic joint values, in a file in millimetres, against the file's numbers
divided by 1000 by hand (and the shipped UR10 file against its own cells read by pandas)."""

import numpy as np
import pandas as pd

from zrp_ga import robots
from zrp_ga.io import measurements
from zrp_ga.io.measurements import read, zrp_format

ROWS_MM = [  # q1..q6 (rad), x, y, z, sx, sy, sz (mm)
    [0, 0, 0, 0, 0, 0, 100, 200, 300, 0.05, 0.06, 0.07],
    [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 450, 550, 650, 0.02, 0.03, 0.04],
    [-0.3, 0.5, 1, 0, -1, 2, 900, -200, 150, 0.11, 0.12, 0.13],
    [1, 1, 1, 1, 1, 1, -500, 350, 700, 0.5, 0.25, 0.125],
]


def test_positions_and_standard_deviations_in_mm_are_read_in_metres(tmp_path):
    path = tmp_path / "mm.csv"
    pd.DataFrame(ROWS_MM, columns=["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z", "sx", "sy", "sz"]).to_csv(path, index=False)
    rows = np.array(ROWS_MM)
    for unit in ("mm", "auto"):
        data = read(path, zrp_format(6, unit, "rad"), robots.get("ur10"))
        assert data.units == ("mm", "rad")
        np.testing.assert_allclose(data.p, rows[:, 6:9] / 1000, rtol=1e-15)
        np.testing.assert_allclose(data.std, rows[:, 9:12] / 1000, rtol=1e-15)
        np.testing.assert_allclose(data.q, rows[:, :6], rtol=1e-15)


def test_the_shipped_ur10_file_reads_its_mm_cells_in_metres():
    from zrp_ga.problems.measured import data_path

    path = data_path("pkg:ur10_ipa/series_b_joint_configurations.csv")
    cells = pd.read_csv(path, sep=";", decimal=",")
    data = read(path, measurements.UR10_IPA, robots.get("ur10"))
    for axis in "xyz":
        np.testing.assert_allclose(data.std[:, "xyz".index(axis)], cells[f"measurement_std_{axis}"].to_numpy() / 1000, rtol=1e-12)
        np.testing.assert_allclose(data.p[:, "xyz".index(axis)], cells[f"measurement_{axis}"].to_numpy() / 1000, rtol=1e-12)
