"""Statistical tests of the report (Demšar, "Statistical comparisons of classifiers over
multiple data sets", JMLR 7, 2006).

- Groups that share their blocks (configurations run with the same seeds on one instance, or
  the values of a setting over the same other settings and seeds): Friedman's test with the
  blocks as blocks, pairwise Wilcoxon signed-rank tests with Holm's correction, and the paired
  probability of superiority (the share of blocks where A ends lower, ties counting half).
- Otherwise: Kruskal-Wallis, pairwise Mann-Whitney U with Holm's correction and the
  Vargha-Delaney A12 = P(a run of A ends lower than a run of B) + P(tie)/2.
- Effect sizes come with 95% bootstrap confidence intervals (scipy.stats.bootstrap, percentile).
- Across instances: Friedman's test with Nemenyi's post-hoc test and critical difference.

Every effect size here is the chance that A does better (lower) than B: 0.5 is no effect."""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pandas as pd
from scipy import stats


def holm(p: np.ndarray) -> np.ndarray:
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


COMPARE_COLUMNS = ["metric", "test", "a", "b", "statistic", "p", "p_holm", "a12", "n_a", "n_b"]
DESIGN_COLUMNS = ["design", "test", "a", "b", "statistic", "p", "p_holm", "effect", "effect_lo", "effect_hi", "n_a", "n_b"]
PAIRED, INDEPENDENT = "paired by block", "independent runs"


def a12(x: np.ndarray, y: np.ndarray) -> float:
    """Vargha and Delaney's A12: P(X < Y) + P(X = Y) / 2 over all pairs (lower is better).

    >>> a12(np.array([1.0, 2.0]), np.array([2.0, 3.0]))
    0.875
    """
    x, y = np.asarray(x, dtype=float)[:, None], np.asarray(y, dtype=float)[None, :]
    return float(np.mean((x < y) + 0.5 * (x == y)))


def paired_superiority(x: np.ndarray, y: np.ndarray) -> float:
    """The share of blocks in which X ends lower than Y, ties counting half.

    >>> paired_superiority(np.array([1.0, 2.0, 3.0]), np.array([2.0, 2.0, 1.0]))
    0.5
    """
    d = np.asarray(y, dtype=float) - np.asarray(x, dtype=float)
    return float(np.mean((d > 0) + 0.5 * (d == 0)))


def effect_ci(x: np.ndarray, y: np.ndarray, paired: bool, level: float = 0.95, resamples: int = 2000) -> tuple[float, float]:
    """A ``level`` bootstrap confidence interval (percentile method, ``resamples`` resamples,
    seeded: the same data give the same interval) of :func:`paired_superiority` (``paired``:
    blocks resampled) or :func:`a12` (each sample resampled on its own)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if paired:
        def statistic(a, b, axis=-1):
            d = b - a
            return np.mean((d > 0) + 0.5 * (d == 0), axis=axis)
    else:
        def statistic(a, b, axis=-1):
            a, b = np.moveaxis(a, axis, -1)[..., :, None], np.moveaxis(b, axis, -1)[..., None, :]
            return np.mean((a < b) + 0.5 * (a == b), axis=(-2, -1))
    if len(x) < 2 or len(y) < 2:
        v = statistic(x, y)
        return float(v), float(v)
    with warnings.catch_warnings():  # a degenerate resample distribution (every resample equal) is a point interval
        warnings.simplefilter("ignore")
        ci = stats.bootstrap((x, y), statistic, paired=paired, vectorized=True, n_resamples=resamples, confidence_level=level,
                             method="percentile", rng=np.random.default_rng(0)).confidence_interval  # fmt: skip
    lo, hi = float(ci.low), float(ci.high)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        v = float(statistic(x, y))
        return v, v
    return lo, hi


def shared_blocks(groups: dict[str, pd.Series]) -> bool:
    """Whether the groups (values indexed by block: a seed, or a seed and other settings) hold
    the same blocks, each once, two or more of them: then they can be compared block by block."""
    sets = [frozenset(v.index) for v in groups.values()]
    return (len(groups) >= 2 and all(v.index.is_unique for v in groups.values()) and len(set(sets)) == 1
            and len(sets[0]) >= 2)  # fmt: skip


def _wilcoxon(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Wilcoxon's signed-rank test, two-sided (scipy's default method: exact for small samples
    without ties or zeros); p = 1 when every difference is zero."""
    if np.all(x == y):
        return 0.0, 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy warns that ties or zeros force the normal approximation
        res = stats.wilcoxon(x, y, alternative="two-sided")
    return float(res.statistic), float(res.pvalue)


