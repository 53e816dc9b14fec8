"""Pose selection: observability indices against direct SVDs, the vectorised costs against a
loop, subset operators' invariants over many seeds, the exchange algorithm against brute
force, the GA's hooks, and a whole run through the app."""

import itertools
import json
import math

import numpy as np
import pytest
from scipy import stats

from zrp_ga import config, robots
from zrp_ga.algorithms import Callback
from zrp_ga.algorithms.exchange import Exchange
from zrp_ga.algorithms.ga import GA
from zrp_ga.algorithms.random_search import RandomSearch
from zrp_ga.core import targets
from zrp_ga.core.errors import one_line
from zrp_ga.core.schema import ConfigError, Index
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.model.simulation import measure, true_robot
from zrp_ga.operators import inversion, rotation, subset
from zrp_ga.problems.selection import SelectionProblem, joints_within_limits
from zrp_ga.run import build, execute


def _calibration(arm, M=40, position_only=False, seed=0, base=False):
    rng = np.random.default_rng(seed)
    layout = Layout(arm.n, base=base)
    truth = true_robot(arm, layout, rng, 0.01, 5e-4)
    data = measure(truth, joints_within_limits(arm, M, rng), rng, joint_noise=1e-3, position_only=position_only)
    return CalibrationProblem(arm, data, layout, -1.0, 1.0, cost="nonlinear", orientation_weight=0.7)


def _direct_indices(cal: CalibrationProblem, S, rcond=1e-4):
    """O1-O4 and A from the SVD of the stacked scaled Jacobian of the poses S, built here from
    the calibration problem's own (exactly normalised, weighted) Jacobian at the nominal."""
    J = cal.J_nominal[: -cal.nominal.n].copy()  # the pose rows (not the unit rows), at the nominal arm
    L = np.linalg.norm(cal.nominal.b0[1:], axis=1).sum()
    J[:, : 3 * cal.nominal.n] /= L  # axis errors (rad) times L: every parameter a length
    r = 3 if cal.data.position_only else 6
    _, s_all, Vt = np.linalg.svd(J, full_matrices=False)
    V = Vt[s_all > rcond * s_all[0]].T
    rows = np.concatenate([np.arange(r * c, r * c + r) for c in S])
    s = np.linalg.svd(J[rows] @ V, compute_uv=False)
    return {"O1": np.prod(s ** (1 / s.size)) / math.sqrt(len(S)), "O2": s[-1] / s[0], "O3": s[-1],
            "O4": s[-1] ** 2 / s[0], "A": np.sum(1 / s**2)}  # fmt: skip


@pytest.mark.parametrize("position_only", [False, True])
def test_indices_match_direct_svds_of_the_stacked_jacobian(position_only):
    cal = _calibration(robots.get("puma560"), position_only=position_only)
    prob = SelectionProblem(cal, k=12, ridge=0.0)
    assert prob.m == (19 if position_only else 25)  # docs/model.md, section 3: 36 - 5 slides - 6 stretches (- 6 tilts)
    X = np.random.default_rng(1).permuted(np.tile(np.arange(40), (6, 1)), axis=1)[:, :12]
    got = prob.indices(X)
    for p, S in enumerate(X):
        want = _direct_indices(cal, S)
        for name in want:
            assert got[name][p] == pytest.approx(want[name], rel=1e-8), name


def test_vectorised_costs_match_a_loop_for_every_index():
    cal = _calibration(robots.get("ur10"), M=30, base=True)
    X = np.random.default_rng(2).permuted(np.tile(np.arange(30), (25, 1)), axis=1)[:, :9].astype(float)
    for index in Index:
        prob = SelectionProblem(cal, k=9, index=index, ridge=0.0)
        loop = []
        for S in X.astype(int):
            v = _direct_indices(cal, S)
            loop.append(v["A"] if index is Index.A else 1.0 / v[index.value])
        np.testing.assert_allclose(prob.costs(X), loop, rtol=1e-8)


def test_indices_do_not_change_when_metres_become_millimetres():
    arm = robots.get("puma560")
    cal = _calibration(arm)
    mm = ZRPRobot(arm.u0, arm.b0 * 1e3, arm.R_h0, arm.joint_types)
    data_mm = cal.data.subset(np.arange(cal.data.M))
    data_mm = type(data_mm)(data_mm.q, data_mm.p * 1e3, data_mm.R)
    cal_mm = CalibrationProblem(mm, data_mm, cal.layout, -1.0, 1.0, cost="nonlinear", orientation_weight=0.7e3)
    X = np.random.default_rng(3).permuted(np.tile(np.arange(40), (5, 1)), axis=1)[:, :10]
    a, b = SelectionProblem(cal, 10, ridge=0.0).indices(X), SelectionProblem(cal_mm, 10, ridge=0.0).indices(X)
    for name in ("O1", "O2", "O3", "O4", "A"):
        np.testing.assert_allclose(a[name], b[name], rtol=1e-7)


