"""The variation and selection operators draw from the distributions their papers publish,
tested with samples large enough to see a wrong exponent or scale.

Each operator is run on a large batch with a fixed seed, and what it did to each gene is
compared with the published distribution by a Kolmogorov-Smirnov or chi-square test at a small
level (``ALPHA``). Each test is also shown to have power: the same sample compared with the
distribution of a plausible wrong parameter (an exponent eta + 1 instead of eta, a scale 3%
off, a tournament one entrant larger) is rejected at a far smaller level (``POWER``).

Published distributions used (independent of the code):

- SBX (Deb and Agrawal 1995), the spread factor ``beta = |c2 - c1| / |p2 - p1|`` has density
  ``(eta + 1) / 2 beta^eta`` for beta <= 1 and ``(eta + 1) / 2 beta^-(eta + 2)`` beyond, CDF
  ``beta^(eta + 1) / 2`` and ``1 - beta^-(eta + 1) / 2``; the bounded version (Deb's, DEAP's
  ``cxSimulatedBinaryBounded``) truncates it, for each child, at the beta that puts the child
  on its bound, ``beta_b = 1 + 2 (distance of the nearer parent to the bound) / |p2 - p1|``:
  CDF ``F(beta) / F(beta_b)``.
- Polynomial mutation (Deb and Goyal 1996), the move ``delta`` in units of the range has density
  ``(eta + 1) / 2 (1 - |delta|)^eta`` on [-1, 1]; the bounded version (Deb's, DEAP's
  ``mutPolynomialBounded``) keeps half the mass on each side and truncates each half at the
  bound: on [-d1, 0] the CDF is ``((1 + t)^(eta+1) - (1 - d1)^(eta+1)) / (2 (1 - (1 - d1)^(eta+1)))``,
  d1 the distance to the lower bound in units of the range (the upper side mirrored).
- Gaussian mutation: ``N(0, (sigma (up - low))^2)`` per gene; BLX-alpha (Eshelman and Schaffer
  1993): ``gamma`` uniform on [-alpha, 1 + alpha]; uniform reset: uniform on [low, up].
- Tournament of size s with replacement among N distinct costs: the r-th best wins with
  probability ``((N - r + 1)^s - (N - r)^s) / N^s`` (Blickle and Thiele 1996).
- Inversion and rotation: the genes are permuted (the multiset kept), the segment [i, j] is
  uniform over the pairs of loci i < j (within a block chosen in proportion to its size), the
  rotation's shift uniform on 1 .. j - i.
"""

from itertools import combinations

import numpy as np
import pytest
from scipy import stats

from zrp_ga.operators import crossover, inversion, mutation, rotation, selection

ALPHA = 1e-3  # the correct distribution must not be rejected at this level
POWER = 1e-8  # a wrong parameter must be rejected at this level


def _ks(sample, cdf):
    return stats.kstest(sample, cdf).pvalue


# --- SBX ----------------------------------------------------------------------------------------
def _sbx_cdf(eta, beta_b):
    """CDF of the spread factor of bounded SBX, truncated at beta_b (module docstring)."""
    def F(b):
        b = np.asarray(b, dtype=float)
        with np.errstate(divide="ignore"):
            return np.where(b <= 1.0, 0.5 * b ** (eta + 1.0), 1.0 - 0.5 * b ** -(eta + 1.0))

    top = F(beta_b)
    return lambda b: np.clip(F(np.minimum(b, beta_b)) / top, 0.0, 1.0)


def _sbx_sample(eta, x1, x2, low, up, n=400_000, seed=1):
    rng = np.random.default_rng(seed)
    ya, yb = np.full((n, 1), x1), np.full((n, 1), x2)
    crossover.sbx(ya, yb, rng, low=np.array([low]), up=np.array([up]), eta=eta, indpb=1.0)
    return ya[:, 0], yb[:, 0]


# (eta, parents, bounds): far bounds (the unbounded law), near bounds (the truncation matters),
# bounds at different distances (each child has its own truncation)
SBX_CASES = [(2.0, 0.45, 0.55, -10.0, 11.0), (2.0, 0.3, 0.5, 0.0, 0.8), (20.0, 0.4, 0.6, 0.39, 0.61),
             (5.0, 0.2, 0.4, 0.1, 1.0)]  # fmt: skip


