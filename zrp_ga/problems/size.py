"""What a problem kind declares about the size of its instances, before one is built: its
genes, what the instance holds and what evaluating genomes costs (:class:`ProblemSize`). The
run's memory and time estimate (:mod:`zrp_ga.run.budget`) asks the kind for it: a kind's
module has, beside ``build(robot, run_seed, **settings) -> Task``,
``size(robot, **settings) -> ProblemSize`` with the same settings.

A calibration problem (the simulated, measured and pose-selection kinds) holds, in float64
(8 bytes), with K genes, ``r`` rows per pose (3 for positions, 6 with orientations), M
calibration and V validation poses, ``R = r M + n`` residual rows (:func:`calibration`):

- **poses**: the pose Jacobians ``(M, 6, K)`` in four working copies (the chain rule, the
  reshape, the stacking, the weights), the forward kinematics' rotations ``(M, n + 1, 3, 3)``
  twice, the stacked Jacobian ``(R, K)`` the problem keeps and two more in the identifiability
  SVD; the text of the measurement file while it is read (about 160 bytes a cell);
- **validation**: the same Jacobians and file text for the validation poses;
- **parameters**: five ``(K, K)`` matrices (the SVD's ``V``, the identity whose rows name
  unidentifiable genes, the null-space basis and its QR, the projector on the identifiable
  directions);
- **per genome evaluated at once**: two residual vectors ``(R,)`` (the linear cost's
  ``y - X J^T``).

Time: the Jacobians (``1.5e-5 s`` per pose and gene), the SVDs, least squares and null-space
bookkeeping (``1.2e-8 s K^3`` plus ``5e-8 s R K min(R, K)``), the file reading (``2e-4 s``
per row) and per evaluation ``3e-8 s`` per pose and joint (or per row and gene for the linear
cost), constants measured on a loaded 2-core machine (a 500-joint arm: 400 s; a 100 000-row
file: 130 s). The estimate adds the optimiser's own (:class:`zrp_ga.algorithms.AlgorithmSize`)
and a margin (:mod:`zrp_ga.run.budget`); tests/test_bad_inputs_more.py compares it with
measured peaks.

>>> p = calibration(n=6, genes=42, poses=30, validation=100, rows_per_pose=6)
>>> p.rows, round(sum(p.held_bytes.values()) / 1e6, 2), p.genome_bytes
(186, 1.44, 2976)
"""

from __future__ import annotations

import dataclasses
import math
import os
import stat
from collections.abc import Mapping
from pathlib import Path

FLOAT = 8  # bytes
JACOBIAN_COPIES = 4
CELL_BYTES = 160  # a measurement file's cell while pandas holds it as text (measured: ~125)
FILE_ROW_S = 2e-4
JACOBIAN_S = 1.5e-5  # per pose and gene: every Jacobian of a run (problem, ranges, projector, judge)
SVD_S = 1.2e-8  # per K^3
ROWS_S = 5e-8  # per R K min(R, K): SVDs and least squares of the stacked Jacobian
EVAL_S = 3e-8  # per evaluation, pose and joint (or row and gene)
SAMPLE_BYTES = 64 * 1024  # of a file, read to estimate its rows

Lower = tuple[str, str]  # the setting that drives a part of the estimate, and what to do about it


@dataclasses.dataclass(frozen=True)
class ProblemSize:
    """A problem instance's size, declared by its kind before it is built.

    ``genes``: K, the genome's length; ``rows``: residual rows of one genome (0: none);
    ``held_bytes``: what the instance holds once built, by part (``poses``, ``validation``,
    ``parameters``, or a kind's own names); ``genome_bytes``: what evaluating one genome holds
    while a population is evaluated at once (bytes per genome); ``build_s``: seconds to build
    it, by part; ``evaluation_s``: seconds per genome evaluation; ``lower``: for each part of
    ``held_bytes`` (and of ``build_s``), the config key that drives it and what to do, as the
    refusal says it; ``choices``: for a genome that chooses among candidates (pose
    selection), how many there are (None: a continuous genome)."""

    genes: int
    rows: int
    held_bytes: Mapping[str, float]
    genome_bytes: float
    build_s: Mapping[str, float]
    evaluation_s: float
    lower: Mapping[str, Lower]
    choices: int | None = None


def calibration(n: int, genes: int, poses: int, validation: int, rows_per_pose: int, cells: tuple[int, int] = (0, 0),
                lower: Mapping[str, Lower] | None = None) -> ProblemSize:  # fmt: skip
    """The size of a calibration problem (module docstring) of an ``n``-joint arm with ``genes``
    K, ``poses`` M and ``validation`` V poses of ``rows_per_pose`` r rows, ``cells``: the
    measurement files' cells to read (calibration, validation); ``lower``: the settings that
    drive each part (default: the simulated kinds' ``problem.n_poses``, ``problem.n_validation``)."""
    K, M, V, r = int(genes), int(poses), int(validation), int(rows_per_pose)
    R = r * M + n
    jacobians = lambda m: FLOAT * (JACOBIAN_COPIES * 6 * m * K + 2 * 9 * m * (n + 1))
    held = {
        "poses": jacobians(M) + FLOAT * 3 * R * K + CELL_BYTES * cells[0],
        "validation": jacobians(V) + CELL_BYTES * cells[1],
        "parameters": FLOAT * 5 * K * K,
    }
    build = {
        "poses": JACOBIAN_S * M * K + ROWS_S * R * K * min(R, K) + FILE_ROW_S * cells[0] / max(n + 3, 1),
        "validation": JACOBIAN_S * V * K + FILE_ROW_S * cells[1] / max(n + 3, 1),
        "parameters": SVD_S * K**3,
    }
    default = {"poses": ("problem.n_poses", "lower problem.n_poses"),
               "validation": ("problem.n_validation", "lower problem.n_validation"),
               "parameters": ("robot", f"an arm of {n} joints has {K} genes: calibrate a shorter chain "
                                       "(robot.base_link, robot.tip_link of a URDF)")}  # fmt: skip
    return ProblemSize(K, R, held, FLOAT * 2 * R, build, EVAL_S * max(M * n, R * K / 30), {**default, **(lower or {})})


def file_rows(path: str | Path) -> int:
    """The rows of a text file, estimated from its size and the length of its first lines (0
    when it is no regular file or cannot be read: its reader says why; a FIFO is not opened,
    which would wait for a writer)."""
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            return 0
        size = st.st_size
        with open(path, "rb") as f:
            sample = f.read(SAMPLE_BYTES)
    except OSError:
        return 0
    lines = sample.count(b"\n") or 1
    return math.ceil(size / (len(sample) / lines)) if sample else 0
