"""Every operator, for every genome size from 1 to 40 and subset sizes from 1, populations of one,
two and odd sizes and every probability edge, against its plain definition written here.

The operators draw their own random numbers; a definition here says which children are possible
given the parents (a tail, a middle, any set of loci exchanged; a segment reversed or rotated;
a blend within its range; genes within their bounds) and that nothing else changes, and, where
the draws are few and stated in the docstring (selections), computes the result itself. The
parents hold distinct genes everywhere, so that where a child's gene came from can be read from
its value. Where few outcomes are possible, every one of them must occur. The GA runs every
operator through whole generations at every size too.

Marked ``boundscheck``: tests/test_kernels.py runs this module again with numba's bounds
checking on and the compiled kernels forced (an index out of bounds then raises IndexError
instead of corrupting memory silently).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from zrp_ga import config, robots
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout, mask
from zrp_ga.model.simulation import simulate
from zrp_ga.operators import crossover, inversion, mutation, refine, rotation, selection, subset
from zrp_ga.operators.base import Streams
from zrp_ga.operators.repair import repair

pytestmark = pytest.mark.boundscheck

SIZES = range(1, 41)  # genome sizes
ROWS = (1, 2, 3, 5)  # populations of one, two and odd sizes
MANY = 300  # rows for the outcomes that must all occur


def _parents(K: int, N: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Two batches (N, K) whose 2 N K genes are all distinct, in [0, 1)."""
    v = (np.random.default_rng(seed).permutation(2 * N * K) + 0.5) / (2 * N * K)
    return v[: N * K].reshape(N, K), v[N * K :].reshape(N, K)


def _exchanged(a, b, ca, cb) -> tuple[int, ...] | None:
    """The loci at which children ca, cb are parents a, b exchanged; None if they are anything else."""
    same, swapped = (ca == a) & (cb == b), (ca == b) & (cb == a)
    return tuple(np.flatnonzero(swapped).tolist()) if np.all(same | swapped) else None


def _tails(K):  # one-point: the loci after a cut point c in 1..K-1
    return {tuple(range(c, K)) for c in range(1, K)} or {()}


def _middles(K):  # two-point: the loci between distinct cut points 1 <= lo < hi <= K-1
    if K == 2:
        return {(1,)}  # one cut point: the second gene
    return {tuple(range(lo, hi)) for lo, hi in itertools.combinations(range(1, K), 2)} or {()}


def _outcomes(op, K, N, seed, **params):
    a, b = _parents(K, N, seed)
    A, B = a.copy(), b.copy()
    op(A, B, rng=np.random.default_rng(seed), **params)
    return [_exchanged(a[r], b[r], A[r], B[r]) for r in range(N)]


@pytest.mark.parametrize("K", SIZES)
def test_one_and_two_point_exchange_a_tail_or_a_middle(K):
    for op, allowed in ((crossover.one_point, _tails(K)), (crossover.two_point, _middles(K))):
        for N in ROWS:
            assert set(_outcomes(op, K, N, 10 * K + N)) <= allowed, (op.__name__, N)
        seen = set(_outcomes(op, K, MANY, K))
        assert seen <= allowed, op.__name__
        if len(allowed) <= 15:  # few outcomes: each one drawn
            assert seen == allowed, op.__name__


@pytest.mark.parametrize("K", SIZES)
def test_uniform_crossover_exchanges_any_loci_and_none_or_all_at_the_edges(K):
    for N in ROWS:
        assert all(loci == () for loci in _outcomes(crossover.uniform, K, N, K, indpb=0.0))
        assert all(loci == tuple(range(K)) for loci in _outcomes(crossover.uniform, K, N, K, indpb=1.0))
        assert None not in _outcomes(crossover.uniform, K, N, K, indpb=0.5)


def _genes(K, N, seed):
    """Genomes in per-gene ranges [low, up] of different widths, and the ranges."""
    rng = np.random.default_rng(seed)
    low = rng.uniform(-2.0, 0.0, K)
    up = low + rng.uniform(0.01, 3.0, K)
    a, b = _parents(K, N, seed)
    return low + a * (up - low), low + b * (up - low), low, up


