"""The report's conclusions in sentences, generated from its statistics: which settings matter,
on which instances, with the test, the p-value after correction and the effect size with its
confidence interval, and "no significant difference" where that is the answer."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from zrp_ga.report import stats
from zrp_ga.report.common import ALPHA
from zrp_ga.report.labels import describe


def p_text(p: float) -> str:
    """A p-value as a reader wants it: two significant digits, ``p < 1e-10`` below that.

    >>> p_text(0.0123), p_text(1e-14), p_text(0.5)
    ('p = 0.012', 'p < 1e-10', 'p = 0.5')
    """
    return "p < 1e-10" if p < 1e-10 else f"p = {p:.2g}"


def effect_text(row: pd.Series, a: str, b: str) -> str:
    """``P(a lower than b) = e [lo, hi]``, oriented so that ``a`` is the row's a."""
    e, lo, hi = row["effect"], row["effect_lo"], row["effect_hi"]
    if row["a"] != a:
        e, lo, hi = 1 - e, 1 - hi, 1 - lo
    what = "in the same block" if row["design"] == stats.PAIRED else "for a random pair of runs"
    ci = f" [95% CI {lo:.2f}, {hi:.2f}]" if math.isfinite(lo) else ""
    return f"P({a} ends lower than {b}, {what}) = {e:.2f}{ci}"


def _count(n: int, word: str) -> str:
    return f"{n} {word}{'s' * (n != 1)}"


def _blocks_word(design: str, what: str) -> str:
    return f"paired by {what}" if design == stats.PAIRED else "independent runs"


def within(t: dict) -> list[str]:
    """One sentence per instance: do the configurations differ, which is best, against how many
    others it is significantly better, and what the design allows."""
    w = t["within"]
    if not len(w):
        return []
    out = []
    ratio = t["runs"].groupby(["instance", "configuration"])["final_over_ref"].median()
    n_inst = w["instance"].nunique()
    for instance, g in w.groupby("instance", sort=False):
        omni = g[g["a"] == "all"]
        pairs = g[g["a"] != "all"]
        best = str(g["best"].iloc[0])
        k = len(set(pairs["a"]) | set(pairs["b"]))
        design = str(pairs["design"].iloc[0])
        n = int(pairs["n_a"].min())
        setup = (f"{k} configurations paired by seed, {_count(n, 'seed')} shared by all" if design == stats.PAIRED
                 else f"{k} configurations, runs not sharing seeds (independent)")  # fmt: skip
        mine = pairs[(pairs["a"] == best) | (pairs["b"] == best)]
        better = mine[(mine["p_holm"] < ALPHA) & (np.where(mine["a"] == best, mine["effect"], 1 - mine["effect"]) > 0.5)]
        head = f"On {instance} ({setup}): "
        if len(omni):
            o = omni.iloc[0]
            corr = f" after Holm's correction over {n_inst} instances" if n_inst > 1 else ""
            verdict = "the configurations differ" if o["p_holm"] < ALPHA else "no significant difference between the configurations"
            stat = f"chi2 = {o['statistic']:.3g}" if o["test"] == "Friedman" else f"H = {o['statistic']:.3g}"
            head += f"{verdict} ({o['test']}, {stat}, {p_text(o['p_holm'])}{corr}). "
        r = ratio.get((instance, best), math.nan)
        head += f"Lowest median final cost: {best} ({r:.3g} x f_ref). "
        test = str(pairs["test"].iloc[0])
        if len(better):
            worst = better.loc[better["p_holm"].idxmax()]
            other = worst["b"] if worst["a"] == best else worst["a"]
            head += (f"It ends significantly lower than {len(better)} of the {k - 1} others ({test}, Holm, "
                     f"p <= {better['p_holm'].max():.2g}); ")  # fmt: skip
            rest = k - 1 - len(better)
            head += (f"not significantly lower than {_count(rest, 'other')}." if rest else "that is all of them.")
            head += f" Against the closest of them it beats, {other}: {effect_text(worst, best, str(other))}."
        floor_p = stats.smallest_p(design, n)
        m = len(pairs)
        limited = floor_p >= ALPHA or (m > 1 and floor_p * m >= ALPHA and not len(better))
        if not len(better):
            head += f"It is not significantly better than any other ({test}, Holm)."
            closest = mine.loc[mine["p"].idxmin()] if len(mine) else None
            if closest is not None and not limited:
                other = closest["b"] if closest["a"] == best else closest["a"]
                head += f" Against {other}: {effect_text(closest, best, str(other))}, {p_text(closest['p_holm'])} after Holm."
        if limited:
            head += (f" With {_count(n, 'seed' if design == stats.PAIRED else 'run')} the smallest p-value a pairwise test can give is "
                     f"{floor_p:.2g} (before correcting for {m} pairs): more seeds are needed to separate configurations.")  # fmt: skip
        out.append(head)
    return out


