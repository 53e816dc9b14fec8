"""The report's conclusions in sentences, generated from its statistics, and the same
conclusions for scripts (``conclusions.json``, :func:`records`).

Every sentence comes from a template below: a function of plain numbers and names that leaves
out a clause whose number is missing (NaN) and says "none" for an empty count, so that no
sentence reads "nan", "(, ...)" or "p >= nan" (tests/test_report_sentences.py feeds each one
empty, single and NaN inputs). The first sentences answer the practical question against the
reference (LM); then what the design allows (all at the floor, the seed drawing the instance,
unrelated groups); then across instances, each setting, interactions and each instance."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from zrp_ga.report import stats
from zrp_ga.report.common import ALPHA
from zrp_ga.report.labels import describe

FLIP = {stats.BETTER: stats.WORSE, stats.WORSE: stats.BETTER}


def p_text(p: float) -> str:
    """A p-value as a reader wants it: two significant digits, ``p < 1e-10`` below that.

    >>> p_text(0.0123), p_text(1e-14), p_text(0.5), p_text(float("nan"))
    ('p = 0.012', 'p < 1e-10', 'p = 0.5', 'p not computed')
    """
    if not math.isfinite(p):
        return "p not computed"
    return "p < 1e-10" if p < 1e-10 else f"p = {p:.2g}"


def count(n: int, word: str, plural: str | None = None) -> str:
    """``n word(s)``, "none" for 0 in the plural: ``count(0, "run")`` is "no runs".

    >>> count(0, "run"), count(1, "run"), count(3, "seed")
    ('no runs', '1 run', '3 seeds')
    """
    many = plural or f"{word}s"
    return f"no {many}" if n == 0 else f"{n} {word if n == 1 else many}"


def num(x: float, fmt: str = ".3g") -> str:
    """A number, or "n/a" when it is missing."""
    return format(x, fmt) if isinstance(x, (int, float, np.number)) and math.isfinite(x) else "n/a"


def paren(*parts: str) -> str:
    """`` (a; b)`` of the parts that say something, "" when none does.

    >>> paren("Friedman", "", "p = 0.01"), paren("", "")
    (' (Friedman; p = 0.01)', '')
    """
    said = [p for p in parts if p]
    return f" ({'; '.join(said)})" if said else ""


def pct(x: float) -> str:
    """A fraction as a percentage: 0.01 -> 1%."""
    return f"{x * 100:.3g}%" if math.isfinite(x) else "n/a"


def oriented(row: pd.Series, me: str) -> tuple[str, str, float, float, float]:
    """A pair's other side, verdict and effect with its interval, seen from ``me`` (a or b)."""
    e, lo, hi, v = float(row["effect"]), float(row["effect_lo"]), float(row["effect_hi"]), str(row["verdict"])
    if row["a"] == me:
        return str(row["b"]), v, e, lo, hi
    return str(row["a"]), FLIP.get(v, v), 1 - e, 1 - hi, 1 - lo


def effect_text(row: pd.Series, me: str) -> str:
    """``P(me ends lower than other) = e [95% CI lo, hi]``, oriented from ``me``'s side."""
    other, _, e, lo, hi = oriented(row, me)
    what = "in the same block" if row["design"] == stats.PAIRED else "for a random pair of runs"
    ci = f" [95% CI {lo:.2f}, {hi:.2f}]" if math.isfinite(lo) and math.isfinite(hi) else ""
    return f"P({me} ends lower than {other}, {what}) = {num(e, '.2f')}{ci}"


