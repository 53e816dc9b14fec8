"""Statistical tests of the report: Kruskal-Wallis and pairwise Mann-Whitney U with Holm's
correction and the Vargha-Delaney A12 within pooled runs; Friedman's test with Nemenyi's
post-hoc test across instances (Demšar, "Statistical comparisons of classifiers over multiple
data sets", JMLR 7, 2006)."""

from __future__ import annotations

import itertools
import math

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