@pytest.mark.parametrize("K", SIZES)
def test_blend_children_lie_on_the_line_of_the_parents_within_alpha(K):
    for N, alpha in itertools.product(ROWS, (0.0, 0.5)):
        a, b, _, _ = _genes(K, N, K + N)
        c1, c2 = a.copy(), b.copy()
        crossover.blend(c1, c2, rng=np.random.default_rng(K), alpha=alpha)
        gamma = (c1 - a) / (b - a)  # child 1 = (1 - gamma) a + gamma b
        assert np.all((gamma >= -alpha - 1e-9) & (gamma <= 1 + alpha + 1e-9))
        np.testing.assert_allclose(c2, gamma * a + (1 - gamma) * b, atol=1e-12)


@pytest.mark.parametrize("K", SIZES)
def test_sbx_children_stay_in_the_ranges_and_untouched_genes_stay(K):
    for N, eta, indpb in itertools.product(ROWS, (0.0, 20.0), (0.0, 0.5, 1.0)):
        a, b, low, up = _genes(K, N, K + N)
        c1, c2 = a.copy(), b.copy()
        crossover.sbx(c1, c2, rng=np.random.default_rng(K), low=low, up=up, eta=eta, indpb=indpb)
        assert np.all((c1 >= low) & (c1 <= up) & (c2 >= low) & (c2 <= up))
        kept = (c1 == a) & (c2 == b)
        if indpb == 0.0:
            assert kept.all()
        if indpb == 1.0:  # every gene crossed: both children change it (a child on a parent is a null set)
            assert not kept.any()


@pytest.mark.parametrize("K", SIZES)
def test_mutations_change_genes_with_indpb_within_their_definitions(K):
    for N, indpb in itertools.product(ROWS, (0.0, 0.3, 1.0)):
        a, _, low, up = _genes(K, N, K + N)
        for op, params in ((mutation.gaussian, dict(sigma=0.1)), (mutation.polynomial, dict(eta=0.0)),
                           (mutation.polynomial, dict(eta=20.0)), (mutation.uniform_reset, {})):  # fmt: skip
            c1 = a.copy()
            op(c1, rng=np.random.default_rng(K), low=low, up=up, indpb=indpb, **params)
            changed = c1 != a
            assert not changed.any() if indpb == 0.0 else (changed.all() if indpb == 1.0 else True), op.__name__
            if op is mutation.gaussian:  # x + N(0, (sigma (up - low))^2): within 7 standard deviations
                assert np.all(np.abs(c1 - a) <= 7 * 0.1 * (up - low))
            else:
                assert np.all((c1 >= low) & (c1 <= up)), op.__name__


def _reversed(a, c) -> tuple[int, int] | None:
    """The segment [i, j] whose reversal makes c of a (genes distinct); (0, 0) if c is a, None if no reversal does."""
    d = np.flatnonzero(c != a)
    if not d.size:
        return (0, 0)
    i, j = d[0], d[-1]
    ok = np.array_equal(c[i : j + 1], a[i : j + 1][::-1]) and np.array_equal(np.delete(c, d), np.delete(a, d))
    return (int(i), int(j)) if ok else None


def _rotated(a, c) -> tuple[int, int] | None:
    """The segment [i, j] whose cyclic shift by 1 .. j - i places makes c of a; (0, 0) if c is a."""
    d = np.flatnonzero(c != a)
    if not d.size:
        return (0, 0)
    i, j = d[0], d[-1]
    shifts = range(1, j - i + 1)
    ok = any(np.array_equal(c[i : j + 1], np.roll(a[i : j + 1], s)) for s in shifts)
    return (int(i), int(j)) if ok and np.array_equal(np.delete(c, d), np.delete(a, d)) else None


def _blockings(K, rng):
    """Gene blocks ([start, stop) covering 0..K): one block, singletons only, random cuts."""
    cuts = sorted(rng.choice(np.arange(1, K), size=min(K - 1, 3), replace=False).tolist()) if K > 1 else []
    bounds = [0, *cuts, K]
    return [[(0, K)], [(k, k + 1) for k in range(K)], list(itertools.pairwise(bounds))]