@pytest.mark.parametrize("eta, x1, x2, low, up", SBX_CASES)
def test_sbx_spread_factors_follow_the_published_bounded_density(eta, x1, x2, low, up):
    ya, yb = _sbx_sample(eta, x1, x2, low, up)
    lo, hi = np.minimum(ya, yb), np.maximum(ya, yb)
    diff, mid = x2 - x1, 0.5 * (x1 + x2)
    beta_lo, beta_hi = (mid - lo) / (0.5 * diff), (hi - mid) / (0.5 * diff)  # each child's spread factor
    bound_lo, bound_hi = 1 + 2 * (x1 - low) / diff, 1 + 2 * (up - x2) / diff
    assert _ks(beta_lo, _sbx_cdf(eta, bound_lo)) > ALPHA
    assert _ks(beta_hi, _sbx_cdf(eta, bound_hi)) > ALPHA
    # power: the same children are not those of eta + 1, nor of eta - 1
    assert _ks(beta_lo, _sbx_cdf(eta + 1, bound_lo)) < POWER and _ks(beta_lo, _sbx_cdf(eta - 1, bound_lo)) < POWER
    assert _ks(beta_hi, _sbx_cdf(eta + 1, bound_hi)) < POWER and _ks(beta_hi, _sbx_cdf(eta - 1, bound_hi)) < POWER
    assert np.all((low <= lo) & (hi <= up))


def test_sbx_truncation_has_power_too():
    """Near a bound, a truncation at the wrong beta_b (the exponent of the bound's term off by
    one) is rejected by the same test."""
    eta, x1, x2, low, up = 2.0, 0.3, 0.5, 0.0, 0.8
    ya, yb = _sbx_sample(eta, x1, x2, low, up)
    beta = (0.5 * (x1 + x2) - np.minimum(ya, yb)) / (0.5 * (x2 - x1))
    b = 1 + 2 * (x1 - low) / (x2 - x1)
    wrong_top = 1.0 - 0.5 * b ** -eta  # F(beta_b) with exponent eta instead of eta + 1
    cdf = _sbx_cdf(eta, np.inf)
    assert _ks(beta, lambda t: np.clip(cdf(np.minimum(t, b)) / wrong_top, 0, 1)) < POWER


def test_sbx_keeps_the_mean_swaps_children_at_random_and_crosses_genes_with_indpb():
    rng = np.random.default_rng(2)
    n, K = 20_000, 10
    low, up = np.zeros(K), np.full(K, 10.0)
    h = rng.uniform(0.5, 4, (n, K))
    a, b = 5 - h, 5 + h  # as far from either bound: both children spread alike, about the mean
    ya, yb = a.copy(), b.copy()
    crossover.sbx(ya, yb, rng, low=low, up=up, eta=3.0, indpb=0.3)
    changed = ya != a
    np.testing.assert_array_equal(changed, yb != b)
    assert stats.binomtest(int(changed.sum()), changed.size, 0.3).pvalue > ALPHA
    np.testing.assert_allclose((ya + yb)[changed], (a + b)[changed], rtol=1e-12)
    # the child nearer the first parent is the one below the mean half the time
    below = (ya < 0.5 * (a + b))[changed]
    assert stats.binomtest(int(below.sum()), below.size, 0.5).pvalue > ALPHA


# --- polynomial mutation ------------------------------------------------------------------------
def _poly_cdf(eta, d1, d2):
    """CDF of the bounded polynomial mutation's move delta (in units of the range)."""
    a1, a2 = (1 - d1) ** (eta + 1), (1 - d2) ** (eta + 1)

    def cdf(t):
        t = np.clip(np.asarray(t, dtype=float), -d1, d2)
        low = 0.5 * ((1 + np.minimum(t, 0)) ** (eta + 1) - a1) / (1 - a1)
        high = 1 - 0.5 * ((1 - np.maximum(t, 0)) ** (eta + 1) - a2) / (1 - a2)
        return np.where(t <= 0, low, high)

    return cdf


def _poly_sample(eta, x, low, up, n=400_000, seed=3):
    rng = np.random.default_rng(seed)
    ya = np.full((n, 1), x)
    mutation.polynomial(ya, rng, low=np.array([low]), up=np.array([up]), eta=eta, indpb=1.0)
    return (ya[:, 0] - x) / (up - low)


@pytest.mark.parametrize("eta, x, low, up", [(20.0, 0.5, 0.0, 1.0), (2.0, -0.9, -1.0, 1.0), (5.0, 2.95, -2.0, 3.0),
                                             (0.5, 1.0, 0.0, 10.0)])  # fmt: skip
