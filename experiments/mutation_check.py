"""Planted bugs, one at a time, and whether the tests named for each one catch it.

Each plant is one dict in ``PLANTS``: the ``file`` (relative to the repository), the exact ``old``
text (it must occur exactly once: a plant whose text has moved is reported as stale, not as
caught), the ``new`` text, the ``tests`` expected to catch it and ``what`` the bug is. For each
plant the script applies it to a copy of the repository (the working tree is never touched),
runs ``python -m pytest -x -q -p no:cacheprovider TESTS`` there with the copy first on
``PYTHONPATH``, records caught (pytest failed) or survived (it passed), and puts the file back.
The named test files are first run once without any plant: they must pass, or a catch means
nothing. The table goes to ``experiments/results/mutation_check.md``.

    python experiments/mutation_check.py                 # every plant
    python experiments/mutation_check.py --only sbx-     # plants whose name starts so
    python experiments/mutation_check.py --list          # the plants, nothing run

To add a plant, append a dict to ``PLANTS`` (the report and run-layer ones go at the end).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "experiments" / "results" / "mutation_check.md"
TIMEOUT_S = 900  # per pytest call: a plant that makes a test hang counts as caught ("timeout")

OPS = "tests/test_operator_distributions.py"
REG = "tests/test_registration_values.py"
WARN = "tests/test_warning_paths.py"
MODEL = ["tests/test_so3.py", "tests/test_kinematics.py"]
UNITS = ["tests/test_measurement_files.py", "tests/test_measurement_units.py"]
REPORT_STATS = ["tests/test_report_stats.py", "tests/test_report.py"]
REPORT_SENTENCES = ["tests/test_report_sentences.py"]
SHAPES = "tests/test_operators_shapes.py"
KERNELS = "tests/test_kernels.py"
SURVIVAL = "tests/test_survival.py"
COMP_FRAMES = "tests/test_compensation_frames.py"
COMP_TABLES = "tests/test_compensation_tables.py"
COMP_INPUTS = "tests/test_compensation_inputs.py"
IDENTIFIED = "tests/test_identified.py"
MASKS = "tests/test_parameter_masks.py"
API_INPUTS = "tests/test_api_inputs.py"
CONSOLE = "tests/test_console_warnings.py"

PLANTS: list[dict] = [
    # --- operators: the distributions ---------------------------------------------------------
    dict(name="sbx-bound-exponent", file="zrp_ga/operators/crossover.py",
         old="alpha = 2.0 - beta ** -(eta + 1.0)", new="alpha = 2.0 - beta ** -eta", tests=[OPS],
         what="SBX: the bound's term beta_b^-(eta+1) with exponent eta"),
    dict(name="sbx-spread-exponent", file="zrp_ga/operators/crossover.py",
         old="power = 1.0 / (eta + 1.0)", new="power = 1.0 / (eta + 2.0)", tests=[OPS],
         what="SBX: spread factor to the power 1/(eta+2) instead of 1/(eta+1)"),
    dict(name="sbx-children-not-swapped", file="zrp_ga/operators/crossover.py",
         old="flip = rng.random(A.shape) <= 0.5", new="flip = rng.random(A.shape) <= 0.0", tests=[OPS],
         what="SBX: the lower child always goes to the first parent"),
    dict(name="polynomial-bound-exponent", file="zrp_ga/operators/mutation.py",
         old="(1.0 - d1) ** (eta + 1.0)", new="(1.0 - d1) ** eta", tests=[OPS],
         what="polynomial mutation: the lower bound's term with exponent eta instead of eta+1"),
    dict(name="polynomial-power", file="zrp_ga/operators/mutation.py",
         old="power = 1.0 / (eta + 1.0)", new="power = 1.0 / eta", tests=[OPS],
         what="polynomial mutation: power 1/eta instead of 1/(eta+1)"),
    dict(name="gaussian-sigma-unscaled", file="zrp_ga/operators/mutation.py",
         old="rng.standard_normal(r.size) * (sigma * (up - low))[c]", new="rng.standard_normal(r.size) * sigma", tests=[OPS],
         what="Gaussian mutation: sigma not scaled by the gene's range"),
    dict(name="gaussian-sigma-other-gene", file="zrp_ga/operators/mutation.py",
         old="(sigma * (up - low))[c]", new="(sigma * (up - low))[r % len(up)]", tests=[OPS],
         what="Gaussian mutation: the width of another gene"),
    dict(name="blend-alpha", file="zrp_ga/operators/crossover.py",
         old="g = (1.0 + 2.0 * alpha) * rng.random(A.shape) - alpha", new="g = (1.0 + alpha) * rng.random(A.shape) - alpha",
         tests=[OPS], what="BLX-alpha: gamma on [-alpha, 1] instead of [-alpha, 1 + alpha]"),
    dict(name="uniform-reset-range", file="zrp_ga/operators/mutation.py",
         old="rng.uniform(low, up, size=A.shape)", new="rng.uniform(low, up + 0.05 * (up - low), size=A.shape)", tests=[OPS],
         what="uniform reset: the range 5% too wide"),
    dict(name="tournament-size-plus-one", file="zrp_ga/operators/selection.py",
         old="size=(k, size))", new="size=(k, size + 1))", tests=[OPS],
         what="tournament: one entrant more than asked"),
    dict(name="segment-never-last-locus", file="zrp_ga/operators/base.py",
         old="x = (r[0] * span).astype(np.intp)", new="x = (r[0] * (span - 1)).astype(np.intp)", tests=[OPS],
         what="segments: the first end never on the last locus (pairs not uniform)"),
    dict(name="rotation-shift-range", file="zrp_ga/operators/rotation.py",
         old="shift = 1 + (rng.random(N) * (j - i)).astype(np.intp)", new="shift = 1 + (rng.random(N) * (j - i - 1)).astype(np.intp)",
         tests=[OPS], what="rotation: the largest shift never drawn"),
    dict(name="block-choice-uniform", file="zrp_ga/operators/base.py",
         old='pick = np.searchsorted(np.cumsum(sizes), rng.random(N) * sizes.sum(), side="right")',
         new="pick = rng.integers(0, len(sizes), N)", tests=[OPS],
         what="block moves: blocks chosen alike instead of by size"),
    # --- operators and kernels: every genome size from one gene (issue 27) ---------------------
    dict(name="segments-one-gene-pair", file="zrp_ga/operators/base.py",
         old="    pair = span >= 2\n", new="    pair = span >= 1\n", tests=[SHAPES],
         what="segments: a pair of loci drawn in a span of one gene (a one-gene genome or block inverted or rotated past its end)"),
    dict(name="one-point-one-gene", file="zrp_ga/operators/crossover.py",
         old="    if K < 2:\n        return ind1, ind2\n", new="", tests=[SHAPES],
         what="one-point crossover of one-gene genomes draws a cut point from an empty range"),
    dict(name="two-point-two-genes", file="zrp_ga/operators/crossover.py",
         old="    if K == 2:\n        lo, hi = np.ones(N, dtype=np.intp), np.full(N, 2)\n", new="", tests=[SHAPES],
         what="two-point crossover of two-gene genomes exchanges nothing"),
    dict(name="block-none-usable", file="zrp_ga/operators/base.py",
         old="    if not len(usable):\n        return np.zeros(N, dtype=np.intp), np.zeros(N, dtype=np.intp)\n", new="",
         tests=[SHAPES], what="block moves when no block has two genes (a genome of one-gene blocks)"),
    dict(name="reverse-mirror-off-by-one", file="zrp_ga/operators/base.py",
         old="np.asarray(i)[:, None] + np.asarray(j)[:, None] - k, k)", new="np.asarray(i)[:, None] + np.asarray(j)[:, None] + 1 - k, k)",
         tests=[SHAPES], what="inversion: each locus takes the gene one past its mirror (reads past the segment)"),
    dict(name="rotate-shift-sign", file="zrp_ga/operators/base.py",
         old="i + (k - i - np.asarray(shift)[:, None]) % length, k)", new="i + (k - i - np.asarray(shift)[:, None] - 1) % length, k)",
         tests=[SHAPES], what="rotation: shifted one place more than drawn (a length-two segment never moves)"),
    dict(name="kernel-layout-no-joint", file="zrp_ga/model/kinematics.py",
         old="    if U.ndim != 3 or n < 1:\n", new="    if U.ndim != 3:\n", tests=[KERNELS],
         what="cost kernels: an arm of no joint passed to the kernels (the matrix kernel reads joint 1)"),
    dict(name="jacobian-axes-unchecked", file="zrp_ga/model/error_model.py",
         old="    if n < 1 or u0.shape != (n, 3) or b0.shape != (n + 1, 3) or prism.shape != (n,):\n",
         new="    if n < 1 or b0.shape != (n + 1, 3) or prism.shape != (n,):\n", tests=[KERNELS],
         what="Jacobian kernel: axes of another arm passed unchecked (reads past u0)"),
    dict(name="numpy-twin-transposed", file="zrp_ga/model/_numpy_kernels.py",
         old="X = np.stack([ci * x + si * (uy * z - uz * y) + d * ux,", new="X = np.stack([ci * x - si * (uy * z - uz * y) + d * ux,",
         tests=[KERNELS], what="the numpy twin of the kernels: one component of each rotation with -sin q"),
    # --- survival (issue 27) ----------------------------------------------------------------------
    dict(name="elite-ranked-by-offspring", file="zrp_ga/algorithms/ga.py",
         old="rank(Pc)[:, :elite]", new="rank(Qc)[:, :elite]", tests=[SURVIVAL],
         what="generational survival: the elite parents picked by the offspring's ranking"),
    dict(name="short-generation-keeps-strategy", file="zrp_ga/algorithms/ga.py",
         old="strategy = ga.strategy if lam >= mu else Strategy.mu_plus_lambda", new="strategy = ga.strategy",
         tests=[SURVIVAL], what="a generation cut short by max_evals (fewer children than mu) survives by its strategy: the population shrinks"),
    # --- registration ---------------------------------------------------------------------------
    dict(name="registration-rms-is-mean", file="zrp_ga/model/registration.py",
         old="return float(np.sqrt(np.mean(self.errors**2)))", new="return float(np.mean(self.errors))", tests=[REG],
         what="registration: the RMS replaced by the mean distance"),
    dict(name="far-registration-doubled", file="zrp_ga/problems/measured.py",
         old="FAR_REGISTRATION = 0.02", new="FAR_REGISTRATION = 0.04", tests=[REG],
         what="registration far off: 4% of the reach instead of 2%"),
    dict(name="far-point-doubled", file="zrp_ga/io/measurements.py",
         old="> 3.0 * (reach + TOOL_ALLOWANCE_M)", new="> 6.0 * (reach + TOOL_ALLOWANCE_M)", tests=[REG],
         what="a measured point far from the others: six reaches instead of three"),
    # --- warnings and what is returned ----------------------------------------------------------
    dict(name="validation-warning-never", file="zrp_ga/run/summary.py",
         old='if np.isfinite(val["calibrated"]) and val["calibrated"] > val["nominal"]:',
         new='if np.isfinite(val["calibrated"]) and val["calibrated"] > 10 * val["nominal"]:', tests=[WARN],
         what="the validation-worse warning only at 10x the nominal error"),
    dict(name="diverged-keeps-optimiser", file="zrp_ga/run/summary.py",
         old="return result.x is None or not np.isfinite(result.cost) or result.cost > nominal_cost",
         new="return result.x is not None and result.cost > nominal_cost", tests=[WARN],
         what="a diverged optimiser's result returned instead of the nominal arm"),
    # --- the report (the coordinator adds the statistics and run-layer plants below) ------------
    dict(name="report-validation-key", file="zrp_ga/report/runs.py",
         old='self.summary.get("validation_rms_mm")', new='self.summary.get("validation_rms")',
         tests=["tests/test_report_runs.py"], what="report: every run's validation error read as missing (NaN)"),
    # --- the model ------------------------------------------------------------------------------
    dict(name="rodrigues-sign", file="zrp_ga/model/so3.py",
         old="return (1.0 - np.cos(q)) * A + np.sin(q) * skew(u) + _E", new="return (1.0 - np.cos(q)) * A - np.sin(q) * skew(u) + _E",
         tests=MODEL, what="Rodrigues' formula with -sin q (the transposed rotation)"),
    dict(name="reference-chain-transposed", file="zrp_ga/model/kinematics.py",
         old="R = R @ so3.rodrigues(q[i], robot.u0[i])", new="R = R @ so3.rodrigues(q[i], robot.u0[i]).T",
         tests=MODEL, what="forward_reference: each joint's rotation transposed"),
    dict(name="forward-kernel-transposed", file="zrp_ga/model/_kernels.py",
         old="ci, si = c[i], s[i]", new="ci, si = c[i], -s[i]",
         tests=MODEL, what="the compiled forward kinematics: each joint's rotation transposed (R(-q))"),
    dict(name="rodrigues-kernel-transposed", file="zrp_ga/model/_kernels.py",
         old="ci, si, ti = c[i], s[i], t[i]", new="ci, si, ti = c[i], -s[i], t[i]",
         tests=MODEL, what="the Rodrigues pose-cost kernel: each joint's rotation transposed"),
    dict(name="matrix-kernel-transposed", file="zrp_ga/model/_kernels.py",
         old="q00, q01, q02, q10, q11, q12, q20, q21, q22 = _rotation(ci, si, vi, ux, uy, uz)",
         new="q00, q10, q20, q01, q11, q21, q02, q12, q22 = _rotation(ci, si, vi, ux, uy, uz)",
         tests=MODEL, what="the matrix pose-cost kernel: joints 2..n rotations transposed"),
    # --- units ----------------------------------------------------------------------------------
    dict(name="mm-factor", file="zrp_ga/io/measurements.py",
         old='LENGTH = {"m": 1.0, "mm": 1e-3}', new='LENGTH = {"m": 1.0, "mm": 1e-2}',
         tests=UNITS, what="measurement files: a millimetre read as 1e-2 m"),
    dict(name="std-not-scaled", file="zrp_ga/io/measurements.py",
         old="std = np.column_stack([col[c] for c in fmt.std]) * u.length", new="std = np.column_stack([col[c] for c in fmt.std])",
         tests=UNITS, what="measurement files: standard deviations left in file units"),
    dict(name="prismatic-not-scaled", file="zrp_ga/io/measurements.py",
         old='col[c] * (u.length if t == "P" else u.joint)', new='col[c] * (1.0 if t == "P" else u.joint)',
         tests=UNITS, what="measurement files: prismatic joint values left in file units"),
    dict(name="robot-file-mm-factor", file="zrp_ga/io/robot_files.py",
         old='LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}', new='LENGTH_UNITS = {"m": 1.0, "mm": 1e-2}',
         tests=["tests/test_robot_files.py"], what="robot files: a millimetre read as 1e-2 m"),
    # --- the run directory: resume, lock, damaged jobs, temporary files -------------------------
    dict(name="resume-ignores-checkpoint", file="zrp_ga/run/build.py",
         old="p = build(cfg, out, state, choices, cache, task)", new="p = build(cfg, out, None, choices, cache, task)",
         tests=["tests/test_resume_checks.py"], what="resume starts the run over instead of continuing its checkpoint"),
    dict(name="resume-skips-input-check", file="zrp_ga/run/build.py",
         old="        check_inputs(p, recorded)\n", new="",
         tests=["tests/test_resume_checks.py"], what="resume continues a checkpoint on a changed robot or data file"),
    dict(name="lock-not-taken", file="zrp_ga/run/directory.py",
         old="        lock.acquire()\n", new="        pass\n",
         tests=["tests/test_run_directory.py"], what="two runs may write into one directory (the lock not taken)"),
    dict(name="damaged-job-kept", file="zrp_ga/run/sweep.py",
         old='damaged = directory.damage(out) if directory.status(out) == "done" else None', new="damaged = None",
         tests=["tests/test_run_directory.py"], what="a sweep job with a damaged summary or convergence log kept as finished"),
    dict(name="checkpoint-tmp-left", file="zrp_ga/run/checkpoint.py",
         old="        tmp.unlink(missing_ok=True)\n", new="",
         tests=["tests/test_run_directory.py"], what="a failed checkpoint write leaves its temporary file"),
    # --- the report's statistics ------------------------------------------------------------------
    dict(name="holm-no-step-down-maximum", file="zrp_ga/report/stats.py",
         old="adjusted = np.maximum.accumulate((m - np.arange(m)) * p[order])", new="adjusted = (m - np.arange(m)) * p[order]",
         tests=REPORT_STATS, what="Holm: the step-down maximum left out (adjusted p-values no longer monotone)"),
    dict(name="nemenyi-cd-no-sqrt2", file="zrp_ga/report/stats.py",
         old="cd = stats.studentized_range.ppf(1 - alpha, k, np.inf) / math.sqrt(2) * se",
         new="cd = stats.studentized_range.ppf(1 - alpha, k, np.inf) * se",
         tests=REPORT_STATS, what="Nemenyi: the critical difference without the division by sqrt 2"),
    dict(name="nemenyi-p-no-sqrt2", file="zrp_ga/report/stats.py",
         old="q = math.sqrt(2) * abs(mean[a] - mean[b]) / se", new="q = abs(mean[a] - mean[b]) / se",
         tests=REPORT_STATS, what="Nemenyi: pairwise p-values without the factor sqrt 2"),
    # --- the report's sentences (issue 27): against made-up studies whose answers are known ------------
    dict(name="report-worst-named-best", file="zrp_ga/report/compare.py",
         old='best = g.groupby("configuration", sort=False)[q["column"]].median().idxmin()',
         new='best = g.groupby("configuration", sort=False)[q["column"]].median().idxmax()',
         tests=REPORT_SENTENCES, what="report: the configuration with the highest median named the best of its instance"),
    dict(name="report-lost-counted-beaten", file="zrp_ga/report/stats.py",
         old="return BETTER if direction > 0 else WORSE", new="return BETTER",
         tests=REPORT_SENTENCES, what="report: a rival the configuration loses to (significantly) counted as beaten"),
    dict(name="report-effect-wrong-side", file="zrp_ga/report/conclusions.py",
         old='return str(row["a"]), FLIP.get(v, v), 1 - e, 1 - hi, 1 - lo', new='return str(row["a"]), FLIP.get(v, v), e, lo, hi',
         tests=REPORT_SENTENCES, what="report: the effect P(best ends lower) given from the other side of the pair"),
    dict(name="report-fifo-read", file="zrp_ga/report/runs.py",
         old='        regular_file(path, f"a run\'s {name}")', new='        path.exists() or regular_file(path, f"a run\'s {name}")',
         tests=["tests/test_report_runs.py"], what="report: a run's file that exists read without checking it is a regular file (a FIFO hangs it)"),
    # --- compensation (zrp_ga.compensation): frames, sizes, units, setups ---------------------------
    dict(name="comp-orientation-frame", file="zrp_ga/compensation/frames.py",
         old="return p @ T[:3, :3].T + T[:3, 3], None if R is None else T[:3, :3] @ R",
         new="return p @ T[:3, :3].T + T[:3, 3], R", tests=[COMP_FRAMES],
         what="compensation: orientation targets in the tracker's frame (or a work object) not turned into the base frame"),
    dict(name="comp-prismatic-size", file="zrp_ga/compensation/result.py",
         old='out["dq_mm"] = dq[:, pri].max(axis=1) * 1e3', new='out["dq_mm"] = np.degrees(dq[:, pri].max(axis=1))',
         tests=[COMP_TABLES], what="compensation: a prismatic joint's correction reported as if it were an angle"),
    dict(name="comp-seed-units", file="zrp_ga/compensation/compensate.py",
         old="return q * np.where(robot.prismatic, LENGTH[pr.length_unit], ANGLE[unit])", new="return q",
         tests=[COMP_TABLES], what="compensation: the first seed read in radians whatever the program's joint unit"),
    dict(name="comp-length-unit", file="zrp_ga/compensation/program.py",
         old="p = None if p_file is None else p_file * LENGTH[length]", new="p = p_file",
         tests=[COMP_TABLES], what="compensation: a program's positions left in its length unit (mm read as m)"),
    dict(name="comp-angle-unit-auto", file="zrp_ga/compensation/program.py",
         old='return "deg" if beyond.any() or (joint_unit == "deg" and cols.joints is not None) else "rad"', new='return "rad"',
         tests=[COMP_TABLES], what="compensation: orientations in degrees read as radians"),
    dict(name="comp-quaternion-order", file="zrp_ga/compensation/orientation.py",
         old="return Rotation.from_quat(values[:, [1, 2, 3, 0]]).as_matrix()", new="return Rotation.from_quat(values).as_matrix()",
         tests=[COMP_TABLES], what="compensation: a quaternion's q1..q4 read as x, y, z, w instead of ABB's w, x, y, z"),
    dict(name="comp-kuka-names", file="zrp_ga/compensation/orientation.py",
         old='NAMED = {"ZYX": ("A", "B", "C")', new='NAMED = {"ZYX": ("C", "B", "A")',
         tests=[COMP_TABLES], what="compensation: KUKA's A and C swapped"),
    dict(name="comp-wrist-sign", file="zrp_ga/compensation/configuration.py",
         old="np.dot(u[3], np.cross(u[4], u[5]))", new="np.dot(u[3], np.cross(u[3], u[5]))",
         tests=[COMP_TABLES], what="compensation: the wrist's branch sign from the wrong axes (always 0)"),
    dict(name="comp-base-foot", file="zrp_ga/compensation/frames.py",
         old="origin = axis1.point + s * z", new="origin = axis1.point",
         tests=[COMP_FRAMES], what="base frame by convention: the origin not at the common normal's foot (the first link's error kept)"),
    dict(name="comp-circle-sense", file="zrp_ga/compensation/frames.py",
         old="direction = normal if np.sum(turns) > 0 else -normal", new="direction = normal",
         tests=[COMP_FRAMES], what="circles: an axis's sense not taken from the way the joint turned"),
    dict(name="comp-work-object-z", file="zrp_ga/compensation/frames.py",
         old="z = np.cross(x, oy)", new="z = np.cross(oy, x)", tests=[COMP_FRAMES],
         what="work object: z = (Y - O) x x, the frame turned half a turn about x"),
    dict(name="comp-base-default", file="zrp_ga/compensation/setups.py",
         old='if setup == "calibration" or (setup == "auto" and arms.base is None):', new='if setup in ("calibration", "auto"):',
         tests=[COMP_FRAMES], what="compensation: a measured run's base frame left the registration's by default"),
    dict(name="comp-work-object-size", file="zrp_ga/compensation/setups.py",
         old="k = float(np.sqrt(1.0 + 2.0 * (reach_from_origin_m / points_apart_m) ** 2))",
         new="k = float(1.0 + 2.0 * reach_from_origin_m / points_apart_m)", tests=[COMP_FRAMES],
         what="compensation: the size a work object's point errors leave, stated with the wrong formula"),
    dict(name="comp-nominal-unchecked", file="zrp_ga/compensation/arms.py",
         old="    if dp > NOMINAL_SLACK * cp + NOMINAL_FLOOR_M or da > NOMINAL_SLACK * ca + NOMINAL_FLOOR_RAD:",
         new="    if False:", tests=[COMP_INPUTS],
         what="compensation: a --nominal arm that is not the run's accepted"),
    # --- issue 27 item 5: the code added since (identified subspace, uncertainty, coverage, robust
    # loss, noise, ROS file, targets, sizes), masks, units of a small volume, the API's inputs, warnings
    dict(name="subspace-se-rule-doubled", file="zrp_ga/model/subspace.py",
         old="1.0 / np.maximum(s[:exact], 1e-300) <= max_se", new="1.0 / np.maximum(s[:exact], 1e-300) <= 2 * max_se",
         tests=[f"{IDENTIFIED}::test_identified_directions_are_those_whose_standard_error_is_small"], what="identified subspace: directions kept up to twice the standard error problem.max_se allows"),
    dict(name="subspace-prior-uniform-factor", file="zrp_ga/model/subspace.py",
         old="factor = prior[:, None] * W[:, rank:] / np.sqrt(3.0)", new="factor = prior[:, None] * W[:, rank:]",
         tests=[f"{IDENTIFIED}::test_what_is_left_at_nominal_has_the_covariance_of_a_uniform_error_within_the_prior"], what="uncertainty of what was left at nominal: the prior's +-p taken as its standard deviation (not p/sqrt 3)"),
    dict(name="uncertainty-total-summed", file="zrp_ga/model/uncertainty.py",
         old='out["position_total_m"] = np.hypot(out["position_m"], out["position_unidentified_m"])',
         new='out["position_total_m"] = out["position_m"] + out["position_unidentified_m"]',
         tests=[f"{IDENTIFIED}::test_the_total_predicted_error_adds_the_two_parts_in_quadrature"], what="predicted error: the identified and unidentified parts added instead of in quadrature"),
    dict(name="uncertainty-noise-one-axis", file="zrp_ga/model/uncertainty.py",
         old="(3 * self.noise_m**2 if noise else 0.0)", new="(self.noise_m**2 if noise else 0.0)",
         tests=[f"{IDENTIFIED}::test_predicted_validation_rms_agrees_with_the_measured_one"], what="predicted validation RMS: the noise of one coordinate instead of three"),
    dict(name="coverage-gap-mean", file="zrp_ga/model/coverage.py",
         old="return float(d[:, 1].max())", new="return float(d[:, 1].mean())",
         tests=[f"{IDENTIFIED}::test_coverage_ranges_and_distances_by_brute_force"], what="coverage: the gap as the mean nearest distance instead of the largest"),
    dict(name="robust-huber-offset", file="zrp_ga/problems/robust.py",
         old="return np.where(big, 2.0 * root - 1.0, z)", new="return np.where(big, 2.0 * root, z)",
         tests=[f"{IDENTIFIED}::test_huber_is_scipys_by_hand"], what="Huber's loss without its -1 (not continuous at the scale)"),
    dict(name="noise-mad-unscaled", file="zrp_ga/problems/identify.py",
         old="MAD = 1.4826  # median absolute deviation", new="MAD = 1.0  # median absolute deviation",
         tests=[f"{IDENTIFIED}::test_planted_outliers_are_named_by_line_and_the_robust_fit_ignores_them"], what="robust noise: the median absolute deviation not scaled to a standard deviation"),
    dict(name="ros-base-link-turn", file="zrp_ga/io/ros_calibration.py",
         old='start = np.diag([-1.0, -1.0, 1.0, 1.0]) if world == "base_link" else np.eye(4)',
         new='start = np.eye(4)', tests=["tests/test_ros_calibration.py"],
         what="ur_description's file: base_link_inertia's half turn about z left out"),
    dict(name="targets-partial-by-default", file="zrp_ga/core/targets.py",
         old='partial = node.get("_partial_", False) if partial is None else partial',
         new='partial = node.get("_partial_", True) if partial is None else partial', tests=["tests/test_targets.py"],
         what="_target_ specs built as partials unless they say otherwise (Hydra builds them)"),
    dict(name="size-parameters-one-matrix", file="zrp_ga/problems/size.py",
         old='"parameters": FLOAT * 8 * K * K,', new='"parameters": FLOAT * K * K,', tests=["tests/test_budget.py"],
         what="budget: the parameter matrices counted once instead of eight K x K matrices"),
    dict(name="mask-last-tool-unnamed", file="zrp_ga/model/layout.py",
         old='for c in "xyz"] for t in range(2, layout.n_tools + 1)})', new='for c in "xyz"] for t in range(2, layout.n_tools)})',
         tests=[f"{MASKS}::test_every_offered_name_can_be_named_and_fixes_what_it_stands_for"], what="masks: the last tool, offered by the refusal's list of valid names, cannot be named"),
    dict(name="mask-links-of-one-joint", file="zrp_ga/model/layout.py",
         old="    if n >= 2:  # a one-joint arm has no link between two axes\n", new="    if True:\n",
         tests=[f"{MASKS}::test_every_offered_name_can_be_named_and_fixes_what_it_stands_for", f"{MASKS}::test_names_not_offered_are_refused"], what="masks: a one-joint arm accepts links, which stand for no parameter"),
    dict(name="units-small-volume", file="zrp_ga/io/measurements.py",
         old="spread * LENGTH[u] >= 0.01 * reach]", new="spread * LENGTH[u] >= 0.03 * reach]",
         tests=["tests/test_measurement_files.py::test_a_small_measured_volume_is_read_in_the_unit_it_was_written_in"], what="units: a measured volume under 3% of the reach (a 4 cm cube for a UR10) cannot be told metres"),
    dict(name="api-rotations-unchecked", file="zrp_ga/api.py",
         old="    so3.check_rotations(R, ", new="    (lambda *a: None)(R, ", tests=[f"{API_INPUTS}::test_rotation_matrices_that_are_no_rotations_are_refused_naming_the_row"],
         what="API: rotation matrices given in memory not checked to be rotations"),
    dict(name="api-seed-string-iterated", file="zrp_ga/api.py",
         old="if isinstance(seed, (str, bytes)) or not isinstance(seed, (Sequence, np.ndarray)):",
         new="if not isinstance(seed, (str, Sequence, np.ndarray)):", tests=[f"{API_INPUTS}::test_a_seed_that_is_no_whole_number_is_refused"],
         what='API: seed="abc" read as the list of seeds a, b, c'),
    dict(name="api-float16-accepted", file="zrp_ga/api.py",
         old="LOSSY_EPS = 1e-6", new="LOSSY_EPS = 1e-2", tests=[f"{API_INPUTS}::test_float16_numbers_are_refused_with_the_step_they_lose"],
         what="API: float16 numbers (3 significant digits) taken without a word"),
    dict(name="api-validation-alone", file="zrp_ga/api.py",
         old="        if validation is not None and data is None:\n", new="        if False:\n", tests=[f"{API_INPUTS}::test_validation_without_data_is_refused_not_a_simulated_calibration"],
         what="API: validation data without calibration data silently calibrate a simulated problem"),
    dict(name="warning-details-on-console", file="zrp_ga/core/errors.py",
         old="handlers += [h for h in logger.handlers if isinstance(h, logging.FileHandler)]",
         new="handlers += list(logger.handlers)", tests=[f"{CONSOLE}::test_the_default_run_says_one_line_per_warning_and_keeps_the_details"],
         what="warnings: the details (every unidentifiable direction) printed on the console too"),
    dict(name="warning-per-job", file="zrp_ga/run/assembly.py",
         old="    return text and of_kind\n", new="    return True\n", tests=[f"{CONSOLE}::test_a_sweep_says_each_warning_once_not_per_job"],
         what="warnings: every job of a sweep says the same warning again"),
    dict(name="terms-joint-twice", file="zrp_ga/model/terms.py",
         old="        if int(v) in out:  # two genes of one effect", new="        if False:  # two genes of one effect",
         tests=["tests/test_terms.py::test_bad_terms_settings_are_one_line_naming_the_key"],
         what="problem.terms: a joint named twice accepted (two genes of one effect, neither identifiable)"),
    dict(name="hydra-job-line-shown", file="zrp_ga/cli/main.py",
         old='    PREFIX = "Error executing job with overrides: "', new='    PREFIX = "(never written)"',
         tests=["tests/test_faults.py::test_a_jobs_error_is_our_one_line_without_hydras"],
         what="a job's error (a full disk) printed as Hydra's 'Error executing job with overrides' line and ours"),
]


def copy_tree(dest: Path) -> Path:
    """The repository without its environment, history and run outputs."""
    skip = shutil.ignore_patterns(".venv", ".git", "__pycache__", "multirun", "outputs", "*.egg-info", ".pytest_cache")
    shutil.copytree(ROOT, dest, ignore=skip, symlinks=True)
    return dest


def pytest(where: Path, tests: list[str]) -> tuple[int, float, str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(where), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    t0 = time.perf_counter()
    try:
        done = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests], cwd=where, env=env,
                              capture_output=True, text=True, timeout=TIMEOUT_S)  # fmt: skip
    except subprocess.TimeoutExpired:
        return -1, time.perf_counter() - t0, "timeout"
    lines = [ln for ln in done.stdout.splitlines() if ln.strip()]
    first_failure = next((ln for ln in lines if ln.startswith("FAILED") or ln.startswith("ERROR")), "")
    return done.returncode, time.perf_counter() - t0, first_failure or (lines[-1] if lines else done.stderr[-200:])


def check_imports(where: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(where))
    out = subprocess.run([sys.executable, "-c", "import zrp_ga; print(zrp_ga.__file__)"], cwd=where, env=env,
                         capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    if not out.startswith(str(where)):
        sys.exit(f"mutation_check: the copy's zrp_ga is not the one imported ({out}); is another on PYTHONPATH?")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, help="plant names or name prefixes")
    ap.add_argument("--list", action="store_true", help="list the plants and stop")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    plants = [p for p in PLANTS if args.only is None or any(p["name"].startswith(o) for o in args.only)]
    if args.list:
        for p in plants:
            print(f"{p['name']:30} {p['file']:35} {p['what']}")
        return 0
    rows = []
    with tempfile.TemporaryDirectory(prefix="zrp_ga_mutation_") as tmp:
        where = copy_tree(Path(tmp) / "repo")
        check_imports(where)
        for tests in sorted({tuple(p["tests"]) for p in plants}):
            code, secs, line = pytest(where, list(tests))
            print(f"unplanted {' '.join(tests)}: {'pass' if code == 0 else 'FAIL'} ({secs:.0f} s)", flush=True)
            if code != 0:
                sys.exit(f"mutation_check: {' '.join(tests)} fail without any plant: {line}")
        for p in plants:
            path = where / p["file"]
            text = path.read_text()
            if text.count(p["old"]) != 1:
                rows.append((p, f"stale (old text found {text.count(p['old'])} times)", 0.0, ""))
                print(f"{p['name']}: stale", flush=True)
                continue
            path.write_text(text.replace(p["old"], p["new"]))
            try:
                code, secs, line = pytest(where, p["tests"])
            finally:
                path.write_text(text)
            result = "caught" if code == 1 else "survived" if code == 0 else "timeout" if code == -1 else f"caught (pytest exit {code})"
            rows.append((p, result, secs, line))
            print(f"{p['name']}: {result} ({secs:.0f} s) {line}", flush=True)
    write(args.out, rows, argv)
    caught = sum(r[1].startswith("caught") for r in rows)
    print(f"{caught} of {len(rows)} plants caught; table in {args.out}")
    return 0 if caught == len(rows) else 1


def _kept(out: Path, run: set[str]) -> dict[str, str]:
    """The table rows of ``out`` (by plant name) for plants not run now (``--only``)."""
    if not out.exists():
        return {}
    rows = [ln for ln in out.read_text().splitlines() if ln.startswith("| ") and not ln.startswith("| plant |")]
    return {ln.split(" | ")[0][2:]: ln for ln in rows if ln.split(" | ")[0][2:] not in run}


def write(out: Path, rows: list, argv: list[str] | None) -> None:
    """The table of ``rows``; with ``--only``, the other plants' rows of the existing table are kept."""
    args = argv if argv is not None else sys.argv[1:]
    cmd = " ".join(["python experiments/mutation_check.py", *args])
    kept = _kept(out, {p["name"] for p, *_ in rows}) if "--only" in args else {}
    new = {}
    for p, result, secs, line in rows:
        test = line.removeprefix("FAILED ").removeprefix("ERROR ").split(" - ")[0].replace("|", "\\|")
        tests = ", ".join(Path(t).name for t in p["tests"])
        new[p["name"]] = f"| {p['name']} | {p['file']} | {p['what']} | {tests} | {result} | {secs:.0f} | {test} |"
    table = [kept.get(p["name"]) or new.get(p["name"]) for p in PLANTS if p["name"] in kept or p["name"] in new]
    caught = sum(" | caught" in ln for ln in table)
    said = (f"the rows of the plants run now from `{cmd}`, the others kept from the table's previous runs" if kept
            else f"`{cmd}`")  # fmt: skip
    lines = [
        "# Mutation check: planted bugs and the tests that catch them",
        "",
        f"Command: {said} (each plant applied alone to a copy of the repository; the named test files run with "
        "`python -m pytest -x -q -p no:cacheprovider FILES`).",
        "",
        f"**{caught} of {len(table)} plants caught.**",
        "",
        "| plant | file | bug | tests | result | s | first failing test |",
        "| --- | --- | --- | --- | --- | ---: | --- |",
        *table,
    ]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())
