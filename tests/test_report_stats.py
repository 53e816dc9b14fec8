"""The report's statistics against known answers: hand computations, published worked examples
(Demšar 2006's critical difference, Holm's step-down) and scipy on made-up data."""

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from zrp_ga.report import stats
from zrp_ga.report.compare import factorial, within_instances


def test_friedman_with_seeds_as_blocks_known_answer():
    # Three configurations, six seeds, A < B < C on every seed: rank sums 6, 12, 18, so
    # chi2 = 12 / (n k (k+1)) sum R^2 - 3 n (k+1) = 12/72 * 504 - 72 = 12 and, with 2 degrees of
    # freedom, p = exp(-12 / 2).
    seeds = range(6)
    base = pd.Series([10.0, 0.1, 5.0, 100.0, 1.0, 50.0], index=seeds)  # a seed effect far larger than the configurations'
    groups = {"A": base + 1, "B": base + 2, "C": base + 3}
    t = stats.compare_design(groups)
    omni = t[t["a"] == "all"].iloc[0]
    assert omni["test"] == "Friedman" and omni["design"] == stats.PAIRED
    assert omni["statistic"] == pytest.approx(12.0) and omni["p"] == pytest.approx(math.exp(-6.0))
    # the same runs as independent samples: Kruskal-Wallis sees the seeds' spread and nothing else
    assert sps.kruskal(*groups.values()).pvalue > 0.5
    # pairwise: Wilcoxon signed-rank, six positive differences out of six: exact p = 2 / 2^6, Holm x3
    pairs = t[t["a"] != "all"].set_index(["a", "b"])
    assert set(pairs["test"]) == {"Wilcoxon signed-rank"}
    assert pairs.loc[("A", "B"), "p"] == pytest.approx(2 / 64)
    assert pairs.loc[("A", "B"), "p_holm"] == pytest.approx(3 * 2 / 64)
    assert pairs.loc[("A", "C"), "effect"] == 1.0  # A ends lower on every seed


@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_paired_tests_equal_scipy_on_random_data():
    rng = np.random.default_rng(3)
    data = {c: pd.Series(rng.normal(loc, 1.0, 12).round(1), index=range(12)) for c, loc in (("a", 0.0), ("b", 0.4), ("c", 1.0), ("d", 1.1))}
    t = stats.compare_design(data, ci=False)
    omni = t[t["a"] == "all"].iloc[0]
    ref = sps.friedmanchisquare(*(v.to_numpy() for v in data.values()))
    assert omni["statistic"] == pytest.approx(ref.statistic) and omni["p"] == pytest.approx(ref.pvalue)
    pairs = t[t["a"] != "all"]
    expected = [sps.wilcoxon(data[a].to_numpy(), data[b].to_numpy()).pvalue for a, b in zip(pairs["a"], pairs["b"])]
    assert pairs["p"].to_numpy() == pytest.approx(expected)
    m = len(expected)  # Holm by hand: the i-th smallest times (m - i), made monotone, capped at 1
    order = np.argsort(expected)
    adjusted = np.minimum(1.0, np.maximum.accumulate([(m - i) * expected[j] for i, j in enumerate(order)]))
    assert pairs["p_holm"].to_numpy()[order] == pytest.approx(adjusted)


def test_unshared_seeds_fall_back_to_kruskal_and_mann_whitney():
    rng = np.random.default_rng(4)
    a = pd.Series(rng.normal(0, 1, 8), index=range(8))
    b = pd.Series(rng.normal(1, 1, 8), index=range(8, 16))  # other seeds
    c = pd.Series(rng.normal(2, 1, 8), index=range(16, 24))
    t = stats.compare_design({"a": a, "b": b, "c": c}, ci=False)
    omni = t[t["a"] == "all"].iloc[0]
    assert omni["test"] == "Kruskal-Wallis" and omni["design"] == stats.INDEPENDENT
    assert omni["p"] == pytest.approx(sps.kruskal(a, b, c).pvalue)
    ab = t[(t["a"] == "a") & (t["b"] == "b")].iloc[0]
    assert ab["p"] == pytest.approx(sps.mannwhitneyu(a, b, alternative="two-sided").pvalue)
    assert ab["effect"] == pytest.approx(np.mean(a.to_numpy()[:, None] < b.to_numpy()[None, :]))  # no ties: A12 = P(a < b)