# --- the first sentences -----------------------------------------------------------------------------
def reference_sentence(a: dict | None) -> list[str]:
    """The practical answer against LM (:func:`zrp_ga.report.reference.answer`): cost, validation
    error, evaluations and how often, of the best configuration; then of every run."""
    if not a or not a.get("runs"):
        return []
    on = f" on the same {count(a['instances'], 'instance')}" if a.get("instances", 0) > 1 else ""
    if a.get("round_off"):
        cost = f"reaches LM's round-off floor in {a['within']} of its {count(a['runs'], 'run')}"
    else:
        spread = (f"; {num(a['ratio_lo'])} to {num(a['ratio_hi'])} x by instance"
                  if a.get("instances", 0) > 1 and a["ratio_lo"] != a["ratio_hi"] else "")  # fmt: skip
        cost = f"ends at {num(a['ratio'])} x LM's cost (median of its {count(a['runs'], 'run')}{spread})"
    val = ""
    if math.isfinite(a.get("val", math.nan)):
        val = f"; it validates at {num(a['val'])} mm RMS" + (f" against LM's {num(a['lm_val'])} mm" if math.isfinite(a.get("lm_val", math.nan)) else "")
    lm_evals = f"LM's {num(a['lm_evals'], ',.0f')}" if math.isfinite(a.get("lm_evals", math.nan)) else "LM's (not recorded)"
    if a.get("round_off"):
        often = ""
    elif a["within"] == 0:
        often = (f"; none of its runs comes within {pct(a['tol'])} of LM's cost in its {num(a['nevals'], ',.0f')} evaluations, "
                 f"where LM takes {num(a['lm_evals'], ',.0f')} (median over the instances)" if math.isfinite(a.get("lm_evals", math.nan))
                 else f"; none of its runs comes within {pct(a['tol'])} of LM's cost")  # fmt: skip
    else:
        often = (f"; {a['within']} of its {count(a['runs'], 'run')} {'comes' if a['within'] == 1 else 'come'} within {pct(a['tol'])} of LM's cost, in a median of "
                 f"{num(a['evals'], ',.0f')} evaluations against {lm_evals}")  # fmt: skip
    verdict = {stats.WORSE: "worse than LM", stats.BETTER: "better than LM", stats.EQUIVALENT: "equivalent to LM",
               stats.UNDECIDED: "undecided against LM"}.get(a.get("verdict", ""), "")  # fmt: skip
    tail = f" Verdict: {verdict}{paren(*_decided_by(a))}." if verdict else ""
    first = f"Against Levenberg-Marquardt, the reference{on}: the best configuration, {a['best']}, {cost}{val}{often}.{tail}"
    rest = a["all_runs"] - a["runs"]
    if rest <= 0 or a.get("round_off"):
        return [first]
    return [first, f"Of the {count(a['all_runs'], 'run')} of every configuration but the references, {a['all_within_11'] or 'none'} "
                   f"{'comes' if a['all_within_11'] == 1 else 'come'} within 1.1 x LM's cost (the closest: {num(a['closest'])} x)."]  # fmt: skip


def _decided_by(a: dict) -> tuple[str, ...]:
    """The test that gave a verdict, and its p: every run within the tolerance, the difference
    test (better, worse), TOST (equivalent), or both (undecided)."""
    tost = f"TOST at +-{pct(a.get('tol', math.nan))}, {p_text(a.get('p_equivalence', math.nan))}"
    if a.get("tied"):
        return (stats.ALL_TIED,)
    if a.get("verdict") == stats.EQUIVALENT:
        return (tost,)
    test = f"{a['test']}, {p_text(a.get('p', math.nan))}" if a.get("test") else ""
    return (test, tost) if a.get("verdict") == stats.UNDECIDED else (test,)


def tied_sentence(tied: list[str], n_instances: int, at_floor: bool, tol: float) -> list[str]:
    """Where every run ends within the tolerance of every other: final costs are one result and
    the comparison moves to evaluations."""
    if not tied or n_instances == 0:
        return []
    where = "the floor" if at_floor else "the same cost"
    if len(tied) == n_instances:
        scope = "on every instance" if n_instances > 1 else "on its instance"
        return [f"All configurations reach {where} {scope}: every run's final cost is within the tolerance ({pct(tol)} of f_ref) "
                "of every other's, so their final costs are equivalent; they differ in the evaluations to reach it, which the "
                "comparisons below use."]  # fmt: skip
    return [f"On {len(tied)} of the {n_instances} instances ({', '.join(tied)}) every run ends within the tolerance ({pct(tol)} of "
            "f_ref) of every other: there the configurations are equivalent on final cost and compared on the evaluations to reach it."]