def test_too_few_poses_identify_too_little_and_the_ridge_keeps_their_indices_finite():
    cal = _calibration(robots.get("puma560"), position_only=True)  # 19 directions, 3 rows per pose
    exact, ridged = SelectionProblem(cal, k=6, ridge=0.0), SelectionProblem(cal, k=6, ridge=1e-6)
    X = exact.sample(np.random.default_rng(4), 5)  # 18 rows for 19 directions
    assert np.all(exact.indices(X)["O1"] == 0.0) and np.all(np.isinf(exact.costs(X)))
    # with the ridge: the singular values of [J_S V; sqrt(lambda) I], lambda = ridge x mean eigenvalue of one pose
    J = cal.J_nominal[: -cal.nominal.n].copy()
    J[:, :18] /= np.linalg.norm(cal.nominal.b0[1:], axis=1).sum()
    _, s_all, Vt = np.linalg.svd(J, full_matrices=False)
    V = Vt[s_all > 1e-4 * s_all[0]].T
    lam = 1e-6 * np.sum((J @ V) ** 2) / (40 * V.shape[1])
    for S, got in zip(X.astype(int), ridged.indices(X)["O1"]):
        JS = J[np.concatenate([np.arange(3 * c, 3 * c + 3) for c in S])] @ V
        s = np.linalg.svd(np.vstack([JS, np.sqrt(lam) * np.eye(V.shape[1])]), compute_uv=False)
        assert got == pytest.approx(np.prod(s ** (1 / s.size)) / math.sqrt(6), rel=1e-8)


def test_problem_refuses_k_beyond_the_candidates():
    cal = _calibration(robots.get("puma560"), M=10)
    with pytest.raises(ValueError, match=r"problem.k: must be in \[1, 9\]"):
        SelectionProblem(cal, k=10)


# --- operators ----------------------------------------------------------------------------------
N, K = 25, 8


def _distinct_in_range(A, n=N):
    A = np.atleast_2d(A)
    return (np.all(np.rint(A) == A) and np.all((A >= 0) & (n > A))
            and all(len(set(row)) == len(row) for row in A.astype(int).tolist()))  # fmt: skip


@pytest.mark.parametrize("seed", range(20))
def test_subset_crossover_keeps_k_distinct_parental_genes(seed):
    rng = np.random.default_rng(seed)
    A, B = subset.sample(rng, 50, K, N), subset.sample(rng, 50, K, N)
    a, b = A.copy(), B.copy()
    subset.crossover(a, b, rng=rng, indpb=0.5)
    assert _distinct_in_range(a) and _distinct_in_range(b)
    for r in range(50):  # the pair's genes are conserved, shared genes stay where they were
        assert sorted(np.r_[a[r], b[r]]) == sorted(np.r_[A[r], B[r]])
        shared = np.isin(A[r], B[r])
        np.testing.assert_array_equal(a[r][shared], A[r][shared])
    assert np.any(a != A)


@pytest.mark.parametrize("seed", range(20))
def test_swap_mutation_brings_in_candidates_from_outside(seed):
    rng = np.random.default_rng(seed)
    A = subset.sample(rng, 50, K, N)
    a = A.copy()
    subset.swap(a, rng=rng, up=np.full(K, N - 1.0), indpb=0.2)
    assert _distinct_in_range(a)
    changed = a != A
    assert np.all(changed.any(axis=1))  # at least one gene per genome
    for r in range(50):
        assert not np.isin(a[r][changed[r]], A[r]).any()  # new genes were outside the subset


def test_swap_mutation_with_little_room_outside_terminates():
    rng = np.random.default_rng(0)
    A = subset.sample(rng, 100, 8, 10)
    a = A.copy()
    subset.swap(a, rng=rng, up=np.full(8, 9.0), indpb=1.0)  # only 2 candidates outside
    assert _distinct_in_range(a, 10) and np.all((a != A).sum(axis=1) <= 2)