@pytest.mark.parametrize("K", SIZES)
def test_inversion_and_rotation_move_one_segment_within_a_block(K):
    rng = np.random.default_rng(K)
    for module, find in ((inversion, _reversed), (rotation, _rotated)):
        for N in (*ROWS, MANY) if K <= 6 else ROWS:
            a, _ = _parents(K, N, K + N)
            A = a.copy()
            module.segment(A, rng=np.random.default_rng(N))
            found = [find(a[r], A[r]) for r in range(N)]
            assert None not in found, module.__name__
            if K >= 2:  # a segment of two or more distinct genes always moves
                assert (0, 0) not in found, module.__name__
            if N == MANY and K <= 6:  # every pair of loci drawn
                assert set(found) == (set(itertools.combinations(range(K), 2)) or {(0, 0)}), module.__name__
            for blocks in _blockings(K, rng):
                A = a.copy()
                module.block(A, rng=np.random.default_rng(N), blocks=blocks)
                found = [find(a[r], A[r]) for r in range(N)]
                usable = [(lo, hi) for lo, hi in blocks if hi - lo >= 2]
                assert None not in found, (module.__name__, blocks)
                for i, j in found:
                    assert ((i, j) == (0, 0) and not usable) or any(lo <= i < j < hi for lo, hi in usable), (module.__name__, blocks)


def _finite(costs):
    return np.where(np.isfinite(costs), costs, np.inf)


@pytest.mark.parametrize("P", [1, 2, 3, 5, 8])
def test_selections_are_their_definitions_for_any_population(P):
    """Tournament: ``k`` rows of ``size`` entrants drawn by ``integers(0, P, (k, size))``, the
    first least cost wins; truncation: ``integers(0, m, k)`` into the ``m = max(1, round(fraction
    P))`` best (stable order); random: ``integers(0, P, k)``. NaN and inf cost the most."""
    costs = np.random.default_rng(P).normal(size=P)
    costs[::3] = [np.nan, np.inf, -np.inf][: len(costs[::3])] if P > 1 else costs[::3]
    for k, size in itertools.product((1, 2, 3, 7), (1, 2, 3, 7)):
        got = selection.tournament(costs, k, rng=np.random.default_rng(k), size=size)
        entrants = np.random.default_rng(k).integers(0, P, size=(k, size))
        assert got.tolist() == [int(e[np.argmin(_finite(costs)[e])]) for e in entrants]
    for k, fraction in itertools.product((1, 2, 7), (0.01, 0.5, 1.0)):
        got = selection.truncation(costs, k, rng=np.random.default_rng(k), fraction=fraction)
        best = sorted(range(P), key=lambda i: (_finite(costs)[i], i))[: max(1, round(fraction * P))]
        assert got.tolist() == [best[i] for i in np.random.default_rng(k).integers(0, len(best), size=k)]
        assert selection.random(costs, k, rng=np.random.default_rng(k)).tolist() == np.random.default_rng(k).integers(0, P, k).tolist()


STREAMED = [
    ("cx", crossover.one_point, {}), ("cx", crossover.two_point, {}), ("cx", crossover.uniform, dict(indpb=0.5)),
    ("cx", crossover.blend, dict(alpha=0.5)), ("cx", crossover.sbx, dict(eta=20.0, indpb=0.5, bounds=True)),
    ("mut", mutation.gaussian, dict(sigma=0.1, indpb=0.3, bounds=True)), ("mut", mutation.polynomial, dict(eta=20.0, indpb=0.3, bounds=True)),
    ("mut", mutation.uniform_reset, dict(indpb=0.3, bounds=True)), ("mut", inversion.segment, {}), ("mut", rotation.segment, {}),
    ("mut", inversion.block, dict(blocks=True)), ("mut", rotation.block, dict(blocks=True)),
]  # fmt: skip


@pytest.mark.parametrize("K", SIZES)
def test_runs_varied_together_get_what_each_gets_alone(K):
    """Rows of two runs (2 and 3 rows) in one call with their own generators: each run's rows
    are exactly those of a call on its rows alone (how the GA evolves runs together)."""
    a, b, low, up = _genes(K, 5, K)
    blocks = _blockings(K, np.random.default_rng(K))[2]
    for kind, op, params in STREAMED:
        params = dict(params)
        if params.pop("bounds", False):
            params.update(low=low, up=up)
        if params.pop("blocks", False):
            params.update(blocks=blocks)
        together = [a.copy()] + ([b.copy()] if kind == "cx" else [])
        op(*together, rng=Streams([np.random.default_rng(1), np.random.default_rng(2)], [2, 3]), **params)
        for seed, rows in ((1, slice(0, 2)), (2, slice(2, 5))):
            alone = [a[rows].copy()] + ([b[rows].copy()] if kind == "cx" else [])
            op(*alone, rng=np.random.default_rng(seed), **params)
            for x, y in zip(together, alone):
                np.testing.assert_array_equal(x[rows], y, err_msg=op.__name__)