def no_reference_sentence(instances: list[str]) -> list[str]:
    """Instances whose floor is the best run itself: no sentence may read 1 x f* as an achievement."""
    if not instances:
        return []
    which = f"on {count(len(instances), 'instance')} ({', '.join(instances[:6])}{', ...' if len(instances) > 6 else ''})"
    return [f"No reference {which}: no run recorded Levenberg-Marquardt's floor, so f* is the lowest final cost of the report's "
            "runs and the best run is at 1 x f* by definition. For a reference, add runs with algorithm=lm or sweep with "
            "objective=over_floor."]  # fmt: skip


def seed_instance_sentence(n_seeds: int) -> list[str]:
    """The seed drew each run's instance: say so, and how to hold the instance."""
    if n_seeds < 2:
        return []
    return [f"Each of the {n_seeds} seeds drew its own problem instance (a simulated problem takes the run's seed when problem.seed "
            "is not set), so no configuration ran twice on one instance: the configurations are compared across the instances, "
            "each instance a block. To repeat runs on one instance, set problem.seed=N (or choose one with instance=NAME)."]  # fmt: skip


def groups_sentence(sizes: list[tuple[int, int]]) -> list[str]:
    """Several groups that never shared an instance: (configurations, instances) per group."""
    if len(sizes) < 2:
        return []
    parts = "; ".join(f"group {g}: {count(c, 'configuration')} on {count(i, 'instance')}" for g, (c, i) in enumerate(sizes, start=1))
    return [f"The runs form {len(sizes)} unrelated groups that never shared an instance ({parts}): nothing is compared across groups."]


# --- across instances, settings, interactions, within ------------------------------------------------
def across_sentence(f: dict | None, note: str, group: str = "") -> list[str]:
    """Friedman's test across instances in words (``group``: "In group 2, " when there are several)."""
    if f is None:
        return [f"{group}Ranks across instances: not computed ({note.strip() or 'no comparison'})."] if note else []
    ranks = f["mean_ranks"]
    if not len(ranks):
        return []
    best, lead = str(ranks.index[0]), f"{group}Across the {count(f['instances'], 'instance')}"
    if f["test"] == "sign test":
        verdict = "differ" if f["p"] < ALPHA else "do not differ significantly"
        return [f"{lead} the two configurations {verdict} (sign test on the instances' medians, {p_text(f['p'])}); {best} ranks "
                f"first on average ({num(ranks.iloc[0], '.2f')})."]  # fmt: skip
    if not f["p"] < ALPHA:
        return [f"{lead} the ranks of the {f['configurations']} configurations do not differ significantly (Friedman, chi2 = "
                f"{num(f['statistic'])}, {p_text(f['p'])}): the data support no ranking."]  # fmt: skip
    within_cd = int((ranks <= ranks.iloc[0] + f["cd"]).sum()) - 1
    return [f"{lead} the ranks differ (Friedman, chi2 = {num(f['statistic'])}, {p_text(f['p'])}). Best mean rank: {best} "
            f"({num(ranks.iloc[0], '.2f')} of {f['configurations']}); {count(within_cd, 'other configuration')} "
            f"{'lies' if within_cd == 1 else 'lie'} within Nemenyi's "
            f"critical difference ({num(f['cd'], '.2f')}) of it, which the test cannot tell apart from it."]  # fmt: skip


def setting_sentence(name: str, tested: int, differ: int, test: str, p_max: float, p_min: float, top: str, top_count: int,
                     pooled: str) -> str:  # fmt: skip
    """One setting over the others: on how many of its ``tested`` instances it matters
    (``differ``), with the test and p-values, which value is best where it does, and ``pooled``
    (the clause across instances, may be empty)."""
    name = name[:1].upper() + name[1:] if name else "The setting"
    where = f" on {differ} of {tested} instances" if tested > 1 else (" on its instance" if differ else "")
    if differ:
        best = f"; best: {top}" + (f" on {top_count} of them" if tested > 1 and top else "") if top else ""
        s = f"{name} matters{where}{paren(test, p_text(p_max).replace('=', '<=') if math.isfinite(p_max) else '')}{best}"
    else:
        any_ = f" on any of the {tested} instances" if tested > 1 else ""
        s = f"{name} makes no significant difference{any_}{paren(test, p_text(p_min).replace('=', '>=') if math.isfinite(p_min) else '')}"
    return s + (f". {pooled}" if pooled else "") + "."