def test_holm_worked_example():
    # Holm's procedure on four hypotheses, p = 0.01, 0.04, 0.03, 0.005, alpha = 0.05: the sorted
    # p-values times 4, 3, 2, 1 are 0.02, 0.03, 0.06, 0.04, made non-decreasing 0.02, 0.03, 0.06,
    # 0.06: H1 and H4 rejected, H2 and H3 not.
    adjusted = stats.holm(np.array([0.01, 0.04, 0.03, 0.005]))
    assert adjusted == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert (adjusted < 0.05).tolist() == [True, False, False, True]


def test_nemenyi_critical_difference_of_demsars_example():
    # Demšar (2006), section 3.2.2: four classifiers on 14 data sets, q_0.05 = 2.569, CD = 2.569
    # sqrt(4 * 5 / (6 * 14)) = 1.25.
    rng = np.random.default_rng(0)
    scores = pd.DataFrame(rng.random((14, 4)), columns=list("abcd"))
    assert stats.friedman(scores)["cd"] == pytest.approx(2.569 * math.sqrt(20 / 84), abs=1e-3)
    assert round(stats.friedman(scores)["cd"], 2) == 1.25


def test_smallest_p_is_what_scipy_gives_at_the_extreme():
    for n in (3, 5, 8):
        assert stats.smallest_p(stats.PAIRED, n) == pytest.approx(sps.wilcoxon(np.arange(1.0, n + 1)).pvalue)
        x, y = np.arange(n, dtype=float), np.arange(n, 2 * n, dtype=float)
        assert stats.smallest_p(stats.INDEPENDENT, n) == pytest.approx(sps.mannwhitneyu(x, y, method="exact").pvalue)


def test_bootstrap_intervals_hold_the_estimate_and_narrow_with_more_data():
    rng = np.random.default_rng(5)
    widths = []
    for n in (10, 80):
        x, y = rng.normal(0, 1, n), rng.normal(0.5, 1, n)
        for paired, est in ((False, stats.a12(x, y)), (True, stats.paired_superiority(x, y))):
            lo, hi = stats.effect_ci(x, y, paired)
            assert lo <= est <= hi
            widths.append(hi - lo)
    assert widths[2] < widths[0] and widths[3] < widths[1]
    lo, hi = stats.effect_ci(np.arange(5.0), np.arange(10.0, 15.0), paired=False)  # every run of A below every run of B
    assert (lo, hi) == (1.0, 1.0)


def _runs_frame(rows):
    df = pd.DataFrame(rows, columns=["run", "configuration", "instance", "seed", "final_cost", "final_over_ref", "x", "y"])
    return df.assign(score=df["final_over_ref"])


def _asked(df, tol=0.0):
    """Every instance's question: the final cost (as ``score``), values within ``tol`` tied."""
    return {i: dict(metric="final cost / f_ref", column="score", tol=tol, tied=False, at_floor=False, level=math.nan)
            for i in df["instance"].unique()}  # fmt: skip


def test_within_instances_pairs_by_seed_and_corrects_over_instances():
    rows = []
    for inst, effect in (("I1", 1.0), ("I2", 0.0)):  # on I2 the two configurations end alike
        for seed in range(6):
            base = 10.0**seed  # seeds differ by decades: only a paired test sees the configurations' difference
            for c, shift in (("good", 0.0), ("bad", effect)):
                rows.append((f"{inst}{c}{seed}", c, inst, seed, base + shift, base + shift, c, ""))
    df = _runs_frame(rows)
    w = within_instances(df, _asked(df))
    i1 = w[(w["instance"] == "I1") & (w["a"] != "all")].iloc[0]
    assert i1["test"] == "Wilcoxon signed-rank" and i1["p"] == pytest.approx(2 / 64)  # six of six: exact
    assert sps.mannwhitneyu(*[[r[4] for r in rows if r[2] == "I1" and r[1] == c] for c in ("good", "bad")]).pvalue > 0.5
    assert w[w["instance"] == "I1"]["best"].iloc[0] == "good"
    i2 = w[(w["instance"] == "I2") & (w["a"] != "all")].iloc[0]
    assert i2["p"] == 1.0 and i2["effect"] == 0.5  # every seed a tie