def compare_design(groups: dict[str, pd.Series], best: str | None = None, ci: bool = True) -> pd.DataFrame:
    """The omnibus test and the pairwise tests of ``groups`` (values, lower is better, indexed
    by block), for the design they have (:func:`shared_blocks`): Friedman and Wilcoxon
    signed-rank (paired), else Kruskal-Wallis and Mann-Whitney U; pairwise p-values Holm-adjusted
    over every pair. Effect = P(a lower than b) (paired superiority, or A12); its bootstrap
    confidence interval for the pairs holding ``best`` (every pair when ``best`` is None and
    ``ci``). Non-finite values are left out (and so the blocks holding them, when paired)."""
    groups = {k: pd.Series(v, dtype=float) for k, v in groups.items()}
    paired = shared_blocks(groups)
    if paired:
        table = pd.DataFrame(groups)
        table = table[np.isfinite(table).all(axis=1)]
        paired = len(table) >= 2
    if not paired:
        groups = {k: v[np.isfinite(v)] for k, v in groups.items()}
        groups = {k: v for k, v in groups.items() if len(v)}
    design = PAIRED if paired else INDEPENDENT
    names = list(groups)
    rows = []
    if len(names) >= 3 or (len(names) == 2 and not paired):
        if paired:
            constant = bool((table.nunique(axis=1) == 1).all())  # every block a tie: scipy divides by zero
            stat, p = (0.0, 1.0) if constant else stats.friedmanchisquare(*(table[c].to_numpy() for c in names))
            test, n = "Friedman", len(table)
        else:
            pooled = np.concatenate([v.to_numpy() for v in groups.values()])
            stat, p = stats.kruskal(*(v.to_numpy() for v in groups.values())) if np.ptp(pooled) > 0 else (0.0, 1.0)
            test, n = "Kruskal-Wallis", len(pooled)
        rows.append(dict(design=design, test=test, a="all", b="all", statistic=float(stat), p=float(p), p_holm=float(p),
                         effect=np.nan, effect_lo=np.nan, effect_hi=np.nan, n_a=n, n_b=np.nan))  # fmt: skip
    pairs = []
    for a, b in itertools.combinations(names, 2):
        if paired:
            x, y = table[a].to_numpy(), table[b].to_numpy()
            stat, p = _wilcoxon(x, y)
            test, effect = "Wilcoxon signed-rank", paired_superiority(x, y)
        else:
            x, y = groups[a].to_numpy(), groups[b].to_numpy()
            stat, p = stats.mannwhitneyu(x, y, alternative="two-sided")
            test, effect = "Mann-Whitney U", a12(x, y)
        lo = hi = np.nan
        if ci and (best is None or best in (a, b)):
            lo, hi = effect_ci(x, y, paired)
        pairs.append(dict(design=design, test=test, a=a, b=b, statistic=float(stat), p=float(p), effect=effect,
                          effect_lo=lo, effect_hi=hi, n_a=len(x), n_b=len(y)))  # fmt: skip
    for row, ph in zip(pairs, holm([r["p"] for r in pairs]) if pairs else []):
        row["p_holm"] = float(ph)
    return pd.DataFrame(rows + pairs, columns=DESIGN_COLUMNS)


def smallest_p(design: str, n: int) -> float:
    """The smallest two-sided p-value a pairwise test can give with ``n`` blocks (paired: Wilcoxon's
    signed-rank test, 2 / 2^n) or ``n`` runs per group (Mann-Whitney U, 2 / C(2n, n)).

    >>> smallest_p(PAIRED, 3), round(smallest_p(INDEPENDENT, 3), 3)
    (0.25, 0.1)
    """
    return 2.0 / 2**n if design == PAIRED else 2.0 / math.comb(2 * n, n)


def compare(groups: dict[str, np.ndarray], metric: str) -> pd.DataFrame:
    """Kruskal-Wallis across groups, then Mann-Whitney U for every pair, Holm-adjusted, with A12
    = P(a run of A ends lower than a run of B) + P(tie) / 2. Non-finite values are left out."""
    groups = {k: v[np.isfinite(v)] for k, v in groups.items()}
    groups = {k: v for k, v in groups.items() if len(v)}
    rows = []
    if len(groups) >= 2:
        pooled = np.concatenate(list(groups.values()))
        h, p = stats.kruskal(*groups.values()) if np.ptp(pooled) > 0 else (0.0, 1.0)  # all equal: scipy divides by 0
        rows.append(dict(metric=metric, test="Kruskal-Wallis", a="all", b="all", statistic=h, p=p, p_holm=p,
                         a12=np.nan, n_a=sum(map(len, groups.values())), n_b=np.nan))  # fmt: skip
    pairs = []
    for a, b in itertools.combinations(groups, 2):
        x, y = groups[a], groups[b]
        u, p = stats.mannwhitneyu(x, y, alternative="two-sided")
        pairs.append(dict(metric=metric, test="Mann-Whitney U", a=a, b=b, statistic=u, p=p,
                          a12=1.0 - u / (len(x) * len(y)), n_a=len(x), n_b=len(y)))  # fmt: skip
    if pairs:
        for row, ph in zip(pairs, holm([r["p"] for r in pairs])):
            row["p_holm"] = ph
    return pd.DataFrame(rows + pairs, columns=COMPARE_COLUMNS)


def friedman(scores: pd.DataFrame, alpha: float = 0.05) -> dict:
    """Friedman's test on ``scores`` ((N instances, k configurations), lower is better, no
    missing cells): the ranks within each instance (ties averaged), their means, the test (the
    sign test, binomial, when k = 2, which Friedman's test then equals but for ties), Nemenyi's
    pairwise p-values and critical difference at ``alpha``.

    Nemenyi: configurations i and j differ when |R_i - R_j| > CD = q_alpha sqrt(k (k + 1) / (6 N)),
    q_alpha the studentized range quantile for k groups and infinite degrees of freedom over
    sqrt 2; p_ij = P(Q_k > sqrt 2 |R_i - R_j| / sqrt(k (k + 1) / (6 N))).
    """
    n, k = scores.shape
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
                mean_ranks=mean.sort_values(), ranks=ranks, cd=cd, alpha=alpha, pairs=pd.DataFrame(pairs))  # fmt: skip