def within_sentence(instance: str, setup: str, omnibus: str, best: str, best_value: str, counts: dict[str, int], test: str,
                    closest: str, limited: str) -> str:  # fmt: skip
    """One instance: the design, the omnibus test, the best configuration, its verdicts against
    every other (``counts``: better, equivalent, worse, undecided), the closest it beats, and
    why the design limits what can be said."""
    head = f"On {instance} ({setup}): {omnibus + ' ' if omnibus else ''}Lowest median: {best}{best_value}."
    others = sum(counts.values())
    if others:
        said = [f"better than {counts[stats.BETTER]}" if counts.get(stats.BETTER) else "",
                f"equivalent to {counts[stats.EQUIVALENT]}" if counts.get(stats.EQUIVALENT) else "",
                f"worse than {counts[stats.WORSE]}" if counts.get(stats.WORSE) else "",
                f"undecided against {counts[stats.UNDECIDED]}" if counts.get(stats.UNDECIDED) else ""]  # fmt: skip
        head += f" Against the {count(others, 'other')}: {', '.join(x for x in said if x)} ({test})."
    if closest:
        head += f" {closest}."
    return head + (f" {limited}" if limited else "")


def within(t: dict) -> list[str]:
    """One sentence per instance with two or more configurations (:func:`within_sentence`)."""
    w = t["within"]
    out = []
    n_inst = int(w.loc[(w["a"] == "all") & w["question"].astype(bool), "instance"].nunique()) if len(w) else 0
    ratio = t["runs"].groupby(["instance", "configuration"])["final_over_ref"].median()
    by_lm = t["floors"].set_index("instance")["by_lm"]
    for instance, g in w.groupby("instance", sort=False):
        g = g[g["question"].astype(bool)]
        pairs, omni = g[g["a"] != "all"], g[g["a"] == "all"]
        if not len(pairs):
            continue
        best, q = str(g["best"].iloc[0]), t["questions"][instance]
        design, n = str(pairs["design"].iloc[0]), int(pairs["n_a"].min())
        k = len(set(pairs["a"]) | set(pairs["b"]))
        unit = "seed" if design == stats.PAIRED else "run"
        setup = (f"{k} configurations paired by seed, {count(n, 'seed')} shared by all" if design == stats.PAIRED
                 else f"{k} configurations, runs not sharing seeds") + f"; compared on {q['metric']}"  # fmt: skip
        if not q["tied"]:
            setup += f", ties within {pct(float(t['floors'].set_index('instance').loc[instance, 'tolerance']))} of f_ref"
        omnibus = _omnibus_text(omni, n_inst)
        r = ratio.get((instance, best), math.nan)
        value = (f" ({num(r)} x f_ref)" if bool(by_lm.get(instance, False)) else f" ({num(r)} x f*, the best run's cost)") if not q["tied"] else ""
        mine = pairs[(pairs["a"] == best) | (pairs["b"] == best)]
        verdicts = [oriented(row, best)[1] for _, row in mine.iterrows()]
        counts = {v: verdicts.count(v) for v in (stats.BETTER, stats.EQUIVALENT, stats.WORSE, stats.UNDECIDED)}
        test = f"{_test_name(pairs)}, Holm over the {count(len(pairs), 'pair')}; TOST for equivalence"
        medians = t["runs"][t["runs"]["instance"] == instance].groupby("configuration")[q["column"]].median()
        out.append(within_sentence(instance, setup, omnibus, best, value, counts, test, _closest(mine, best, medians),
                                   _limited(t, design, n, len(pairs), counts, unit)))  # fmt: skip
    return out


def _test_name(rows: pd.DataFrame) -> str:
    """The test the rows ran (the rank test where some pairs were tied on their face)."""
    tests = rows.loc[rows["test"] != stats.ALL_TIED, "test"]
    return str(tests.mode().iloc[0]) if len(tests) else stats.ALL_TIED