def test_factorial_main_effects_paired_by_the_other_settings():
    rows = []
    rng = np.random.default_rng(1)
    for inst in ("I1", "I2"):
        for seed in range(5):
            for y in ("y0", "y1"):
                base = float(rng.uniform(1, 100))  # every (seed, y) block its own scale
                for x in ("x0", "x1"):
                    v = base * (1.5 if x == "x1" else 1.0)
                    rows.append((f"{inst}{seed}{x}{y}", f"{x} {y}", inst, seed, v, v, x, y))
    df = _runs_frame(rows)
    tests, medians = factorial(df, ["x", "y"], _asked(df))
    x = tests[(tests["setting"] == "x") & (tests["a"] != "all")].set_index("instance")
    assert set(x["design"]) == {stats.PAIRED}
    assert x.loc["I1", "n_a"] == 10  # blocks: 5 seeds x 2 values of y
    assert x.loc["I1", "p"] == pytest.approx(2 / 2**10)  # x1 worse in all ten blocks
    assert x.loc["I1", "p_holm"] == x.loc["I2", "p_holm"] == pytest.approx(2 * 2 / 2**10)  # Holm over the two instances
    assert x.loc["all", "n_a"] == 20 and x.loc["all", "effect"] == 1.0  # across instances: the instance joins the block
    assert set(medians[medians["setting"] == "x"]["instance"]) == {"I1", "I2", "all"}
    y = tests[(tests["setting"] == "y") & (tests["a"] != "all")].set_index("instance")
    assert (y["p"] > 0.05).all()  # y's blocks are the (seed, x) pairs: its values differ at random


def test_nemenyi_pairwise_p_is_alpha_at_the_critical_difference():
    # Demšar's rule: two configurations differ at level alpha when their mean ranks differ by more
    # than CD (1.25 in his four-on-14 example, with q_0.05 = 2.569 from his Table 5). A pair whose
    # ranks differ by exactly 2.569 sqrt(20 / 84) must then have p = 0.05; by 2 x that, p < 0.05.
    scores = pd.DataFrame(np.tile([1.0, 2.0, 3.0, 4.0], (14, 1)), columns=list("abcd"))
    result = stats.friedman(scores)  # mean ranks 1, 2, 3, 4
    se = math.sqrt(20 / 84)
    pairs = result["pairs"].set_index(["a", "b"])["p_nemenyi"]
    # mean ranks 1 apart (a-b): q = sqrt 2 x 1 / se; the p at the CD itself, from the same
    # distribution: P(Q_4 > 2.569 sqrt 2) = 0.05 (Demšar's q_alpha is the studentized range over sqrt 2)
    assert sps.studentized_range.sf(2.569 * math.sqrt(2), 4, np.inf) == pytest.approx(0.05, abs=2e-4)
    expected_ab = sps.studentized_range.sf(math.sqrt(2) * 1.0 / se, 4, np.inf)
    assert pairs[("a", "b")] == pytest.approx(expected_ab, rel=1e-9)
    assert pairs[("a", "b")] > 0.05 > pairs[("a", "c")]  # 1 rank < CD = 1.25 < 2 ranks
    assert pairs[("a", "d")] < pairs[("a", "c")] < pairs[("a", "b")]


def test_signed_rank_equals_scipy_exact_permutation_and_normal():
    rng = np.random.default_rng(7)
    plain = rng.normal(0.3, 1.0, (20, 12))  # no ties, no zeros: scipy's exact test
    w, p = stats.signed_rank(plain)
    ref = sps.wilcoxon(plain, axis=-1, method="exact")
    assert p == pytest.approx(ref.pvalue)
    assert w == pytest.approx(np.where(plain > 0, sps.rankdata(np.abs(plain), axis=-1), 0).sum(axis=-1))  # W+ by hand
    tied = rng.normal(0.3, 1.0, (6, 10)).round(1)  # ties and zeros: scipy's exact permutation test (2^10 sign patterns)
    tied[0, :3] = 0.0
    for row, pr in zip(tied, stats.signed_rank(tied)[1]):
        assert pr == pytest.approx(sps.wilcoxon(row, method=sps.PermutationMethod()).pvalue)
    for alternative in ("greater", "less"):
        assert stats.signed_rank(tied, alternative)[1][1] == pytest.approx(
            sps.wilcoxon(tied[1], alternative=alternative, method=sps.PermutationMethod()).pvalue)
    big = rng.normal(0.1, 1.0, (3, 80))  # beyond 50 differences: the normal approximation
    assert stats.signed_rank(big)[1] == pytest.approx(sps.wilcoxon(big, axis=-1, method="asymptotic").pvalue)
    assert stats.signed_rank(np.zeros((1, 5)))[1][0] == 1.0  # nothing left: no evidence