def _subsets(k, n, N, seed):
    return subset.sample(np.random.default_rng(seed), N, k, n)


def _distinct_in_range(genes, n):
    return all(len(set(r)) == len(r) for r in genes.tolist()) and np.all((genes >= 0) & (genes < n) & (genes == np.rint(genes)))


@pytest.mark.parametrize("k", range(1, 13))
def test_subset_operators_keep_subsets_for_every_size_from_one(k):
    for n, N in itertools.product((k + 1, k + 2, 2 * k + 1, k + 10), ROWS):
        a, b = _subsets(k, n, N, k), _subsets(k, n, N, k + 1)
        assert a.shape == (N, k) and _distinct_in_range(a, n)
        for indpb in (0.0, 0.5, 1.0):
            A, B = a.copy(), b.copy()
            subset.crossover(A, B, rng=np.random.default_rng(n), indpb=indpb)
            assert _distinct_in_range(A, n) and _distinct_in_range(B, n)
            for r in range(N):  # genes both hold stay; the pair's genes are the parents' genes
                common = set(a[r]) & set(b[r])
                assert common <= set(A[r]) and common <= set(B[r])
                assert sorted(A[r].tolist() + B[r].tolist()) == sorted(a[r].tolist() + b[r].tolist())
                if indpb == 0.0:
                    assert A[r].tolist() == a[r].tolist()
                if indpb == 1.0:
                    assert set(A[r]) == set(b[r])
            A = a.copy()
            subset.swap(A, rng=np.random.default_rng(n), up=np.full(k, n - 1.0), indpb=indpb)
            assert _distinct_in_range(A, n)
            for r in range(N):
                new = set(A[r]) - set(a[r])
                assert 1 <= len(new) <= n - k  # at least one per genome, never more than there is room for
        junk = np.random.default_rng(k).uniform(-3, n + 3, size=(N, k))
        junk[0, 0], junk[-1, -1] = np.nan, np.inf
        junk[:, -1] = junk[:, 0]  # repeats
        subset.repair(junk, np.random.default_rng(k), n)
        assert _distinct_in_range(junk, n)
        A = a.copy()
        subset.repair(A, np.random.default_rng(k), n)
        np.testing.assert_array_equal(A, a)  # a subset stays as it is
        for op in (inversion.segment, rotation.segment):
            A = a.copy()
            op(A, rng=np.random.default_rng(k))
            assert [sorted(r) for r in A.tolist()] == [sorted(r) for r in a.tolist()]


def _reflect(x, lo, hi):
    """Fold x back into [lo, hi] off its bounds, one reflection at a time."""
    while not lo <= x <= hi:
        x = 2 * lo - x if x < lo else 2 * hi - x
    return x


@pytest.mark.parametrize("K", SIZES)
def test_repair_clips_or_reflects_into_the_ranges(K):
    for N in ROWS:
        a, _, low, up = _genes(K, N, K)
        x = low + (a - low) * 5.0 - 2.0 * (up - low)  # genes far outside, both sides
        got = repair(x.copy(), low, up, "clip")
        np.testing.assert_array_equal(got, [[min(max(v, lo), hi) for v, lo, hi in zip(row, low, up)] for row in x])
        got = repair(x.copy(), low, up, "reflect")
        np.testing.assert_allclose(got, [[_reflect(v, lo, hi) for v, lo, hi in zip(row, low, up)] for row in x], atol=1e-12)


class _Linear:
    """A least-squares problem with residual y - J x, Jacobian J and gene ranges."""

    def __init__(self, J, y, lower, upper):
        self.J, self.y, self.lower, self.upper = J, y, lower, upper

    def residual(self, x):
        return self.y - self.J @ x

    def jacobian(self, x):
        return self.J