def _omnibus_text(omni: pd.DataFrame, n_inst: int) -> str:
    if not len(omni):
        return ""
    o = omni.iloc[0]
    if o["verdict"] == stats.EQUIVALENT:
        return "every run ends within the tolerance of every other."
    corr = f" after Holm's correction over {n_inst} instances" if n_inst > 1 else ""
    verdict = "the configurations differ" if o["verdict"] == "differ" else "no significant difference between the configurations"
    stat = f"chi2 = {num(o['statistic'])}" if o["test"] == "Friedman" else f"H = {num(o['statistic'])}"
    return f"{verdict} ({o['test']}, {stat}, {p_text(o['p_holm'])}{corr})."


def _closest(mine: pd.DataFrame, best: str, medians: pd.Series) -> str:
    """The effect against the closest rival the best beats: the one with the lowest median."""
    beaten = [row for _, row in mine.iterrows() if oriented(row, best)[1] == stats.BETTER]
    if not beaten:
        return ""
    row = min(beaten, key=lambda r: (medians.get(oriented(r, best)[0], math.inf), -r["p_holm"]))
    return f"Against the closest it beats, {oriented(row, best)[0]}: {effect_text(row, best)}, {p_text(row['p_holm'])} after Holm"


def _limited(t: dict, design: str, n: int, m: int, counts: dict, unit: str) -> str:
    """Why the design cannot separate configurations: the smallest p-value a pairwise test can
    give with ``n`` blocks or runs (not when the seed drew the instance: then n is 1)."""
    floor_p = stats.smallest_p(design, n) if n > 0 else 1.0
    if counts.get(stats.BETTER) or counts.get(stats.WORSE) or not (floor_p >= ALPHA or floor_p * m >= ALPHA):
        return ""
    return (f"With {count(n, unit)} the smallest p-value a pairwise test can give is {num(floor_p, '.2g')} (before correcting for "
            f"{count(m, 'pair')}): more seeds are needed to separate configurations.")  # fmt: skip


def factors(t: dict) -> list[str]:
    """One sentence per setting (:func:`setting_sentence`)."""
    f = t["factors"]
    out = []
    for key, g in f.groupby("setting", sort=False):
        per = g[(g["instance"] != "all") & (g["a"] == "all")]
        if not len(per):  # two values: the one pair per instance
            per = g[(g["instance"] != "all") & (g["a"] != "all")]
        sig = per[per["verdict"].isin(["differ", stats.BETTER, stats.WORSE])]
        name = setting_name(key)
        design = str(g["design"].iloc[0]) if len(g) else ""
        blocks = "paired by the other settings and the seed" if design == stats.PAIRED else "independent runs"
        test = f"{_test_name(per) if len(per) else 'no test'}, {blocks}" + (", Holm over the instances" if len(per) > 1 else "")
        best_by = sig.groupby("best").size().sort_values(ascending=False) if len(sig) else pd.Series(dtype=int)
        top = str(best_by.index[0]) if len(best_by) else ""
        if len(per) and (per["verdict"] == stats.EQUIVALENT).all():
            where = f" on every one of the {len(per)} instances" if len(per) > 1 else ""
            out.append(f"{name[:1].upper() + name[1:]} makes no difference{where}: its values are equivalent, every run within the "
                       "tolerance of the runs it is compared with.")  # fmt: skip
            continue
        out.append(setting_sentence(name, len(per), len(sig), test, float(sig["p_holm"].max()) if len(sig) else math.nan,
                                    float(per["p_holm"].min()) if len(per) else math.nan, top,
                                    int(best_by.iloc[0]) if len(best_by) else 0, _pooled(g, t)))  # fmt: skip
    return out


def _pooled(g: pd.DataFrame, t: dict) -> str:
    """A setting across instances: the values' medians and the best against its closest rival."""
    pooled = g[(g["instance"] == "all") & (g["a"] != "all")]
    if not len(pooled) or t["floors"]["instance"].nunique() < 2:
        return ""
    best = str(pooled["best"].iloc[0])
    med = t["factor_medians"]
    m = med[(med["setting"] == g["setting"].iloc[0]) & (med["instance"] == "all")]
    meds = ", ".join(f"{v} {num(x)}" for v, x in m.set_index("value")["median_final_over_ref"].sort_values().items())
    mine = pooled[(pooled["a"] == best) | (pooled["b"] == best)]
    row = mine.loc[mine["p"].idxmax()]
    other, verdict, *_ = oriented(row, best)
    relation = {stats.BETTER: "better than", stats.WORSE: "worse than", stats.EQUIVALENT: "equivalent to"}.get(verdict, "undecided against")
    return (f"Across instances (final / f_ref, median: {meds}): {best} is {relation} {other}, {effect_text(row, best)}, "
            f"{p_text(row['p_holm'])}")  # fmt: skip


