"""The size of a run, estimated before any work: memory and time from the arm's joints, the
poses (or measurement-file rows), the population and the evaluation budget. A run whose
estimate does not fit the memory this machine has available is refused with one line that
gives the estimate and the setting to lower, before anything is read or allocated.

The memory estimate adds what the largest steps hold, in float64 (8 bytes), with K genes
(``6n`` plus 3 for the base point, the hand or each further tool), ``r`` rows per pose (3 for
positions, 6 with orientations), M calibration and V validation poses, ``R = r M + n`` rows:

- **poses**: the pose Jacobians ``(M, 6, K)`` in four working copies (the chain rule, the
  reshape, the stacking, the weights), the forward kinematics' rotations ``(M, n + 1, 3, 3)``
  twice, the stacked Jacobian ``(R, K)`` the problem keeps and two more in the identifiability
  SVD; the text of the measurement file while it is read (about 160 bytes a cell);
- **validation**: the same Jacobians and file text for the validation poses;
- **parameters**: eight ``(K, K)`` matrices (the SVD's ``V``, the identity whose rows name
  unidentifiable genes, the null-space basis and its QR, the projector on the identifiable
  directions; the identified subspace's: the axes' tangent basis, the directions, the factor
  of the prior of those left at nominal);
- **population**: P genomes at once, each with two residual vectors ``(R,)`` (the linear cost's
  ``y - X J^T``), its genes twice and DEAP's objects (about 600 bytes); pose selection: the
  information matrices ``(m, m)`` and their per-pose blocks; CMA-ES: a ``(P, P)`` matrix.

All of it times 1.25 for what the sum leaves out (measured peaks, tracemalloc: 0.9 to 1.3 of the
sum on simulated, measured and 200-joint runs, tests/test_bad_inputs_more.py).

The time estimate adds the Jacobians (``1.5e-5 s`` per pose and gene), the SVDs, least squares
and null-space bookkeeping (``1.2e-8 s K^3`` plus ``5e-8 s R K min(R, K)``), the cost evaluations
(``3e-8 s`` per evaluation, pose and joint, or per row and gene for the linear cost, plus
``3e-4 s`` for DEAP's handling of the individual) and the file reading (``2e-4 s`` per row), constants measured on a loaded 2-core machine (a 500-joint
arm: 400 s; a 100 000-row file: 130 s). It is said, not enforced.

Available memory: ``MemAvailable`` of ``/proc/meminfo`` (elsewhere ``os.sysconf``'s free
pages); the environment variable ``ZRP_GA_MEMORY`` (``8G``, ``500M``, bytes) replaces it, to
allow a run the estimate overrates or to keep a shared machine's runs smaller.

>>> s = Size(joints=6, genes=42, poses=30, validation=100, rows_per_pose=6, population=40, evaluations=460)
>>> round(memory(s) / 1e6, 1), round(seconds(s), 1)
(2.0, 0.2)
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import stat
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

ENV = "ZRP_GA_MEMORY"
FLOAT = 8  # bytes
JACOBIAN_COPIES = 4
CELL_BYTES = 160  # a measurement file's cell while pandas holds it as text (measured: ~125)
INDIVIDUAL_BYTES = 600  # a DEAP individual's objects beside its genes
MARGIN = 1.25  # for what the sum leaves out (Python objects, short-lived copies): measured peaks were 0.9-1.3 of it
INDIVIDUAL_S = 3e-4  # per evaluation: DEAP's copying, selection and variation of an individual
FILE_ROW_S = 2e-4
JACOBIAN_S = 1.5e-5  # per pose and gene: every Jacobian of a run (problem, ranges, projector, judge)
SVD_S = 1.2e-8  # per K^3
ROWS_S = 5e-8  # per R K min(R, K): SVDs and least squares of the stacked Jacobian
EVAL_S = 3e-8  # per evaluation, pose and joint (or row and gene)
SAMPLE_BYTES = 64 * 1024  # of a file, read to estimate its rows
LONG_S = 600  # a run estimated to take longer is announced


@dataclasses.dataclass(frozen=True)
class Size:
    """What a run's size depends on: ``joints`` n, ``genes`` K, calibration ``poses`` M and
    ``validation`` poses V, ``rows_per_pose`` r (3 or 6), genomes evaluated at once
    (``population``), cost ``evaluations`` in all (None: not known), measurement-file cells to
    read (``cells``: calibration, validation), for pose selection the ``subset`` size k (0: a
    calibration), and whether the optimiser is ``cmaes`` (the ``cma`` package holds a
    ``(lambda, lambda)`` matrix)."""

    joints: int
    genes: int
    poses: int
    validation: int
    rows_per_pose: int
    population: int
    evaluations: int | None
    cells: tuple[int, int] = (0, 0)
    subset: int = 0
    cmaes: bool = False

    @property
    def rows(self) -> int:
        return self.rows_per_pose * self.poses + self.joints


def memory_parts(s: Size) -> dict[str, float]:
    """Bytes by what drives them: ``poses``, ``validation``, ``parameters``, ``population``
    (module docstring)."""
    K, n, R = s.genes, s.joints, s.rows
    jac = lambda M: FLOAT * (JACOBIAN_COPIES * 6 * M * K + 2 * 9 * M * (n + 1))
    if s.subset:  # pose selection: each genome's information matrix and its blocks
        per_genome = FLOAT * (s.subset * s.rows_per_pose * K + 2 * K * K + 2 * s.subset)
    else:
        per_genome = FLOAT * (2 * R + 2 * K) + INDIVIDUAL_BYTES
    parts = {
        "poses": jac(s.poses) + FLOAT * 3 * R * K + CELL_BYTES * s.cells[0],
        "validation": jac(s.validation) + CELL_BYTES * s.cells[1],
        "parameters": FLOAT * 8 * K * K,
        "population": s.population * per_genome + FLOAT * s.cmaes * s.population**2,
    }
    return {k: MARGIN * v for k, v in parts.items()}


def memory(s: Size) -> float:
    """Bytes the run needs at most (module docstring)."""
    return sum(memory_parts(s).values())


def seconds(s: Size) -> float:
    """Seconds the run takes, roughly (module docstring); without a known number of
    evaluations, the time before the optimiser's."""
    K, n, R = s.genes, s.joints, s.rows
    t = JACOBIAN_S * (s.poses + s.validation) * K + SVD_S * K**3 + ROWS_S * R * K * min(R, K)
    t += FILE_ROW_S * sum(s.cells) / max(n + 3, 1)
    if s.evaluations:
        t += s.evaluations * (INDIVIDUAL_S + EVAL_S * (s.subset * K * K if s.subset else max(s.poses * n, R * K / 30)))
    return t