@pytest.mark.parametrize("seed", range(20))
def test_repair_makes_any_genome_a_subset_and_keeps_what_was_one(seed):
    rng = np.random.default_rng(seed)
    A = rng.uniform(-3, N + 3, size=(40, K))
    A[:10] = np.rint(A[:10] / 4)  # many repeats
    A[0, 0] = np.nan
    good = subset.sample(rng, 5, K, N)
    a, g = A.copy(), good.copy()
    subset.repair(a, rng, N)
    subset.repair(g, rng, N)
    assert _distinct_in_range(a)
    np.testing.assert_array_equal(g, good)  # a subset stays as it was


@pytest.mark.parametrize("op", [inversion.segment, rotation.segment])
def test_inversion_and_rotation_reorder_a_subset_without_changing_it(op):
    rng = np.random.default_rng(5)
    A = subset.sample(rng, 200, K, N)
    a = A.copy()
    op(a, rng=rng)
    assert np.all(np.sort(a, axis=1) == np.sort(A, axis=1)) and np.any(a != A)


def test_sample_is_uniform_over_the_subsets():
    n, k, draws = 6, 3, 20000
    X = subset.sample(np.random.default_rng(7), draws, k, n).astype(int)
    assert _distinct_in_range(X, n)
    combos = {c: i for i, c in enumerate(itertools.combinations(range(n), k))}
    counts = np.bincount([combos[tuple(sorted(r))] for r in X.tolist()], minlength=len(combos))
    assert stats.chisquare(counts).pvalue > 1e-3


# --- algorithms ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny():
    return SelectionProblem(_calibration(robots.get("puma560"), M=10, seed=8), k=6, index=Index.O1)


def test_exchange_ends_where_no_exchange_improves_and_finds_the_brute_force_optimum(tiny):
    every = np.array(list(itertools.combinations(range(10), 6)), dtype=float)
    optimum = tiny.costs(every).min()
    found = []
    for seed in range(8):
        result = Exchange().run(tiny, np.random.default_rng(seed))
        S = result.x
        assert _distinct_in_range(S, 10) and result.cost == pytest.approx(tiny.costs(S[None])[0], rel=1e-12)
        # independently: the best addition, then the best removal, gives nothing better
        outside = np.setdiff1d(np.arange(10), S)
        best_add = outside[np.argmin([tiny.costs(np.append(S, j)[None])[0] for j in outside])]
        bigger = np.append(S, best_add)
        removal = min(tiny.costs(np.delete(bigger, i)[None])[0] for i in range(7))
        assert removal >= result.cost
        found.append(result.cost)
    assert min(found) == pytest.approx(optimum, rel=1e-12)
    assert np.all(np.array(found) <= np.quantile(tiny.costs(every), 0.05))  # each in the best 5% of all subsets


def test_exchange_refuses_a_calibration_problem():
    cal = _calibration(robots.get("puma560"), M=10)
    with pytest.raises(ConfigError, match="problem=pose_selection"):
        Exchange().run(cal, np.random.default_rng(0))


def test_random_search_keeps_the_best_of_its_samples(tiny):
    result = RandomSearch(samples=250, batch=100).run(tiny, np.random.default_rng(0))
    assert result.nevals == 250 and _distinct_in_range(result.x, 10)
    rng = np.random.default_rng(0)  # the same draws: batches of 100, 100 and 50 subsets
    draws = np.vstack([tiny.sample(rng, n) for n in (100, 100, 50)])
    assert result.cost == tiny.costs(draws).min() == tiny.costs(result.x[None])[0]


class Rows(Callback):
    def __init__(self):
        self.rows = []

    def on_generation(self, algorithm, row):
        self.rows.append(dict(row))


def _ga(*overrides) -> GA:
    return targets.create(config.load(["experiment=pose_selection", *overrides]).algorithm, "algorithm")


@pytest.mark.parametrize("crossover", ["subset", "two_point", "blend"])
def test_ga_keeps_subsets_whatever_the_operators(crossover):
    prob = SelectionProblem(_calibration(robots.get("puma560"), M=60, seed=9), k=10)
    rows = Rows()
    ga = _ga(f"crossover={crossover}", "mutation=gaussian" if crossover == "blend" else "mutation=swap",
             "population.max_evals=600", "population.mu=20", "population.lambda_=20")  # fmt: skip
    result = ga.run(prob, np.random.default_rng(0), [rows])
    assert _distinct_in_range(ga.pop, 60) and _distinct_in_range(result.x, 60)
    assert result.cost == pytest.approx(prob.costs(result.x[None])[0], rel=1e-12)
    assert result.cost < rows.rows[0]["best"]