def setting_name(key: str) -> str:
    """A setting in words: ``refine`` -> "the pseudo-inverse step", ``population.mu`` -> "mu"."""
    return {"refine": "the pseudo-inverse step", "algorithm": "the algorithm"}.get(key, describe(key, "\0").replace("\0", "").strip())


def interactions(t: dict) -> list[str]:
    """The pairs of settings whose interaction the aligned rank transform finds."""
    ix = t["interactions"]
    out = []
    for (a, b), g in ix.groupby(["setting_a", "setting_b"], sort=False):
        found = g[g["found"]]
        if len(found):
            na, nb = setting_name(a), setting_name(b)
            out.append(f"{na[:1].upper() + na[1:]} and {nb} interact on {len(found)} of {count(len(g), 'instance')} "
                       f"({', '.join(found['instance'])}; aligned rank transform, Holm over {count(len(ix), 'test')}; "
                       f"{p_text(float(found['p_holm'].max())).replace('=', '<=')}): the effect of {na} depends on {nb} there "
                       "(the interaction figure).")  # fmt: skip
    return out


def _without_reference(t: dict) -> list[str]:
    """Instances whose f* is the best run itself: no floor record, no LM run, not round-off."""
    f, ref = t["floors"], t.get("reference")
    with_lm = set(ref.loc[ref["reference"] == "Levenberg-Marquardt", "instance"]) if ref is not None and len(ref) else set()
    return [i for i, by_lm, off in zip(f["instance"], f["by_lm"], f["round_off"]) if not by_lm and not off and i not in with_lm]


def sentences(t: dict) -> dict[str, list[str]]:
    """The conclusions by heading, the practical answer first."""
    floors, asked = t["floors"], t["questions"]
    tied = [i for i, q in asked.items() if q["tied"]]
    sizes = [(int(g["configuration"].nunique()), int(g["instance"].nunique())) for _, g in t["runs"].groupby("group", sort=True)]
    seeds = int(t["runs"]["seed"].nunique()) if t.get("seed_drew_instance") else 0
    tol = floors.loc[floors["instance"].isin(tied), "tolerance"]  # the tied instances' own (the round-off floor's may be larger)
    first = (reference_sentence(t.get("answer")) + tied_sentence(tied, len(asked), all(asked[i]["at_floor"] for i in tied),
             float(tol.max()) if len(tol) else math.nan)
             + no_reference_sentence(_without_reference(t))
             + seed_instance_sentence(seeds)
             + groups_sentence(sizes))  # fmt: skip
    groups = [f for f in t.get("friedman_groups", []) if f["result"] is not None or len(sizes) == 1]
    across = []
    for f in groups:
        if len(floors) > 1:
            across += across_sentence(f["result"], f["note"], f"In group {f['group']}, " if len(sizes) > 1 else "")
    return {"In short": first, "Across instances": across, "Each setting over the others": factors(t),
            "Interactions": interactions(t), "Within each instance": within(t)}


def _record(kind: str, row: dict | pd.Series, **scope) -> dict:
    """One pairwise conclusion for conclusions.json."""
    return dict(
        scope=dict(kind=kind, **scope, a=str(row["a"]), b=str(row["b"])), question=str(row.get("metric", "")),
        design=str(row["design"]), test=str(row["test"]), statistic=_json(row["statistic"]), p=_json(row["p"]),
        p_holm=_json(row["p_holm"]),
        effect=dict(name="P(a ends lower than b)" + (" in the same block" if row["design"] == stats.PAIRED else ", a random pair of runs"),
                    value=_json(row["effect"]), ci95=[_json(row["effect_lo"]), _json(row["effect_hi"])]),
        equivalence=dict(test="TOST (two one-sided rank tests at +-tolerance)", p=_json(row["p_equivalence"]),
                         p_holm=_json(row["p_equivalence_holm"])),
        verdict=str(row["verdict"]),
    )  # fmt: skip