def test_ties_within_the_tolerance_and_the_verdicts():
    # differences 0.004 on every one of 8 seeds: a difference with tol 0, the same result within tol 0.01
    x = pd.Series(np.arange(8.0), index=range(8))
    y = x + 0.004
    strict = stats.compare_design({"a": x, "b": y}, tol=0.0)
    assert strict["verdict"].iloc[0] == stats.BETTER and strict["p"].iloc[0] == pytest.approx(2 / 2**8)
    loose = stats.compare_design({"a": x, "b": y}, tol=0.01)
    assert loose["verdict"].iloc[0] == stats.EQUIVALENT and loose["test"].iloc[0] == stats.ALL_TIED
    assert loose["effect"].iloc[0] == 0.5
    # TOST: differences spread around 0 well inside +-1 on 12 seeds: equivalent as a finding, p from scipy's one-sided tests
    rng = np.random.default_rng(2)
    d = np.r_[rng.uniform(-0.3, 0.3, 12), 1.2, -1.1]  # two differences beyond the tolerance, the rest well inside
    t = stats.compare_design({"a": pd.Series(np.zeros(14)), "b": pd.Series(d)}, tol=1.0)
    up = sps.wilcoxon(d + 1.0, alternative="greater").pvalue
    down = sps.wilcoxon(d - 1.0, alternative="less").pvalue
    assert t["p_equivalence"].iloc[0] == pytest.approx(max(up, down)) and t["verdict"].iloc[0] == stats.EQUIVALENT
    assert t["test"].iloc[0] == "Wilcoxon signed-rank"  # not every run within the tolerance: the test decided
    few = stats.compare_design({"a": pd.Series(np.zeros(3)), "b": pd.Series(d[:3])}, tol=1.0)
    assert few["verdict"].iloc[0] == stats.EQUIVALENT  # three differences, all within 1: equivalent on their face
    wide = stats.compare_design({"a": pd.Series(np.zeros(3)), "b": pd.Series([0.5, -2.0, 3.0])}, tol=1.0)
    assert wide["verdict"].iloc[0] == stats.UNDECIDED  # 3 seeds can neither separate nor join them


def test_interaction_f_equals_a_two_way_anova_on_the_aligned_ranks_by_least_squares():
    rng = np.random.default_rng(4)
    a = np.repeat(["a0", "a1", "a2"], 16)
    b = np.tile(np.repeat(["b0", "b1"], 8), 3)
    crossing = np.where((a == "a2") == (b == "b1"), 1.0, 0.0)  # a2 best with b0, worst with b1
    y = crossing + rng.normal(0, 0.3, len(a))
    f, p = stats.interaction(y, a, b)
    # independently: align for the interaction, rank, then the interaction's F from the residual sums of squares of
    # the additive and the full (cell means) linear models, by numpy's least squares
    df = pd.DataFrame({"y": y, "a": a, "b": b})
    cell = df.groupby(["a", "b"])["y"].transform("mean")
    r = sps.rankdata((df["y"] - cell) + (cell - df.groupby("a")["y"].transform("mean") - df.groupby("b")["y"].transform("mean")
                                         + df["y"].mean()))  # fmt: skip
    additive = pd.get_dummies(df[["a", "b"]], drop_first=True).astype(float).assign(one=1.0).to_numpy()
    full = pd.get_dummies(df["a"] + df["b"]).astype(float).to_numpy()
    rss = [np.sum((r - m @ np.linalg.lstsq(m, r, rcond=None)[0]) ** 2) for m in (additive, full)]
    f_ref = ((rss[0] - rss[1]) / 2) / (rss[1] / (len(r) - 6))
    assert f == pytest.approx(f_ref) and p == pytest.approx(sps.f.sf(f_ref, 2, len(r) - 6)) and p < 0.001
    parallel = np.where(a == "a2", 1.0, 0.0) + np.where(b == "b1", 0.5, 0.0) + rng.normal(0, 0.3, len(a))
    assert stats.interaction(parallel, a, b)[1] > 0.01


def test_the_effect_interval_of_many_runs_stays_in_bounded_memory():
    """A12's bootstrap on 20,000 runs a side: as pairs it would hold 20,000 x 20,000 numbers per
    resample (3.2 GB); from ranks, in batches, it stays below 100 MB."""
    import tracemalloc

    rng = np.random.default_rng(0)
    x, y = rng.normal(0, 1, 20_000), rng.normal(0.1, 1, 20_000)
    tracemalloc.start()
    lo, hi = stats.effect_ci(x, y, paired=False, resamples=100)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    a12 = stats.a12(x, y)
    assert lo < a12 < hi and hi - lo < 0.03 and peak < 100e6
    assert a12 == pytest.approx(1 - sps.mannwhitneyu(x, y).statistic / 20_000**2)
