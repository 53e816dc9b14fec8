"""The memory budget (zrp_ga.run.budget): the limits a process has (the machine's available
memory, ``ulimit -v`` and ``-d``, cgroup v2 and v1 memory limits) each simulated and one real,
the refusal naming the one that binds; a sweep refused once before any job; the API refused
before any allocation; and a problem kind and an optimiser added through the README's recipe
alone, whose declared sizes the estimate uses."""

from __future__ import annotations

import json
import os
import re
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import zrp_ga
from zrp_ga import robots
from zrp_ga.algorithms import AlgorithmSize
from zrp_ga.model import kinematics
from zrp_ga.problems.size import calibration
from zrp_ga.run import budget

GiB = 2**30
LATER = 256 * 2**20  # what the budget keeps for the program's later mappings under an address-space limit


def _zrp_ga(*args: str, cwd: Path, env: dict | None = None, preexec=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zrp_ga.cli", *args, "progress=false"], capture_output=True, text=True,
                          cwd=cwd, env={**os.environ, **(env or {})}, preexec_fn=preexec, timeout=600)  # fmt: skip


def _one_line(proc: subprocess.CompletedProcess) -> str:
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("zrp-ga: error: "), proc.stderr
    return lines[0]


# --- each limit, simulated ----------------------------------------------------------------------
def _kernel(tmp_path: Path, available_kb: int, vm_kb: int = 0, data_kb: int = 0, cgroup: str = "0::/\n") -> tuple[Path, Path]:
    """A fake /proc (meminfo, self/status, self/cgroup) and an empty cgroup root."""
    proc, root = tmp_path / "proc", tmp_path / "cgroup"
    (proc / "self").mkdir(parents=True)
    root.mkdir()
    (proc / "meminfo").write_text(f"MemTotal:       32000000 kB\nMemFree:         1000000 kB\nMemAvailable:   {available_kb} kB\n")
    (proc / "self" / "status").write_text(f"Name:\tpython\nVmPeak:\t{vm_kb + 5} kB\nVmSize:\t{vm_kb} kB\nVmData:\t{data_kb} kB\n")
    (proc / "self" / "cgroup").write_text(cgroup)
    return proc, root


def _rlimits(monkeypatch, **soft: int) -> None:
    """``resource.getrlimit`` with the soft limits given by name (RLIMIT_AS=...), unlimited otherwise."""
    by_number = {getattr(resource, name): value for name, value in soft.items()}
    monkeypatch.setattr(resource, "getrlimit", lambda which: (by_number.get(which, resource.RLIM_INFINITY), resource.RLIM_INFINITY))


def test_the_machine_binds_without_process_limits(tmp_path, monkeypatch):
    _rlimits(monkeypatch)
    proc, root = _kernel(tmp_path, available_kb=8_000_000)
    lim = budget.memory_limit({}, proc, root)
    assert lim.bytes == 8_000_000 * 1024 and lim.says == "this machine has 8.19 GB available"


def test_the_address_space_limit_less_what_is_mapped(tmp_path, monkeypatch):
    _rlimits(monkeypatch, RLIMIT_AS=4 * GiB)
    proc, root = _kernel(tmp_path, available_kb=20_000_000, vm_kb=1_000_000)
    lim = budget.memory_limit({}, proc, root)
    assert lim.bytes == 4 * GiB - 1_000_000 * 1024 - LATER  # 4 GiB less the 1 GB VmSize less the program's later mappings
    assert lim.says.startswith("the process's address-space limit (ulimit -v: 4.29 GB") and "or raise ulimit -v" in lim.hint


def test_the_data_segment_limit_less_what_is_mapped(tmp_path, monkeypatch):
    _rlimits(monkeypatch, RLIMIT_AS=8 * GiB, RLIMIT_DATA=2 * GiB)
    proc, root = _kernel(tmp_path, available_kb=20_000_000, vm_kb=1_000_000, data_kb=300_000)
    lim = budget.memory_limit({}, proc, root)
    assert lim.bytes == 2 * GiB - 300_000 * 1024 - LATER and "data-segment limit (ulimit -d: 2.15 GB" in lim.says