def test_polynomial_mutation_follows_the_published_bounded_density(eta, x, low, up):
    delta = _poly_sample(eta, x, low, up)
    d1, d2 = (x - low) / (up - low), (up - x) / (up - low)
    assert _ks(delta, _poly_cdf(eta, d1, d2)) > ALPHA
    assert _ks(delta, _poly_cdf(eta + 1, d1, d2)) < POWER and _ks(delta, _poly_cdf(max(eta - 1, eta / 2), d1, d2)) < POWER
    assert np.all((-d1 <= delta) & (delta <= d2))


def test_polynomial_mutation_mutates_genes_with_indpb_within_the_bounds():
    rng = np.random.default_rng(4)
    low, up = np.array([0.0, -5.0, 100.0]), np.array([1.0, 5.0, 101.0])
    a = rng.uniform(low, up, (30_000, 3))
    ya = a.copy()
    mutation.polynomial(ya, rng, low=low, up=up, eta=10.0, indpb=0.2)
    assert stats.binomtest(int((ya != a).sum()), ya.size, 0.2).pvalue > ALPHA
    assert np.all((low <= ya) & (ya <= up))


# --- Gaussian mutation, uniform reset -----------------------------------------------------------
def test_gaussian_mutation_moves_by_sigma_times_the_range_of_each_gene():
    rng = np.random.default_rng(5)
    low, up = np.array([0.0, -1.0, 10.0, 0.0]), np.array([1.0, 3.0, 10.5, 0.02])  # widths 1, 4, 0.5, 0.02
    sigma, indpb, n = 0.07, 0.6, 250_000
    a = np.zeros((n, 4))
    ya = a.copy()
    mutation.gaussian(ya, rng, low=low, up=up, sigma=sigma, indpb=indpb)
    moved = ya != a
    assert stats.binomtest(int(moved.sum()), moved.size, indpb).pvalue > ALPHA
    z = ya / (sigma * (up - low))  # each gene in units of its own sigma
    sample = z[moved]
    assert _ks(sample, stats.norm.cdf) > ALPHA
    assert _ks(sample, stats.norm(scale=1.03).cdf) < POWER and _ks(sample, stats.norm(scale=0.97).cdf) < POWER
    for k in range(4):  # each gene by its own width (a width taken from another gene is rejected)
        assert _ks(z[moved[:, k], k], stats.norm.cdf) > ALPHA


def test_uniform_reset_draws_uniformly_in_each_genes_range():
    rng = np.random.default_rng(6)
    low, up = np.array([0.0, -3.0, 5.0]), np.array([1.0, 3.0, 5.1])
    a = np.tile(low - 1.0, (200_000, 1))  # outside the ranges: a reset gene shows
    ya = a.copy()
    mutation.uniform_reset(ya, rng, low=low, up=up, indpb=0.25)
    reset = ya != a
    assert stats.binomtest(int(reset.sum()), reset.size, 0.25).pvalue > ALPHA
    for k in range(3):
        u = (ya[reset[:, k], k] - low[k]) / (up[k] - low[k])
        assert _ks(u, stats.uniform.cdf) > ALPHA
        assert _ks(u, stats.uniform(-0.02, 1.04).cdf) < POWER  # a range 4% too wide is seen


# --- BLX-alpha ----------------------------------------------------------------------------------
@pytest.mark.parametrize("alpha", [0.0, 0.5, 1.0])
def test_blend_gamma_is_uniform_on_minus_alpha_one_plus_alpha(alpha):
    rng = np.random.default_rng(7)
    a, b = rng.uniform(-1, 1, (100_000, 3)), rng.uniform(2, 3, (100_000, 3))
    ya, yb = a.copy(), b.copy()
    crossover.blend(ya, yb, rng, alpha=alpha)
    gamma = ((ya - a) / (b - a)).ravel()
    np.testing.assert_allclose(ya + yb, a + b, rtol=1e-12, atol=1e-12)
    assert _ks(gamma, stats.uniform(-alpha, 1 + 2 * alpha).cdf) > ALPHA
    wrong = alpha * 1.1 + 0.02
    assert _ks(gamma, stats.uniform(-wrong, 1 + 2 * wrong).cdf) < POWER


# --- selection ----------------------------------------------------------------------------------
def _tournament_probs(N, s):
    r = np.arange(1, N + 1)
    return ((N - r + 1.0) ** s - (N - r + 0.0) ** s) / float(N) ** s