def _slowest(s: Size) -> str:
    """Which part of the estimate drives the time: ``parameters`` (the SVDs), ``poses`` or
    ``population`` (the evaluations)."""
    K = s.genes
    parts = {
        "parameters": SVD_S * K**3,
        "poses": JACOBIAN_S * s.poses * K + ROWS_S * s.rows * K * min(s.rows, K) + FILE_ROW_S * s.cells[0] / (s.joints + 3),
    }
    parts["population"] = seconds(s) - sum(parts.values())
    return max(parts, key=parts.get)


def parse_bytes(text: str) -> float:
    """``8G``, ``500M``, ``64k`` or a number of bytes; ValueError naming ZRP_GA_MEMORY."""
    t = str(text).strip().upper().removesuffix("B").removesuffix("I")
    scale = {"K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}.get(t[-1:], 1)
    try:
        value = float(t[:-1] if scale > 1 else t) * scale
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{ENV}: must be an amount of memory such as 8G or 500M, got {text!r}")
    return value


def available_bytes(environ: dict | None = None) -> float:
    """Memory this run may use: ``ZRP_GA_MEMORY`` if set, else what the kernel says is
    available (``MemAvailable``), else the free pages; inf when none can be read."""
    environ = os.environ if environ is None else environ
    if environ.get(ENV):
        return parse_bytes(environ[ENV])
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return math.inf


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


def _human(b: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def _duration(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.0f} min" if s < 7200 else f"{s / 3600:.1f} h"


def check(s: Size, lower: dict[str, tuple[str, str]], available: float | None = None) -> None:
    """Refuse (ValueError, one line) a run whose memory estimate exceeds ``available`` (default:
    :func:`available_bytes`), naming the estimate, its largest part and the setting to lower
    (``lower``: part -> (config key, what to do)); log the estimate otherwise, as a warning when
    the run will take long."""
    parts = memory_parts(s)
    need, have = sum(parts.values()), available_bytes() if available is None else available
    t = seconds(s)
    if need <= have:
        memory_said = f"{_human(need)} of memory, {_human(have)} available"
        if t > LONG_S:  # said on the console before the run starts, so that it can be stopped at once
            log.warning(
                "this run will take about %s (and %s); to go faster: %s", _duration(t), memory_said, lower[_slowest(s)][1]
            )
        else:
            log.debug("size: about %s and %s", _duration(t), memory_said)
        return
    top = max(parts, key=parts.get)
    shares = ", ".join(f"{k} {_human(v)}" for k, v in sorted(parts.items(), key=lambda kv: -kv[1]) if v >= 0.01 * need)
    key, advice = lower[top]
    raise ValueError(f"{key}: the run would need about {_human(need)} of memory ({shares}; {_duration(t)}), this machine "
                     f"has {_human(have)} available: {advice} (or set {ENV} to allow more)")  # fmt: skip


# --- from a config -------------------------------------------------------------------------------
def _get(node: Any, key: str, default: Any = None) -> Any:
    value = node.get(key, default) if hasattr(node, "get") else getattr(node, key, default)
    return default if value is None else value


def of_config(cfg: Any, n: int) -> tuple[Size, dict[str, str]]:
    """The :class:`Size` of a composed config (``zrp_ga.config.Config``) for an arm of ``n``
    joints, and for each part of the estimate the setting that drives it."""
    from zrp_ga.data import resolve

    p, pop = cfg.problem, cfg.population
    target = str(_get(cfg.algorithm, "_target_", ""))
    kind = str(_get(p, "_target_", ""))
    orientation = bool(_get(p, "use_orientation", False)) if "measured" in kind else not bool(_get(p, "position_only", False))
    r = 6 if orientation else 3
    measured = bool(_get(p, "calibration_file"))  # registered to the data: the base point and the hand are genes
    K = (
        6 * n
        + 3 * (measured or bool(_get(p, "identify_base", False)))
        + 3 * (orientation if measured else bool(_get(p, "identify_hand", False)))
    )
    columns = n + 3 + 3 * orientation
    lower = {"parameters": ("robot", f"an arm of {n} joints has {K} genes: calibrate a shorter chain "
                                     "(robot.base_link, robot.tip_link of a URDF)"),
             "population": ("population", "lower population.mu and population.lambda_")}  # fmt: skip
    cells, M, V = [0, 0], 0, 0
    files = [("calibration_file", 0), ("validation_file", 1)]
    if measured:
        rows = [file_rows(resolve(str(_get(p, f)))) if _get(p, f) else 0 for f, _ in files]
        cells = [rows[0] * columns, rows[1] * columns]
        fraction = float(_get(p, "validation_fraction", 0.0))
        M, V = (rows[0], rows[1]) if rows[1] else (round(rows[0] * (1 - fraction)), round(rows[0] * fraction))
        lower["poses"] = ("problem.calibration_file", f"calibrate on fewer of its about {rows[0]} rows")
        lower["validation"] = (
            ("problem.validation_file", f"validate on fewer of its about {rows[1]} rows") if rows[1] else lower["poses"]
        )
    elif "selection" in kind:
        M, V = int(_get(p, "n_candidates", 0)), int(_get(p, "n_validation", 0))
        lower["poses"], lower["validation"] = (
            ("problem.n_candidates", "lower problem.n_candidates"),
            ("problem.n_validation", "lower problem.n_validation"),
        )
    else:
        M, V = int(_get(p, "n_poses", 1)), int(_get(p, "n_validation", 0))
        lower["poses"], lower["validation"] = (
            ("problem.n_poses", "lower problem.n_poses"),
            ("problem.n_validation", "lower problem.n_validation"),
        )
    mu, lam = int(_get(pop, "mu", 1)), int(_get(pop, "lambda_", 1))
    if target.endswith("cmaes.CMAES"):
        P = lam
    elif target.endswith(("lm.LM", "exchange.Exchange")):
        P = 1
    elif target.endswith("random_search.RandomSearch"):
        P = int(_get(cfg.algorithm, "batch", 100))
        lower["population"] = ("algorithm.batch", "lower algorithm.batch")
    else:
        P = mu + lam
    generations, max_evals = _get(pop, "generations"), _get(pop, "max_evals")
    evals = [v for v in (max_evals, generations and mu + generations * lam) if v]
    subset = int(_get(p, "k", 0)) if "selection" in kind else 0
    cmaes = target.endswith("cmaes.CMAES")
    return Size(n, K, M, V, r, P, min(evals) if evals else None, (cells[0], cells[1]), subset, cmaes), lower


def check_config(cfg: Any, robot: Any, available: float | None = None) -> Size:
    """:func:`check` the run of ``cfg`` on ``robot`` (a ZRPRobot) before its problem is built."""
    size, lower = of_config(cfg, int(robot.n))
    check(size, lower, available)
    return size