def factors(t: dict) -> list[str]:
    """One sentence per setting: on how many instances it matters, which value is best, and the
    effect across instances."""
    f, med = t["factors"], t["factor_medians"]
    if not len(f):
        return []
    out = []
    for key, g in f.groupby("setting", sort=False):
        per = g[(g["instance"] != "all") & (g["a"] == "all")]
        pooled = g[g["instance"] == "all"]
        inst_pairs = g[(g["instance"] != "all") & (g["a"] != "all")]
        name = {"refine": "the pseudo-inverse step", "algorithm": "the algorithm"}.get(key, describe(key, "\0").replace("\0", "").strip())
        m = med[(med["setting"] == key)]
        if len(per):  # three or more values: the omnibus test per instance
            sig = per[per["p_holm"] < ALPHA]
            where = f"on {len(sig)} of {len(per)} instances" if len(per) > 1 else ("on its instance" if len(sig) else "")
            test = per["test"].iloc[0]
        else:  # two values: the one pairwise test per instance
            per2 = inst_pairs  # their p_holm: corrected over the instances (tables.factorial)
            sig = per2[per2["p_holm"] < ALPHA]
            where = f"on {len(sig)} of {len(per2)} instances" if len(per2) > 1 else ""
            test = per2["test"].iloc[0] if len(per2) else ""
            per = per2
        design = g["design"].iloc[0]
        blocks = _blocks_word(design, "the other settings and the seed")
        corr = ", Holm over the instances" if len(per) > 1 else ""
        if len(sig):
            best_by = sig.groupby("best").size().sort_values(ascending=False)
            top = str(best_by.index[0])
            s = f"{name[0].upper() + name[1:]} matters{' ' + where if where else ''} ({test}, {blocks}{corr}; {p_text(sig['p_holm'].max()).replace('=', '<=')})"
            s += f"; best: {top} on {best_by.iloc[0]} of them" if len(per) > 1 else f"; best: {top}"
        else:
            lo = per["p_holm"].min() if len(per) else math.nan
            s = (f"{name[0].upper() + name[1:]} makes no significant difference" + (f" on any of the {len(per)} instances" if len(per) > 1 else "")
                 + f" ({test}, {blocks}{corr}; p >= {lo:.2g})")  # fmt: skip
        if t["floors"]["instance"].nunique() == 1 and len(inst_pairs):  # one instance: its effect, against the closest rival
            best = str(g["best"].iloc[0])
            mp = m[m["instance"] != "all"].set_index("value")["median_final_over_ref"]
            s += ". Median final / f_ref: " + ", ".join(f"{v} {x:.3g}" for v, x in mp.sort_values().items())
            mine = inst_pairs[(inst_pairs["a"] == best) | (inst_pairs["b"] == best)]
            if len(mine):
                row = mine.loc[mine["p"].idxmax()]
                other = str(row["b"] if row["a"] == best else row["a"])
                s += f"; {effect_text(row, best, other)}, {p_text(row['p_holm'])}"
        if len(pooled) and pooled["instance"].nunique() and t["floors"]["instance"].nunique() > 1:
            pp = pooled[pooled["a"] != "all"]
            best = str(pooled["best"].iloc[0])
            mp = m[m["instance"] == "all"].set_index("value")["median_final_over_ref"]
            meds = ", ".join(f"{v} {x:.3g}" for v, x in mp.sort_values().items())
            s += f". Across instances (final / f_ref, median: {meds})"
            mine = pp[(pp["a"] == best) | (pp["b"] == best)]
            if len(mine):
                row = mine.loc[mine["p"].idxmax()]  # the closest rival
                other = str(row["b"] if row["a"] == best else row["a"])
                s += f": {effect_text(row, best, other)}, {p_text(row['p_holm'])}"
        out.append(s + ".")
    return out


def across(t: dict) -> list[str]:
    """The Friedman test across instances, in words."""
    f = t["friedman"]
    if f is None:
        return [f"Ranks across instances: not computed ({t['friedman_note'].strip()})."]
    ranks = f["mean_ranks"]
    best = ranks.index[0]
    if f["test"] == "sign test":
        verdict = "differ" if f["p"] < ALPHA else "do not differ significantly"
        return [f"Across the {f['instances']} instances the two configurations {verdict} (sign test on the instances' median "
                f"final costs, {p_text(f['p'])}); {best} ranks first on average ({ranks.iloc[0]:.2f})."]  # fmt: skip
    if f["p"] >= ALPHA:
        return [f"Across the {f['instances']} instances the ranks of the {f['configurations']} configurations do not differ "
                f"significantly (Friedman, chi2 = {f['statistic']:.3g}, {p_text(f['p'])}): the data support no ranking."]  # fmt: skip
    within_cd = int((ranks <= ranks.iloc[0] + f["cd"]).sum()) - 1
    return [f"Across the {f['instances']} instances the ranks differ (Friedman, chi2 = {f['statistic']:.3g}, {p_text(f['p'])}). "
            f"Best mean rank: {best} ({ranks.iloc[0]:.2f} of {f['configurations']}); {_count(within_cd, 'other configuration')} "
            f"lie within Nemenyi's critical difference ({f['cd']:.2f}) of it, which the test cannot tell apart from it."]  # fmt: skip


def sentences(t: dict) -> dict[str, list[str]]:
    """The conclusions by heading: across instances, each setting, within each instance."""
    return {"Across instances": across(t) if t["floors"]["instance"].nunique() > 1 else [],
            "Each setting over the others": factors(t), "Within each instance": within(t)}
