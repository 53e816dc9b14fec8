"""Statistical tests of the report (Demšar, "Statistical comparisons of classifiers over
multiple data sets", JMLR 7, 2006), equivalence before difference.

**Tolerance.** Results closer than a tolerance ``tol`` (the report's: the targets' resolution
and at least the round-off floor, :mod:`zrp_ga.report.tables`) are the same result: paired
differences within it are zero, and independent values within it of a lower one are that
value (:func:`snap`). Every test, effect size and verdict below uses it.

- Groups that share their blocks (configurations run with the same seeds on one instance, or
  the values of a setting over the same other settings and seeds): Friedman's test with the
  blocks as blocks, pairwise Wilcoxon signed-rank tests (exact, ties included) with Holm's
  correction, and the paired probability of superiority (the share of blocks where A ends
  lower by more than ``tol``, ties counting half).
- Otherwise: Kruskal-Wallis, pairwise Mann-Whitney U with Holm's correction and the
  Vargha-Delaney A12 = P(a run of A ends lower than a run of B) + P(tie)/2.
- **Equivalence** is a finding, not an absence of one: two one-sided tests (TOST; Schuirmann
  1987, here with the rank tests above: the shift of B against A is above -tol, and below
  +tol), Holm-corrected over the pairs. A pair whose every run lies within ``tol`` of the
  other's is equivalent on its face.
- **One verdict per pair** (:func:`verdict`): equivalent when every run is within the
  tolerance; else better or worse when the difference test (Holm) says so; else equivalent
  when TOST (Holm) says so; else undecided.
- Effect sizes come with 95% bootstrap confidence intervals (scipy.stats.bootstrap,
  percentile), in memory bounded by batches whatever the number of runs.
- Across instances: Friedman's test with Nemenyi's post-hoc test and critical difference.

Every effect size here is the chance that A does better (lower) than B: 0.5 is no effect."""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy import stats

from zrp_ga.report.common import ALPHA

BETTER, WORSE, EQUIVALENT, UNDECIDED = "better", "worse", "equivalent", "undecided"
ALL_TIED = "every run within the tolerance"
COMPARE_COLUMNS = ["metric", "test", "a", "b", "statistic", "p", "p_holm", "a12", "n_a", "n_b"]
DESIGN_COLUMNS = ["design", "test", "a", "b", "statistic", "p", "p_holm", "effect", "effect_lo", "effect_hi", "n_a", "n_b",
                  "p_equivalence", "p_equivalence_holm", "verdict", "direction"]  # fmt: skip
PAIRED, INDEPENDENT = "paired by block", "independent runs"
RESAMPLES = 2000
BATCH_NUMBERS = 1_000_000  # numbers a bootstrap batch resamples at once (8 MB a copy), whatever the sample sizes


def holm(p: ArrayLike) -> np.ndarray:
    """Holm's step-down adjusted p-values. By hand: scipy.stats has Benjamini-Hochberg
    (``false_discovery_control``) but not Holm, and statsmodels would be a dependency for six lines.

    >>> holm(np.array([0.01, 0.04, 0.03])).round(3).tolist()
    [0.03, 0.06, 0.06]
    """
    p = np.asarray(p, dtype=float)
    order = np.argsort(p)
    m = len(p)
    adjusted = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(adjusted, 1.0)
    return out


def snap(values: np.ndarray, tol: float) -> np.ndarray:
    """(n,) values with each one within ``tol`` above the lowest of its group replaced by that
    lowest value: sorted ascending, a group starts at a value and takes every value up to it +
    ``tol`` (so that ties are transitive). ``tol`` 0 changes nothing; NaN stays NaN.

    >>> snap(np.array([1.0, 1.004, 1.009, 1.02, 3.0]), 0.01).tolist()
    [1.0, 1.0, 1.0, 1.02, 3.0]
    """
    v = np.asarray(values, dtype=float).copy()
    if not tol > 0:
        return v
    finite = np.flatnonzero(np.isfinite(v))
    start = -np.inf
    for i in finite[np.argsort(v[finite], kind="stable")]:
        if v[i] > start + tol:
            start = v[i]
        v[i] = start
    return v