@pytest.mark.parametrize("size", [1, 2, 3, 5])
def test_tournament_winners_by_rank_follow_the_closed_form(size):
    rng = np.random.default_rng(8)
    N, k = 12, 300_000
    costs = rng.permutation(np.arange(N) * 1.5 + 0.25)  # distinct, in random order
    winners = selection.tournament(costs, k, rng, size=size)
    rank = np.argsort(np.argsort(costs))[winners]  # 0: the best
    counts = np.bincount(rank, minlength=N)
    assert stats.chisquare(counts, k * _tournament_probs(N, size)).pvalue > ALPHA
    assert stats.chisquare(counts, k * _tournament_probs(N, size + 1)).pvalue < POWER
    if size > 1:
        assert stats.chisquare(counts, k * _tournament_probs(N, size - 1)).pvalue < POWER


def test_truncation_draws_uniformly_from_the_best_fraction_and_random_from_all():
    rng = np.random.default_rng(9)
    N, k = 20, 200_000
    costs = rng.permutation(np.arange(N, dtype=float))
    chosen = selection.truncation(costs, k, rng, fraction=0.25)
    assert set(costs[chosen]) == {0.0, 1.0, 2.0, 3.0, 4.0}
    assert stats.chisquare(np.bincount(costs[chosen].astype(int), minlength=5)).pvalue > ALPHA
    picked = selection.random(costs, k, rng)
    assert stats.chisquare(np.bincount(picked, minlength=N)).pvalue > ALPHA


# --- inversion and rotation ---------------------------------------------------------------------
def _segments_of(ya, original):
    """First and last changed locus of each row."""
    changed = ya != original
    assert changed.any(axis=1).all()  # a segment of two or more distinct genes always moves
    first = changed.argmax(axis=1)
    last = ya.shape[1] - 1 - changed[:, ::-1].argmax(axis=1)
    return first, last


def _pair_counts(first, last, K):
    index = {pair: m for m, pair in enumerate(combinations(range(K), 2))}
    return np.bincount([index[(i, j)] for i, j in zip(first, last)], minlength=len(index)), index


@pytest.mark.parametrize("module", [inversion, rotation])
def test_segment_moves_keep_the_genes_and_pick_every_pair_of_loci_alike(module):
    rng = np.random.default_rng(10)
    n, K = 120_000, 7
    original = np.tile(np.arange(K, dtype=float) * 10, (n, 1))
    ya = original.copy()
    module.segment(ya, rng)
    np.testing.assert_array_equal(np.sort(ya, axis=1), original)
    first, last = _segments_of(ya, original)
    counts, _ = _pair_counts(first, last, K)
    assert stats.chisquare(counts).pvalue > ALPHA  # uniform over the 21 pairs, the last locus included
    rows, k = np.arange(n)[:, None], np.arange(K)[None]
    inside = (k >= first[:, None]) & (k <= last[:, None])
    if module is inversion:  # the segment reversed
        source = first[:, None] + last[:, None] - k
    else:  # the segment shifted right by 1 .. length - 1, uniformly for each length
        shift = np.argmax(ya == original[rows[:, 0], first][:, None], axis=1) - first  # where gene i went
        length = last - first + 1
        assert np.all((shift >= 1) & (shift <= length - 1))
        for L in range(3, K + 1):  # (length 2: the one shift 1)
            assert stats.chisquare(np.bincount(shift[length == L], minlength=L)[1:]).pvalue > ALPHA
        source = first[:, None] + (k - first[:, None] - shift[:, None]) % length[:, None]
    np.testing.assert_array_equal(ya, np.where(inside, original[rows, np.where(inside, source, k)], original))

@pytest.mark.parametrize("module", [inversion, rotation])
def test_block_moves_stay_in_a_block_chosen_by_its_size(module):
    rng = np.random.default_rng(11)
    n, blocks = 150_000, [(0, 3), (3, 4), (4, 9)]  # sizes 3, 1 (never chosen), 5
    K = 9
    original = np.tile(np.arange(K, dtype=float), (n, 1))
    ya = original.copy()
    module.block(ya, rng, blocks=blocks)
    np.testing.assert_array_equal(np.sort(ya, axis=1), original)
    first, last = _segments_of(ya, original)
    counts, index = _pair_counts(first, last, K)
    expected = np.zeros(len(index))
    for a, b in blocks:
        if b - a >= 2:
            pairs = list(combinations(range(a, b), 2))
            for pair in pairs:
                expected[index[pair]] = (b - a) / 8 / len(pairs)
    assert counts[expected == 0].sum() == 0  # no segment crosses a block's edge or enters the 1-gene block
    keep = expected > 0
    assert stats.chisquare(counts[keep], n * expected[keep]).pvalue > ALPHA
    wrong = np.where(keep, 0.5 / keep.sum() + 0.5 * expected, 0)  # blocks chosen half alike: rejected
    assert stats.chisquare(counts[keep], n * wrong[keep] / wrong.sum()).pvalue < POWER