def test_cgroup_v2_limits_from_the_process_up_less_the_working_set(tmp_path, monkeypatch):
    """The job's cgroup (2 GiB, 1 GiB charged of which 0.5 GiB inactive file pages) binds over
    its step's ("max": none) and its parent's (16 GiB, 10 GiB charged)."""
    _rlimits(monkeypatch)
    proc, root = _kernel(tmp_path, available_kb=30_000_000, cgroup="0::/slurm/job7/step0\n")
    files = {"slurm": (16 * GiB, 10 * GiB, 0), "slurm/job7": (2 * GiB, GiB, GiB // 2), "slurm/job7/step0": ("max", 900 * 2**20, 0)}
    for folder, (limit, current, inactive) in files.items():
        (root / folder).mkdir(parents=True)
        (root / folder / "memory.max").write_text(f"{limit}\n")
        (root / folder / "memory.current").write_text(f"{current}\n")
        (root / folder / "memory.stat").write_text(f"anon 1000\nfile 2000\nactive_file 10\ninactive_file {inactive}\n")
    lim = budget.memory_limit({}, proc, root)
    assert lim.bytes == 2 * GiB - (GiB - GiB // 2)  # 1.5 GiB; the parent leaves 6 GiB
    assert lim.says == f"the cgroup's memory limit ({root}/slurm/job7/memory.max: 2.15 GB, 537 MB in use) leaves 1.61 GB"
    assert len([x for x in budget.limits(proc, root) if "cgroup" in x.says]) == 2  # the step's "max" is no limit


def test_cgroup_v1_memory_controller(tmp_path, monkeypatch):
    _rlimits(monkeypatch)
    proc, root = _kernel(tmp_path, available_kb=30_000_000, cgroup="11:pids:/docker/abc\n4:memory:/docker/abc\n0::/\n")
    (root / "memory" / "docker" / "abc").mkdir(parents=True)
    (root / "memory" / "memory.limit_in_bytes").write_text("9223372036854771712\n")  # the root: no limit
    job = root / "memory" / "docker" / "abc"
    (job / "memory.limit_in_bytes").write_text(f"{3 * GiB}\n")
    (job / "memory.usage_in_bytes").write_text(f"{GiB}\n")
    (job / "memory.stat").write_text(f"cache 5\ninactive_file 7\ntotal_inactive_file {GiB // 4}\n")
    lim = budget.memory_limit({}, proc, root)
    assert lim.bytes == 3 * GiB - (GiB - GiB // 4) and str(job / "memory.limit_in_bytes") in lim.says


def test_the_environment_replaces_every_limit(tmp_path, monkeypatch):
    _rlimits(monkeypatch, RLIMIT_AS=GiB)
    proc, root = _kernel(tmp_path, available_kb=100)
    assert budget.memory_limit({"ZRP_GA_MEMORY": "3G"}, proc, root).bytes == 3 * GiB


def test_the_refusal_names_the_limit_that_binds(tmp_path, monkeypatch):
    """A run of 4 GB (estimated) on a machine with 19 GB available in a container of 3 GiB with
    1 GiB in use: refused by the container's limit, whatever the machine has."""
    _rlimits(monkeypatch)
    proc, root = _kernel(tmp_path, available_kb=19_000_000, cgroup="0::/\n")
    (root / "memory.max").write_text(f"{3 * GiB}\n")
    (root / "memory.current").write_text(f"{GiB}\n")
    e = budget.estimate(calibration(6, 36, 1000, 0, 6), AlgorithmSize(30_000, None, 0.0))
    assert 3.6e9 < e.bytes < 3.65e9  # 30,000 genomes of two 6006-row residuals, 96 kB each, times 1.25
    with pytest.raises(ValueError, match=re.escape(f"the cgroup's memory limit ({root}/memory.max: 3.22 GB, 1.07 GB in use) "
                                                   "leaves 2.15 GB: lower population.mu and population.lambda_ "
                                                   "(or give the container or job more memory)")):  # fmt: skip
        budget.check(e, budget.memory_limit({}, proc, root))
    budget.check(e, budget.memory_limit({}, proc, tmp_path / "no_cgroup"))  # the machine alone: it fits


def test_a_real_address_space_limit_refuses_with_its_line(tmp_path):
    """``ulimit -v 2G``: the 100,000-pose run (2.1 GB estimated) would fit the machine but not
    the process; refused naming the limit, before anything is allocated, no run directory."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 * GiB, 2 * GiB))

    proc = _zrp_ga("problem=multipose", "problem.n_poses=100000", f"hydra.run.dir={tmp_path}/run", cwd=tmp_path, preexec=limit)
    line = _one_line(proc)
    assert line.startswith("zrp-ga: error: problem.n_poses: the run would need about 2.")
    assert "the process's address-space limit (ulimit -v: 2.15 GB, " in line and line.endswith("(or raise ulimit -v)")
    assert not (tmp_path / "run").exists()


# --- a sweep, once -------------------------------------------------------------------------------
def test_a_sweep_whose_largest_job_does_not_fit_is_refused_once_with_no_directory(tmp_path):
    for launcher in ("basic", "zrp_ga"):
        sweep = tmp_path / launcher
        proc = _zrp_ga("-m", "population.mu=10,1000000000", "seed=0,1", "crossover=blend,sbx", f"hydra/launcher={launcher}",
                       f"hydra.sweep.dir={sweep}", cwd=tmp_path)  # fmt: skip
        line = _one_line(proc)
        assert line.startswith("zrp-ga: error: population: the sweep's largest job (population.mu=1000000000) would need "
                               "about 1.71 TB of memory (population 1.71 TB"), line  # fmt: skip
        assert "Launching" not in proc.stdout + proc.stderr and not sweep.exists()


def test_a_sweep_of_its_configs_params_names_the_largest_job(tmp_path):
    """experiment=population_sweep sweeps population.mu over 10 ... 200 in its params: with
    memory for the mu=100 job but not the mu=200 one, that job is named."""
    from zrp_ga import config

    need = {mu: budget.of_config(config.load(["experiment=population_sweep", f"population.mu={mu}"]), robots.get("puma560")).bytes
            for mu in (100, 200)}  # fmt: skip
    assert need[100] < need[200]
    env = {"ZRP_GA_MEMORY": str(int((need[100] + need[200]) / 2))}
    line = _one_line(_zrp_ga("-m", "experiment=population_sweep", f"hydra.sweep.dir={tmp_path}/s", cwd=tmp_path, env=env))
    assert "population: the sweep's largest job (population.mu=200) would need about" in line
    assert not (tmp_path / "s").exists()


# --- the API -------------------------------------------------------------------------------------
def test_the_api_refuses_before_allocating():
    """Without a budget, ``population={"mu": 10**9}`` asked numpy for 268 GiB (10^9 x 36 genes x 8 bytes)."""
    with pytest.raises(ValueError, match=r"^population: the run would need about 1\.71 TB of memory"):
        zrp_ga.calibrate("puma560", population={"mu": 10**9})


def test_the_api_counts_data_in_memory(monkeypatch):
    arm = robots.get("puma560")
    q = np.random.default_rng(0).uniform(-1, 1, (2000, 6))
    p = kinematics.forward(arm, q)[1]
    monkeypatch.setenv("ZRP_GA_MEMORY", "20M")
    with pytest.raises(ValueError, match=r"^data: the run would need about .* ZRP_GA_MEMORY allows 21 MB: calibrate on "
                                         r"fewer of its 2000 rows"):  # fmt: skip
        zrp_ga.calibrate(arm, (q, p), algorithm="lm")


# --- the parts of a calibration problem, by hand ------------------------------------------------
def test_a_calibration_problems_parts_by_hand():
    """``problems.size.calibration``'s parts from its docstring's formulas, written out here with
    the numbers of one shape (n = 6 joints, K = 42 genes, M = 30 and V = 100 poses of 6 rows):
    eight K x K float64 matrices for the parameters (8 x 42 x 42 x 8 = 112 896 bytes)."""
    p = calibration(n=6, genes=42, poses=30, validation=100, rows_per_pose=6)
    assert p.rows == 6 * 30 + 6 == 186
    assert p.held_bytes["parameters"] == 8 * 42 * 42 * 8 == 112_896
    # four copies of the (M, 6, K) Jacobians, the rotations (M, n + 1, 3, 3) twice, three (R, K) matrices
    assert p.held_bytes["poses"] == 8 * (4 * 30 * 6 * 42 + 2 * 30 * 7 * 9) + 8 * 3 * 186 * 42 == 459_648
    assert p.held_bytes["validation"] == 8 * (4 * 100 * 6 * 42 + 2 * 100 * 7 * 9) == 907_200
    assert p.genome_bytes == 2 * 186 * 8


@pytest.mark.parametrize("n", [1, 6, 40])
def test_the_budget_counts_eight_k_by_k_matrices_of_a_simulated_problem(n):
    """Through the run's estimate (the simulated kind's ``size`` of an n-joint arm, with the
    margin): the parameters part is eight K x K float64 matrices, K = 6n genes (the default
    layout: six per joint, no base or hand genes); for 40 joints (K = 240: 3.7 MB) they are
    most of what the problem holds."""
    from zrp_ga.problems import simulated

    arm = robots.get("puma560") if n == 6 else robots.ZRPRobot.from_dh([0.1] * n, [0.3] * n, [np.pi / 2] * n, name=f"chain{n}")
    problem = simulated.size(arm, n_poses=20, n_validation=0)
    K = 6 * n
    assert problem.genes == K
    e = budget.estimate(problem, AlgorithmSize(population=1, evaluations=1, held_bytes=0.0))
    assert e.memory["parameters"] == pytest.approx(1.25 * 8 * K * K * 8, rel=1e-12)
    if n == 40:
        assert e.memory["parameters"] > e.memory["poses"]


# --- a problem kind and an optimiser added by the README's recipe --------------------------------
TOY = '''
"""A toy problem kind and a toy optimiser, each added as the README's recipe says."""
import itertools

import numpy as np

from zrp_ga.algorithms import Algorithm, AlgorithmSize, Result
from zrp_ga.model import simulation
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.metrics import Judge
from zrp_ga.problems import Task
from zrp_ga.problems.size import ProblemSize

POSE_BYTES, GENOME_BYTES = 1_000_000, 50_000  # what the toy declares


def build(robot, run_seed=0, levels=2, span=1.0):
    """A calibration on the corners of a grid in joint space (levels ** n poses), measured
    without noise on a true arm drawn around robot."""
    layout = Layout(robot.n)
    rng = np.random.default_rng([run_seed, 1])
    truth = simulation.true_robot(robot, layout, rng, 0.01, 0.0005)
    grid = np.array(list(itertools.product(np.linspace(-span, span, levels), repeat=robot.n)))
    validation = simulation.measure(truth, rng.uniform(-span, span, (20, robot.n)), rng)
    problem = CalibrationProblem(robot, simulation.measure(truth, grid, rng), layout, -0.05, 0.05)
    return Task(f"toy-grid{levels}", problem, Judge(layout, robot, validation), robot, {"kind": "toy", "poses": len(grid)})


def size(robot, levels=2, span=1.0):
    M = levels ** robot.n
    return ProblemSize(genes=6 * robot.n, rows=6 * M + robot.n, held_bytes={"poses": POSE_BYTES * M},
                       genome_bytes=GENOME_BYTES, build_s={"poses": 1e-3 * M}, evaluation_s=1e-4,
                       lower={"poses": ("problem.levels", "lower problem.levels")})


class GaussNewton(Algorithm):
    """Gauss-Newton steps from the best of `starts` random genomes."""

    def __init__(self, starts=4, steps=6, work_bytes=1_000_000):
        super().__init__()
        self.starts, self.steps, self.work_bytes = starts, steps, work_bytes

    def size(self, problem):
        return AlgorithmSize(self.starts, self.starts + self.steps, self.work_bytes,
                             lower=("algorithm.starts", "lower algorithm.starts"))

    def initialize(self):
        p = self.problem
        X = self.rng.uniform(p.lower, p.upper, (self.starts, p.lower.size))
        self.costs = self.toolbox.evaluate(X)
        self.nevals = self.starts
        self.offer(X, self.costs)
        self.x, self.initial = self.best_x.copy(), (X, self.costs.copy())

    def step(self):
        p = self.problem
        self.x = self.x + np.linalg.lstsq(p.jacobian(self.x), p.residual(self.x), rcond=1e-10)[0]
        self.costs = self.toolbox.evaluate(self.x[None])
        self.nevals, self.gen = self.nevals + 1, self.gen + 1
        self.offer(self.x[None], self.costs)
        self.stop_reason = "steps" if self.gen >= self.steps else ""

    def result(self):
        return Result(self.best_x, self.best_cost, self.nevals, self.stop_reason, *self.initial)


class Blind(GaussNewton):
    size = Algorithm.size  # declares nothing
'''


@pytest.fixture(scope="module")
def toy(tmp_path_factory) -> tuple[Path, dict]:
    """The recipe: one module (on PYTHONPATH) and one config per group (in --config-dir)."""
    d = tmp_path_factory.mktemp("toy")
    (d / "toy_kind.py").write_text(TOY)
    (d / "toy_plain.py").write_text("import toy_kind\n\n\ndef build(robot, run_seed=0, levels=2, n_poses=5):  # declares no size\n"
                                    "    return toy_kind.build(robot, run_seed, levels)\n")  # fmt: skip
    for group, name, text in (("problem", "toy", "_target_: toy_kind.build\nlevels: 2\n"),
                              ("problem", "toy_plain", "_target_: toy_plain.build\nlevels: 2\nn_poses: 5\n"),
                              ("algorithm", "toy", "_target_: toy_kind.GaussNewton\nstarts: 4\nsteps: 6\nwork_bytes: 1000000\n"),
                              ("algorithm", "blind", "_target_: toy_kind.Blind\n")):  # fmt: skip
        (d / "conf" / group).mkdir(parents=True, exist_ok=True)
        (d / "conf" / group / f"{name}.yaml").write_text(text)
    return d, {"PYTHONPATH": os.pathsep.join([str(d), os.environ.get("PYTHONPATH", "")])}


def test_a_problem_kind_and_an_optimiser_added_by_the_recipe_run_and_are_sized_as_declared(toy, tmp_path):
    d, env = toy
    args = ("--config-dir", str(d / "conf"), "problem=toy", "algorithm=toy")
    # declared: 2^6 poses of 1 MB, 4 genomes of 50 kB at once and 1 MB of the optimiser's own, times 1.25
    need = 1.25 * (2**6 * 1_000_000 + 4 * 50_000 + 1_000_000)
    line = _one_line(_zrp_ga(*args, f"hydra.run.dir={tmp_path}/small", cwd=tmp_path, env={**env, "ZRP_GA_MEMORY": str(int(need) - 1)}))
    assert line.startswith("zrp-ga: error: problem.levels: the run would need about 81.5 MB of memory (poses 80 MB, population 1.5 MB; ")
    assert "lower problem.levels" in line and "declares no size" not in line
    line = _one_line(_zrp_ga(*args, "algorithm.work_bytes=1e9", f"hydra.run.dir={tmp_path}/big", cwd=tmp_path,
                             env={**env, "ZRP_GA_MEMORY": "1G"}))  # fmt: skip
    assert line.startswith("zrp-ga: error: algorithm.starts: the run would need about 1.33 GB of memory (population 1.25 GB, poses 80 MB")
    proc = _zrp_ga(*args, f"hydra.run.dir={tmp_path}/run", cwd=tmp_path, env={**env, "ZRP_GA_MEMORY": str(int(need) + 1)})
    assert proc.returncode == 0, proc.stderr
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["instance"] == "toy-grid2" and s["problem"]["poses"] == 64 and s["nevals"] == 4 + 6
    assert s["algorithm"] == "gaussnewton" and s["stop_reason"] == "steps"
    # noise-free data of an arm the layout describes: the calibrated model predicts unseen poses exactly
    assert s["validation_rms_mm"]["nominal"] > 1.0 and s["validation_rms_mm"]["calibrated"] < 1e-6


def test_a_kind_and_an_optimiser_that_declare_nothing_are_counted_generically_and_said_so(toy, tmp_path):
    d, env = toy
    line = _one_line(_zrp_ga("--config-dir", str(d / "conf"), "problem=toy_plain", "algorithm=blind", f"hydra.run.dir={tmp_path}/r",
                             cwd=tmp_path, env={**env, "ZRP_GA_MEMORY": "1k"}))  # fmt: skip
    assert "problem kind 'toy_plain' declares no size (no size() beside its build): counted as a calibration of 42 genes " \
           "on 5 pose(s) and 0 validation pose(s)" in line  # fmt: skip
    assert "optimiser toy_kind.Blind declares no size (no size() method): counted as population.mu + population.lambda_ " \
           "= 40 genomes" in line  # fmt: skip


def test_cmaes_holds_what_it_declares():
    """CMA-ES's declaration against tracemalloc's peak of a run on a problem that holds nothing
    (a sphere): the ``cma`` package's matrices grow as K^2, its population's copies as lambda K."""
    import tracemalloc

    from zrp_ga.algorithms.cmaes import CMAES
    from zrp_ga.problems.size import ProblemSize

    class Sphere:
        def __init__(self, K: int) -> None:
            self.lower, self.upper, self.names = -np.ones(K), np.ones(K), [f"x{i}" for i in range(K)]

        def costs(self, X):
            return np.einsum("ij,ij->i", np.atleast_2d(X), np.atleast_2d(X))

    CMAES({"mu": 1, "lambda_": 4, "generations": 2, "max_evals": None}, 0.3).run(Sphere(3), np.random.default_rng(0))  # imports
    for K, lam in ((600, 10), (40, 3000)):
        cmaes = CMAES({"mu": 1, "lambda_": lam, "generations": 3, "max_evals": None}, 0.3)
        declared = cmaes.size(ProblemSize(K, 0, {}, 0.0, {}, 0.0, {})).held_bytes
        tracemalloc.start()
        try:
            cmaes.run(Sphere(K), np.random.default_rng(0))
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak <= declared <= 2.5 * peak, (K, lam, peak, declared)