@pytest.mark.parametrize("K", SIZES)
def test_the_pseudo_inverse_step_reaches_the_least_squares_solution(K):
    rng = np.random.default_rng(K)
    for M, N in ((1, 1), (K, 2), (K + 3, 3)):
        J, y = rng.normal(size=(M, K)), rng.normal(size=M)
        X = rng.normal(size=(N, K))
        wide = _Linear(J, y, np.full(K, -1e6), np.full(K, 1e6))
        got = refine.pinv(X.copy(), rng=rng, problem=wide)[0]
        P = np.linalg.pinv(J)
        np.testing.assert_allclose(got, X @ (np.eye(K) - P @ J).T + P @ y, atol=1e-8)  # x + pinv(J) (y - J x)
        narrow = _Linear(J, y, np.full(K, -0.01), np.full(K, 0.01))
        got = refine.pinv(np.zeros((N, K)), rng=rng, problem=narrow)[0]
        assert np.all((got >= -0.01 - 1e-12) & (got <= 0.01 + 1e-12))


# --- whole generations, every operator, every genome size ------------------------------------------
GA_SETTINGS = [
    ["crossover=two_point", "mutation=gaussian", "inversion=segment", "rotation=segment", "refine=pinv", "refine.share=0.4"],
    ["crossover=one_point", "mutation=polynomial", "inversion=block", "rotation=block", "refine=none"],
    ["crossover=uniform", "mutation=uniform_reset", "inversion=segment", "rotation=block", "refine=none", "selection=truncation"],
    ["crossover=blend", "mutation=gaussian", "inversion=block", "rotation=segment", "refine=none", "selection=random",
     "algorithm.strategy=generational", "algorithm.elite=1"],
    ["crossover=sbx", "mutation=polynomial", "inversion=segment", "rotation=segment", "refine=none", "algorithm.strategy=mu_comma_lambda"],
]  # fmt: skip


@pytest.fixture(scope="module")
def arm_and_data():
    arm = robots.get("puma560")
    layout = Layout(6, base=True, hand=True)
    sim = simulate(arm, layout, np.random.default_rng(3), n_poses=3, n_validation=1)
    return arm, layout, sim.calibration


@pytest.mark.parametrize("settings", GA_SETTINGS, ids=lambda s: s[0].split("=")[1])
def test_the_ga_runs_every_operator_for_every_genome_size(settings, arm_and_data):
    """Genomes of 1 to 40 genes (``problem.free`` naming that many), population 3, 5 children a
    generation, each operator with probability 1: every generation finishes, genes in range."""
    arm, layout, data = arm_and_data
    node = config.load([*settings, "population.mu=3", "population.lambda_=5", "population.generations=2",
                        "crossover.prob=1", "mutation.prob=1", "inversion.prob=1", "rotation.prob=1"]).algorithm  # fmt: skip
    for K in SIZES:
        masked = mask(layout, free=layout.full_names[:K])
        half = np.full(K, 0.01)
        problem = CalibrationProblem(arm, data, masked, -half, half, cost="nonlinear")
        result = config.instantiate(node, "algorithm").run(problem, np.random.default_rng(K))
        assert result.x.shape == (K,) and np.all(np.abs(result.x) <= 0.01) and np.isfinite(result.cost), K


def test_the_ga_selects_poses_for_every_subset_size_from_one():
    """Pose selection's GA (subset crossover and swap, inversion, rotation, each with probability
    1) for subsets of 1 to 12 of 14 candidate poses: subsets of distinct candidates throughout."""
    from zrp_ga.model.simulation import measure, true_robot
    from zrp_ga.problems.selection import SelectionProblem, joints_within_limits

    arm, rng = robots.get("puma560"), np.random.default_rng(4)
    layout = Layout(6)
    data = measure(true_robot(arm, layout, rng, 0.01, 5e-4), joints_within_limits(arm, 14, rng), rng, joint_noise=1e-3)
    calibration = CalibrationProblem(arm, data, layout, -1.0, 1.0, cost="nonlinear")
    node = config.load(["experiment=pose_selection", "population.mu=3", "population.lambda_=5", "population.generations=2",
                        "population.max_evals=null", "crossover.prob=1", "mutation.prob=1", "inversion.prob=1",
                        "rotation.prob=1"]).algorithm  # fmt: skip
    for k in range(1, 13):
        problem = SelectionProblem(calibration, k=k)
        ga = config.instantiate(node, "algorithm")
        result = ga.run(problem, np.random.default_rng(k))
        assert _distinct_in_range(ga.pop, 14) and _distinct_in_range(result.x[None], 14) and result.x.shape == (k,), k