def test_ga_on_a_calibration_problem_still_draws_uniform_genes_and_clips():
    """The hooks leave existing problems alone: the first population is exactly the uniform
    draw of the GA's generator, and genes are clipped into their ranges."""
    cal = _calibration(robots.get("puma560"), M=10)
    ga = targets.create(config.load(["refine=none", "population.mu=7"]).algorithm, "algorithm")
    ga.setup(cal, np.random.default_rng(11))
    ga.initialize()
    np.testing.assert_array_equal(ga.pop, np.random.default_rng(11).uniform(cal.lower, cal.upper, size=(7, 36)))
    genes = np.full((2, 36), 5.0)
    ga.toolbox.repair(genes)
    np.testing.assert_array_equal(genes, np.broadcast_to(cal.upper, (2, 36)))


def test_the_pseudo_inverse_step_is_refused_on_a_selection_problem():
    prob = SelectionProblem(_calibration(robots.get("puma560"), M=20), k=5)
    ga = targets.create(config.load(["problem=pose_selection"]).algorithm, "algorithm")  # refine=pinv
    with pytest.raises(ConfigError, match="refine: .*set refine=none"):
        ga.run(prob, np.random.default_rng(0))


# --- through the app ----------------------------------------------------------------------------
def test_a_selection_run_writes_the_files_and_judges_its_poses_by_calibrating_on_them(tmp_path):
    from scipy.optimize import least_squares

    over = ["experiment=pose_selection", "problem.k=8", "problem.n_candidates=60", "problem.n_validation=40",
            "population.max_evals=400", "population.mu=20", "population.lambda_=20", "progress=false"]  # fmt: skip
    cfg = config.load(over)
    execute.run(cfg, tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    for f in ("convergence.csv", "best_params.csv", "initial_population.csv", "selected_poses.csv", "calibrated_robot.yaml"):
        assert (tmp_path / f).exists(), f
    poses = s["selection"]["poses"]
    assert len(set(poses)) == 8 and s["best_genome"] == {f"pose_{j + 1}": p for j, p in enumerate(poses)}
    # independently: least squares on the chosen rows of the same simulated instance
    task = build.prepare(config.load(over), tmp_path / "again").task
    cal = task.problem.calibration
    sub = CalibrationProblem(cal.nominal, cal.data.subset(np.array(poses)), cal.layout, cal.lower, cal.upper, cost="nonlinear")
    x = least_squares(sub.residual, np.zeros(36), jac=lambda v: -sub.jacobian(v), method="lm", ftol=1e-15, xtol=1e-15,
                      gtol=1e-15).x  # converged fully, as LM is run
    from zrp_ga.model import metrics

    val = task.calibrate_on(np.array(poses)).judge.validation
    err = metrics.position_errors(cal.layout, cal.nominal, x, val)
    assert s["validation_rms_mm"]["calibrated"] == pytest.approx(1e3 * np.sqrt(np.mean(err**2)), rel=1e-6)
    assert s["selection"]["all_candidates"]["val_rms_mm"] < s["validation_rms_mm"]["nominal"]
    assert s["final_cost"] == pytest.approx(task.problem.costs(np.array(poses, dtype=float)[None])[0], rel=1e-12)


@pytest.mark.parametrize("override, expected", [
    ("problem.k=0", "problem.k: must be at least 1, got 0"),
    ("problem.k=600", "problem.n_candidates: must be more than problem.k = 600, got 500"),
    ("problem.rcond=2", "problem.rcond: must be in (0, 1), got 2.0"),
    ("problem.index=O5", "problem.index"),
])  # fmt: skip
def test_bad_selection_settings_are_one_line_naming_the_key(tmp_path, override, expected):
    with pytest.raises(Exception) as info:
        build.prepare(config.load(["experiment=pose_selection", override]), tmp_path / "run")
    assert expected in one_line(info.value)


def test_a_measured_subset_too_small_to_calibrate_fully_is_still_judged(tmp_path):
    """8 of the UR10's rows: 24 position equations for 27 identifiable combinations. A measured
    calibration refuses so few points; pose selection judges them anyway (underdetermined LM)
    and says how many directions they identify."""
    over = ["experiment=pose_selection", "problem=ur10_selection", "problem.k=8", "problem.reference=false",
            "population.max_evals=200", "population.mu=20", "population.lambda_=20", "progress=false"]  # fmt: skip
    execute.run(config.load(over), tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert np.isfinite(s["validation_rms_mm"]["calibrated"])
    assert any("choose more" in w for w in s["warnings"])