def a12(x: np.ndarray, y: np.ndarray) -> float:
    """Vargha and Delaney's A12: P(X < Y) + P(X = Y) / 2 over all pairs (lower is better),
    from the ranks of the pooled sample (memory n_x + n_y, not n_x x n_y).

    >>> a12(np.array([1.0, 2.0]), np.array([2.0, 3.0]))
    0.875
    """
    return float(_a12_ranks(np.asarray(x, dtype=float), np.asarray(y, dtype=float), axis=-1))


def _a12_ranks(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    """A12 along ``axis`` (the rest batched): U_y / (n_x n_y), U_y = R_y - n_y (n_y + 1) / 2 with
    R_y the sum of y's mid-ranks in the pooled sample (Mann and Whitney's U of y over x)."""
    x, y = np.moveaxis(x, axis, -1), np.moveaxis(y, axis, -1)
    nx, ny = x.shape[-1], y.shape[-1]
    ranks = stats.rankdata(np.concatenate([x, y], axis=-1), axis=-1)
    return (ranks[..., nx:].sum(axis=-1) - ny * (ny + 1) / 2) / (nx * ny)


def paired_superiority(x: np.ndarray, y: np.ndarray, tol: float = 0.0) -> float:
    """The share of blocks in which X ends lower than Y by more than ``tol``, ties (within
    ``tol``) counting half.

    >>> paired_superiority(np.array([1.0, 2.0, 3.0]), np.array([2.0, 2.0, 1.0]))
    0.5
    """
    return float(np.mean(_scores(np.asarray(y, dtype=float) - np.asarray(x, dtype=float), tol)))


def _scores(d: np.ndarray, tol: float) -> np.ndarray:
    """Per block: 1 where the difference d = y - x > tol (X lower), 1/2 within tol, 0 below."""
    return (d > tol) + 0.5 * (np.abs(d) <= tol)


# --- Wilcoxon's signed-rank test, exact with ties -----------------------------------------------
def signed_rank(d: np.ndarray, alternative: str = "two-sided", exact_up_to: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Wilcoxon's signed-rank test of each row of ``d`` ((R, n) differences; zeros and NaN left
    out, as Wilcoxon's own zero method): W+ (the sum of the mid-ranks of |d| of the positive
    differences) and its p-value under random signs, ``alternative`` "two-sided", "greater"
    (d tends to be positive) or "less"; (R,) each; p = 1 where nothing is left.

    Exact, ties included, for up to ``exact_up_to`` non-zero differences (scipy's own limit for
    its exact test; beyond, its normal approximation with the tie correction): the null distribution
    of 2 W+ is built by convolving each difference's two outcomes (0 or twice its mid-rank) one
    difference at a time, all rows at once. By hand because scipy's exact test with ties is a
    permutation test (``method="auto"``), about 0.3 s a call: a thousand pairs would take five
    minutes. Checked against scipy (exact without ties, its permutation test with them, its
    normal approximation beyond ``exact_up_to``) in tests/test_report_stats.py."""
    w, p, _ = _signed_rank(d, alternative, exact_up_to)
    return w, p


def _signed_rank(d: np.ndarray, alternative: str, exact_up_to: int = 50) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`signed_rank` and the sum of all the mid-ranks (W+ + W-), (R,) each."""
    d = np.atleast_2d(np.asarray(d, dtype=float))
    live = np.isfinite(d) & (d != 0)
    a = np.where(live, np.abs(d), np.nan)
    ranks2 = np.nan_to_num(2 * stats.rankdata(a, axis=-1, nan_policy="omit"), nan=0.0).astype(np.int64)
    ranks2[~live] = 0
    w2 = np.where(d > 0, ranks2, 0).sum(axis=-1)
    p = np.ones(len(d))
    count = live.sum(axis=-1)
    exact = (count > 0) & (count <= exact_up_to)
    rows = np.flatnonzero(exact)
    chunk = max(1, int(2e6 // max(1, int(ranks2[rows].sum(axis=-1).max(initial=1)) + 1)))
    for k in range(0, len(rows), chunk):
        sel = rows[k:k + chunk]
        p[sel] = _exact_p(ranks2[sel], w2[sel], alternative)
    approx = np.flatnonzero(count > exact_up_to)
    if len(approx):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            p[approx] = stats.wilcoxon(np.where(live[approx], d[approx], 0.0), alternative=alternative, method="asymptotic",
                                       axis=-1).pvalue  # fmt: skip
    return w2 / 2.0, p, ranks2.sum(axis=-1) / 2.0


def _exact_p(ranks2: np.ndarray, w2: np.ndarray, alternative: str) -> np.ndarray:
    """The exact p-values of rows of doubled mid-ranks ``ranks2`` (R, n) (0: left out) at the
    observed 2 W+ ``w2`` (R,): the distribution of the sum of each rank taken with probability 1/2."""
    total = ranks2.sum(axis=-1)
    top = int(total.max())
    dist = np.zeros((len(ranks2), top + 1))
    dist[:, 0] = 1.0
    grid = np.arange(top + 1)
    for j in range(ranks2.shape[1]):
        shift = ranks2[:, j][:, None]
        moved = np.where(grid >= shift, np.take_along_axis(dist, np.clip(grid - shift, 0, None), axis=1), 0.0)
        dist = 0.5 * (dist + moved)
    w = w2[:, None]
    if alternative == "greater":
        return np.minimum(1.0, (dist * (grid >= w)).sum(axis=1))
    if alternative == "less":
        return np.minimum(1.0, (dist * (grid <= w)).sum(axis=1))
    centre = total[:, None] / 2.0
    far = np.abs(grid - centre) >= np.abs(w - centre) - 1e-9
    return np.minimum(1.0, (dist * far).sum(axis=1))


# --- the tests of a pair -------------------------------------------------------------------------
def _paired_pairs(diffs: np.ndarray, tol: float) -> dict[str, np.ndarray]:
    """Per pair (rows of ``diffs`` (R, n), d = b - a: positive where A ends lower): Wilcoxon's W+
    and two-sided p with differences within ``tol`` as zeros, and TOST's p (the larger of the two
    one-sided p-values that the shift is above -tol and below +tol)."""
    zeroed = np.where(np.abs(diffs) <= tol, 0.0, diffs)
    w, p, total = _signed_rank(zeroed, "two-sided")
    if tol > 0:
        p_up = signed_rank(diffs + tol, "greater")[1]
        p_down = signed_rank(diffs - tol, "less")[1]
        p_eq = np.maximum(p_up, p_down)
    else:
        p_eq = np.ones(len(diffs))
    tied = (np.abs(diffs) <= tol).all(axis=1)
    direction = np.sign(2 * w - total)  # W+ against W-
    return dict(statistic=w, p=p, p_eq=p_eq, tied=tied, effect=_scores(diffs, tol).mean(axis=1), direction=direction)


def _independent_pair(x: np.ndarray, y: np.ndarray, tol: float) -> dict[str, float]:
    """Mann-Whitney U of A (``x``) against B (``y``) on the pair's values snapped to ``tol``,
    A12, and TOST's p with B shifted by -tol and +tol."""
    both = snap(np.concatenate([x, y]), tol)
    xs, ys = both[: len(x)], both[len(x):]
    if np.ptp(both) == 0:
        u, p = len(x) * len(y) / 2.0, 1.0
    else:
        u, p = stats.mannwhitneyu(xs, ys, alternative="two-sided")
    p_eq = 1.0
    if tol > 0:
        p_up = stats.mannwhitneyu(y + tol, x, alternative="greater").pvalue
        p_down = stats.mannwhitneyu(y - tol, x, alternative="less").pvalue
        p_eq = float(max(p_up, p_down))
    effect = float(_a12_ranks(xs, ys))
    return dict(statistic=float(u), p=float(p), p_eq=p_eq, tied=bool(np.ptp(np.concatenate([x, y])) <= tol), effect=effect,
                direction=float(np.sign(effect - 0.5)))  # fmt: skip


def verdict(tied: bool, p_holm: float, direction: float, p_equivalence_holm: float, alpha: float = ALPHA) -> str:
    """One answer for a pair, A against B: ``equivalent`` when every run is within the tolerance
    (``tied``); else ``better`` or ``worse`` (A's side, ``direction`` > 0: A lower) when the
    difference test says so; else ``equivalent`` when TOST says so; else ``undecided``.

    >>> verdict(False, 0.01, -1.0, 1.0), verdict(True, 1.0, 0.0, 1.0), verdict(False, 0.4, 1.0, 0.01)
    ('worse', 'equivalent', 'equivalent')
    """
    if tied:
        return EQUIVALENT
    if p_holm < alpha and direction != 0:
        return BETTER if direction > 0 else WORSE
    if p_equivalence_holm < alpha:
        return EQUIVALENT
    return UNDECIDED


def effect_ci(x: np.ndarray, y: np.ndarray, paired: bool, tol: float = 0.0, level: float = 0.95,
              resamples: int = RESAMPLES) -> tuple[float, float]:  # fmt: skip
    """A ``level`` bootstrap confidence interval (percentile method, ``resamples`` resamples,
    seeded: the same data give the same interval) of :func:`paired_superiority` (``paired``:
    blocks resampled) or :func:`a12` (each sample resampled on its own, the values snapped to
    ``tol``), in batches of at most ``BATCH_NUMBERS`` numbers."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if paired:
        los, his = paired_cis(np.atleast_2d(y - x), tol, level, resamples)
        return float(los[0]), float(his[0])
    both = snap(np.concatenate([x, y]), tol)
    x, y = both[: len(x)], both[len(x):]
    if len(x) < 2 or len(y) < 2 or np.ptp(both) == 0:
        v = a12(x, y)
        return v, v
    batch = max(1, BATCH_NUMBERS // (len(x) + len(y)))
    with warnings.catch_warnings():  # a degenerate resample distribution is a point interval
        warnings.simplefilter("ignore")
        ci = stats.bootstrap((x, y), _a12_ranks, vectorized=True, n_resamples=resamples, confidence_level=level,
                             method="percentile", batch=batch, rng=np.random.default_rng(0)).confidence_interval  # fmt: skip
    lo, hi = float(ci.low), float(ci.high)
    return (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else (a12(x, y),) * 2


def paired_cis(diffs: np.ndarray, tol: float, level: float = 0.95, resamples: int = RESAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """Bootstrap intervals (percentile, seeded) of the paired superiority of every row of
    ``diffs`` ((R, n), d = b - a), the blocks resampled; all rows in one call, in batches."""
    s = _scores(np.asarray(diffs, dtype=float), tol)
    point = s.mean(axis=1)
    if s.shape[1] < 2:
        return point, point
    batch = max(1, BATCH_NUMBERS // s.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ci = stats.bootstrap((s,), np.mean, axis=-1, vectorized=True, n_resamples=resamples, confidence_level=level,
                             method="percentile", batch=batch, rng=np.random.default_rng(0)).confidence_interval  # fmt: skip
    lo, hi = np.atleast_1d(ci.low).astype(float), np.atleast_1d(ci.high).astype(float)
    bad = ~(np.isfinite(lo) & np.isfinite(hi))
    lo[bad], hi[bad] = point[bad], point[bad]
    return lo, hi


def shared_blocks(groups: dict[str, pd.Series]) -> bool:
    """Whether the groups (values indexed by block: a seed, or a seed and other settings) hold
    the same blocks, each once, two or more of them: then they can be compared block by block."""
    sets = [frozenset(v.index) for v in groups.values()]
    return (len(groups) >= 2 and all(v.index.is_unique for v in groups.values()) and len(set(sets)) == 1
            and len(sets[0]) >= 2)  # fmt: skip


def _usable(groups: dict[str, pd.Series]) -> tuple[bool, dict[str, pd.Series], pd.DataFrame | None]:
    """The design the groups allow (paired when they share two or more blocks with finite
    values in every group) and the groups' finite values (paired: as one table, blocks x groups)."""
    groups = {k: pd.Series(v, dtype=float) for k, v in groups.items()}
    if shared_blocks(groups):
        table = pd.DataFrame(groups)
        table = table[np.isfinite(table.to_numpy()).all(axis=1)]
        if len(table) >= 2:
            return True, groups, table
    kept = {k: v[np.isfinite(v.to_numpy())] for k, v in groups.items()}
    return False, {k: v for k, v in kept.items() if len(v)}, None


def _omnibus(paired: bool, groups: dict[str, pd.Series], table: pd.DataFrame | None, tol: float) -> dict:
    """Friedman's test (blocks: the table's rows, each snapped to ``tol``) or Kruskal-Wallis
    (the pooled values snapped), with the verdict ``equivalent`` when every value lies within
    ``tol`` of every other, ``differ`` at p < alpha (before any correction), else ``undecided``."""
    if paired:
        assert table is not None  # _usable gives a paired design its table
        values = np.apply_along_axis(snap, 1, table.to_numpy(), tol)
        constant = bool((np.ptp(values, axis=1) == 0).all())  # every block a tie: scipy divides by zero
        stat, p = (0.0, 1.0) if constant else stats.friedmanchisquare(*values.T)
        test, n, pooled = "Friedman", len(table), table.to_numpy().ravel()
    else:
        pooled = np.concatenate([v.to_numpy() for v in groups.values()])
        snapped = snap(pooled, tol)
        cuts = np.cumsum([len(v) for v in groups.values()])[:-1]
        stat, p = stats.kruskal(*np.split(snapped, cuts)) if np.ptp(snapped) > 0 else (0.0, 1.0)
        test, n = "Kruskal-Wallis", len(pooled)
    tied = bool(np.ptp(pooled) <= tol)
    return dict(design=PAIRED if paired else INDEPENDENT, test=ALL_TIED if tied else test, a="all", b="all", statistic=float(stat),
                p=float(p), p_holm=float(p), effect=np.nan, effect_lo=np.nan, effect_hi=np.nan, n_a=n, n_b=np.nan,
                p_equivalence=np.nan, p_equivalence_holm=np.nan, direction=np.nan,
                verdict=EQUIVALENT if tied else ("differ" if p < ALPHA else UNDECIDED))  # fmt: skip


def compare_design(groups: dict[str, pd.Series], best: str | None = None, ci: bool = True, tol: float = 0.0) -> pd.DataFrame:
    """The omnibus test and the pairwise tests of ``groups`` (values, lower is better, indexed
    by block), for the design they have (:func:`shared_blocks`): Friedman and Wilcoxon
    signed-rank (paired), else Kruskal-Wallis and Mann-Whitney U, values within ``tol`` tied;
    pairwise p-values and TOST's Holm-adjusted over every pair, and one :func:`verdict` per pair
    (A's side). Effect = P(a lower than b) (paired superiority, or A12); its bootstrap
    confidence interval for the pairs holding ``best`` (every pair when ``best`` is None and
    ``ci``). Non-finite values are left out (and so the blocks holding them, when paired)."""
    paired, groups, table = _usable(groups)
    names = list(groups)
    rows = [_omnibus(paired, groups, table, tol)] if len(names) >= 3 or (len(names) == 2 and not paired) else []
    pairs = list(itertools.combinations(names, 2))
    wanted = [ci and (best is None or best in pair) for pair in pairs]
    found = []
    if paired and pairs:
        assert table is not None  # _usable gives a paired design its table
        col = {c: k for k, c in enumerate(table.columns)}
        values = table.to_numpy()
        ia, ib = np.array([col[a] for a, _ in pairs]), np.array([col[b] for _, b in pairs])
        diffs = (values[:, ib] - values[:, ia]).T
        r = _paired_pairs(diffs, tol)
        lo, hi = np.full(len(pairs), np.nan), np.full(len(pairs), np.nan)
        if any(wanted):
            lo[wanted], hi[wanted] = paired_cis(diffs[wanted], tol)
        for i, (a, b) in enumerate(pairs):
            found.append(dict(test="Wilcoxon signed-rank", a=a, b=b, n_a=len(table), n_b=len(table), lo=lo[i], hi=hi[i],
                              **{k: v[i] for k, v in r.items()}))  # fmt: skip
    else:
        for (a, b), want in zip(pairs, wanted):
            x, y = groups[a].to_numpy(), groups[b].to_numpy()
            ci_lo, ci_hi = effect_ci(x, y, False, tol) if want else (np.nan, np.nan)
            found.append(dict(test="Mann-Whitney U", a=a, b=b, n_a=len(x), n_b=len(y), lo=ci_lo, hi=ci_hi,
                              **_independent_pair(x, y, tol)))  # fmt: skip
    p_holm: np.ndarray | list[float] = holm([f["p"] for f in found]) if found else []
    eq_holm: np.ndarray | list[float] = holm([f["p_eq"] for f in found]) if found else []
    for f, ph, eh in zip(found, p_holm, eq_holm):
        rows.append(dict(design=PAIRED if paired else INDEPENDENT, test=ALL_TIED if f["tied"] else f["test"], a=f["a"], b=f["b"],
                         statistic=float(f["statistic"]), p=float(f["p"]), p_holm=float(ph), effect=float(f["effect"]),
                         effect_lo=float(f["lo"]), effect_hi=float(f["hi"]), n_a=f["n_a"], n_b=f["n_b"],
                         p_equivalence=float(f["p_eq"]), p_equivalence_holm=float(eh),
                         verdict=verdict(bool(f["tied"]), float(ph), float(f["direction"]), float(eh)),
                         direction=float(f["direction"])))  # fmt: skip
    return pd.DataFrame(rows, columns=DESIGN_COLUMNS)


def smallest_p(design: str, n: int) -> float:
    """The smallest two-sided p-value a pairwise test can give with ``n`` blocks (paired: Wilcoxon's
    signed-rank test, 2 / 2^n) or ``n`` runs per group (Mann-Whitney U, 2 / C(2n, n)).

    >>> smallest_p(PAIRED, 3), round(smallest_p(INDEPENDENT, 3), 3)
    (0.25, 0.1)
    """
    if design == PAIRED:
        return 2.0 * 2.0**-n
    return 2.0 * math.exp(2 * math.lgamma(n + 1) - math.lgamma(2 * n + 1))  # 2 / C(2n, n), without an integer too large for a float


def friedman(scores: pd.DataFrame, alpha: float = ALPHA, tol: pd.Series | float = 0.0) -> dict:
    """Friedman's test on ``scores`` ((N instances, k configurations), lower is better, no
    missing cells, each instance's scores within ``tol`` (per instance) tied): the ranks within
    each instance (ties averaged), their means, the test (the sign test, binomial, when k = 2,
    which Friedman's test then equals but for ties), Nemenyi's pairwise p-values and critical
    difference at ``alpha``.

    Nemenyi: configurations i and j differ when |R_i - R_j| > CD = q_alpha sqrt(k (k + 1) / (6 N)),
    q_alpha the studentized range quantile for k groups and infinite degrees of freedom over
    sqrt 2; p_ij = P(Q_k > sqrt 2 |R_i - R_j| / sqrt(k (k + 1) / (6 N))).
    """
    n, k = scores.shape
    tols = tol if isinstance(tol, pd.Series) else pd.Series(float(tol), index=scores.index)
    scores = pd.DataFrame([snap(row.to_numpy(), float(tols.get(i, 0.0))) for i, row in scores.iterrows()], index=scores.index,
                          columns=scores.columns)  # fmt: skip
    ranks = scores.rank(axis=1, method="average")
    mean = ranks.mean(axis=0)
    if k == 2:
        a, b = scores.columns
        wins = int((scores[a] < scores[b]).sum())
        losses = int((scores[a] > scores[b]).sum())
        p = stats.binomtest(wins, wins + losses).pvalue if wins + losses else 1.0
        test, statistic = "sign test", float(wins)
    elif (ranks.nunique(axis=1) == 1).all():  # every instance a k-way tie: scipy would divide by zero
        test, statistic, p = "Friedman", 0.0, 1.0
    else:
        statistic, p = stats.friedmanchisquare(*(scores[c].to_numpy() for c in scores.columns))
        test = "Friedman"
    se = math.sqrt(k * (k + 1) / (6.0 * n))
    cd = stats.studentized_range.ppf(1 - alpha, k, np.inf) / math.sqrt(2) * se
    pairs = []
    for a, b in itertools.combinations(scores.columns, 2):
        q = math.sqrt(2) * abs(mean[a] - mean[b]) / se
        pairs.append(dict(a=a, b=b, rank_a=mean[a], rank_b=mean[b], p_nemenyi=float(stats.studentized_range.sf(q, k, np.inf))))
    return dict(test=test, statistic=float(statistic), p=float(p), instances=n, configurations=k,
                mean_ranks=mean.sort_values(kind="stable"), ranks=ranks, cd=cd, alpha=alpha, pairs=pd.DataFrame(pairs))  # fmt: skip


def interaction(values: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """The interaction of two settings on ``values`` (N,) with levels ``a`` and ``b`` (N,),
    the aligned rank transform's F test (Higgins and Tashtoush 1994; Wobbrock et al., CHI 2011):
    the values aligned for the interaction (the cell means' interaction part plus the residual),
    ranked, and the interaction's F of a two-way analysis of variance on the ranks, every other
    setting and the seed as replication. Returns (F, p); (0, 1) when the ranks do not vary or a
    cell is empty. By hand: neither scipy nor the package's dependencies have it (statsmodels'
    ANOVA would be a dependency for a dozen lines)."""
    y = np.asarray(values, dtype=float)
    keep = np.isfinite(y)
    y = y[keep]
    ia, la = pd.factorize(np.asarray(a)[keep])
    ib, lb = pd.factorize(np.asarray(b)[keep])
    n_a, n_b = len(la), len(lb)
    cell = ia * n_b + ib
    counts = np.bincount(cell, minlength=n_a * n_b)
    if n_a < 2 or n_b < 2 or (counts == 0).any() or len(y) <= n_a * n_b:
        return 0.0, 1.0

    def parts(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        mean_cell = np.bincount(cell, v, n_a * n_b) / counts
        mean_a = np.bincount(ia, v, n_a) / np.bincount(ia, minlength=n_a)
        mean_b = np.bincount(ib, v, n_b) / np.bincount(ib, minlength=n_b)
        return mean_cell[cell], mean_a[ia], mean_b[ib], float(v.mean())

    c, ma, mb, mu = parts(y)
    r = stats.rankdata((y - c) + (c - ma - mb + mu))
    rc, ra, rb, rm = parts(r)
    ss_ab, ss_err = float(((rc - ra - rb + rm) ** 2).sum()), float(((r - rc) ** 2).sum())
    df_ab, df_err = (n_a - 1) * (n_b - 1), len(y) - n_a * n_b
    if ss_err <= 0 or ss_ab <= 1e-12 * ss_err:
        return 0.0, 1.0
    f = (ss_ab / df_ab) / (ss_err / df_err)
    return float(f), float(stats.f.sf(f, df_ab, df_err))