def _json(x) -> float | None:
    """A number for JSON: NaN and infinities as null."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def records(t: dict) -> dict:
    """Every conclusion of the report for scripts (``conclusions.json``): ``conclusions``, one per
    compared pair, with its scope (within an instance, a setting on an instance or across all,
    validation error, across instances, against the reference), the question, the test, its
    statistic, p and p corrected (Holm), the effect with its 95% interval, the equivalence test
    and the verdict (better, worse, equivalent or undecided, from a's side); ``tests``: the
    omnibus tests (verdict differ, equivalent or undecided); ``tolerance`` (the setting, relative
    to f_ref) and ``tolerance_by_instance`` (the one each instance's tests used, relative to its
    f_ref: never below the round-off floor) and ``alpha``."""
    out, tests = [], []
    for kind, df, where in (("within instance", t["within"], ("instance",)), ("setting", t["factors"], ("setting", "instance")),
                            ("validation error", t["statistics"], ("instance",))):  # fmt: skip
        for row in df.to_dict("records"):  # rows as dicts: pandas' Series per row took seconds for a suite
            scope = {k: str(row[k]) for k in where}
            if row["a"] == "all":
                tests.append(dict(scope=dict(kind=kind, **scope), question=str(row["metric"]), test=str(row["test"]),
                                  statistic=_json(row["statistic"]), p=_json(row["p"]), p_holm=_json(row["p_holm"]),
                                  verdict=str(row["verdict"])))  # fmt: skip
            else:
                out.append(_record(kind, row, **scope))
    for f in t.get("friedman_groups", []):
        out += _nemenyi(f)
    a = t.get("answer")
    if a:
        out.append(dict(scope=dict(kind="against the reference", a=a["best"], b="Levenberg-Marquardt", instances=a["instances"]),
                        question="final cost / LM's cost", design="one sample", test=a["test"], statistic=_json(a["ratio"]),
                        p=_json(a["p"]), p_holm=_json(a["p"]),
                        effect=dict(name="median final cost / LM's cost", value=_json(a["ratio"]),
                                    ci95=[_json(a["ratio_lo"]), _json(a["ratio_hi"])]),
                        equivalence=dict(test="TOST at +-tolerance", p=_json(a["p_equivalence"]), p_holm=_json(a["p_equivalence"])),
                        verdict=a["verdict"]))  # fmt: skip
    floors = t["floors"]
    by_instance = {str(i): _json(float(f"{x:.12g}")) for i, x in zip(floors["instance"], floors["tolerance"])} if len(floors) else {}
    return dict(alpha=ALPHA, tolerance=_json(float(f"{t['rule'].resolution():.12g}")), tolerance_by_instance=by_instance,
                conclusions=out, tests=tests)  # fmt: skip


def _nemenyi(f: dict) -> list[dict]:
    """Across instances: each pair's Nemenyi p, better or worse below alpha, else undecided."""
    r = f["result"]
    if r is None or not len(r["pairs"]):
        return []
    out = []
    for row in r["pairs"].itertuples(index=False):
        side = stats.BETTER if row.rank_a < row.rank_b else stats.WORSE
        out.append(dict(scope=dict(kind="across instances", group=f["group"], a=str(row.a), b=str(row.b)),
                        question="mean rank over the instances", design="instances as blocks", test=f"{r['test']}, Nemenyi",
                        statistic=_json(row.rank_a - row.rank_b), p=_json(row.p_nemenyi), p_holm=_json(row.p_nemenyi),
                        effect=dict(name="mean rank of a - mean rank of b", value=_json(row.rank_a - row.rank_b), ci95=[None, None]),
                        equivalence=dict(test="", p=None, p_holm=None),
                        verdict=side if row.p_nemenyi < ALPHA and r["p"] < ALPHA else stats.UNDECIDED))  # fmt: skip
    return out
