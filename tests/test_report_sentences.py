"""The report's sentences against independent answers: studies made up so that the best
configuration, whom it beats and the effect from its side are known by construction (and the
p-values from scipy), a sweep whose runs all end at the floor, a folder of unrelated runs, and
every sentence template fed empty, single and NaN inputs."""

import copy
import json
import math
import re

import numpy as np
import pandas as pd
import pytest
from report_fakes import ALGORITHMS, fake_run
from scipy import stats as sps

from zrp_ga import report
from zrp_ga.report import conclusions, drawing, stats

BROKEN = re.compile(r"\bnan\b|\(,|\(\)|\(\s*;|;\s*\)|p >= nan|  |\s\.|\.\.(?!\.)|\binf\b", re.IGNORECASE)


def _ga(cx, mut="polynomial"):
    cfg = copy.deepcopy(ALGORITHMS["ga"])
    cfg["crossover"]["op"]["_target_"] = f"zrp_ga.operators.crossover.{cx}"
    cfg["mutation"] = {"op": {"_target_": f"zrp_ga.operators.mutation.{mut}"}}
    return cfg


def _run(root, name, instance, cx, seed, final, floor=1.0, evals=100, mut="polynomial", **kw):
    """A GA run whose best cost falls from 10 x its final to its final at ``evals`` evaluations."""
    rows = [(10, 10.0 * final), (evals // 2, 3.0 * final), (evals, final)]
    return fake_run(root / name, instance, "ga", rows, floor=floor, seed=seed, config=_ga(cx, mut), nominal=100.0,
                    choices={"algorithm": "ga", "crossover": cx, "mutation": mut}, **kw)  # fmt: skip


def _all_sentences(t):
    return [s for lines in conclusions.sentences(t).values() for s in lines]


@pytest.fixture(scope="module")
def known(tmp_path_factory):
    """Instance I1, paired by ten seeds: four crossovers ordered on every seed, blend < sbx <
    one point < two point, each 10% of the floor apart (written worst first, so that the best
    is the second of every pair). Instance I2, independent runs: uniform reset's median is the
    lower, but 11 x 11 of its 21 x 21 pairs with Gaussian end lower (A12 = 0.27): the
    configuration with the lowest median loses to the other."""
    root = tmp_path_factory.mktemp("known")
    order = ["two_point", "one_point", "sbx", "blend"]
    for seed in range(10):
        scale = 1.5 + 0.3 * seed  # seeds of different difficulty: only pairing sees the order
        for k, cx in enumerate(order):
            _run(root, f"I1-{k}-{cx}-{seed}", "I1", cx, seed, final=scale + 0.1 * (len(order) - 1 - k))
    x = [2.0] * 11 + [100.0] * 10  # median 2
    y = [1.5] * 10 + [3.0] * 11  # median 3: P(x < y) = 11 x 11 / 441
    for i, v in enumerate(x):
        _run(root, f"I2-x-{i}", "I2", "blend", 100 + i, v, mut="uniform_reset")
    for i, v in enumerate(y):
        _run(root, f"I2-y-{i}", "I2", "blend", 200 + i, v, mut="gaussian")
    runs, left = report.find_runs([root])
    assert not left
    return report.build_tables(runs), np.array(x), np.array(y)


def _within(t, instance):
    return next(s for s in conclusions.within(t) if s.startswith(f"On {instance} "))


def test_the_best_is_the_lowest_and_beats_the_three_others_with_its_effect(known):
    t, _, _ = known
    said = _within(t, "I1")
    assert "Lowest median: blend, polynomial mutation" in said.replace("blend crossover", "blend")
    assert "better than 3" in said and "worse than" not in said and "undecided" not in said
    # the closest it beats is sbx (0.1 apart on every seed): every block goes to blend, P = 1, and the exact
    # Wilcoxon p of ten differences of one sign, 2 / 2^10, Holm over the 6 pairs of the instance: x6 at most
    p = sps.wilcoxon(np.full(10, 0.1)).pvalue
    assert p == pytest.approx(2 / 2**10)
    m = re.search(r"Against the closest it beats, (.+?): P\((.+?) ends lower than (.+?), in the same block\) = ([0-9.]+) "
                  r"\[95% CI ([0-9.]+), ([0-9.]+)\], p = ([0-9.e-]+) after Holm", said)  # fmt: skip
    assert m, said
    assert m.group(1).startswith("sbx crossover") and m.group(2).startswith("blend crossover")
    assert float(m.group(4)) == 1.0 and (float(m.group(5)), float(m.group(6))) == (1.0, 1.0)
    assert float(m.group(7)) == pytest.approx(min(1.0, 6 * p), rel=0.05)


def test_the_lowest_median_can_lose_and_is_then_not_counted_as_winning(known):
    t, x, y = known
    said = _within(t, "I2")
    assert "Lowest median: blend crossover, uniform reset mutation" in said
    u = sps.mannwhitneyu(x, y, alternative="two-sided")
    a12 = np.mean(x[:, None] < y[None, :]) + 0.5 * np.mean(x[:, None] == y[None, :])
    assert a12 == pytest.approx(121 / 441) and u.pvalue < 0.05  # the other ends lower, significantly
    assert "worse than 1" in said and "better than" not in said
    pair = t["within"][(t["within"]["instance"] == "I2") & (t["within"]["a"] != "all")].iloc[0]
    assert pair["p"] == pytest.approx(u.pvalue)
    other, verdict, effect, lo, hi = conclusions.oriented(pair, "blend crossover, uniform reset mutation")
    assert verdict == stats.WORSE and effect == pytest.approx(a12) and lo <= effect <= hi


def test_conclusions_json_says_the_same_from_each_side(known, tmp_path):
    t, _, _ = known
    recs = conclusions.records(t)["conclusions"]
    i1 = [c for c in recs if c["scope"]["kind"] == "within instance" and c["scope"]["instance"] == "I1"]
    assert len(i1) == 6  # every pair once
    assert t["runs"].loc[t["runs"]["instance"] == "I1", "configuration"].iloc[0].startswith("two point")
    for c in i1:  # crossovers read worst first: a is the worse of every pair
        assert c["verdict"] == "worse" and c["effect"]["value"] == 0.0, c
    assert all(not BROKEN.search(s) for s in _all_sentences(t))


@pytest.fixture(scope="module")
def at_the_floor(tmp_path_factory):
    """Two crossovers, six shared seeds, every run ending at the floor to 1e-14 relative (the
    pseudo-inverse step's round-off): blend reaches it in 50 evaluations, sbx in 200."""
    root = tmp_path_factory.mktemp("floor")
    for seed in range(6):
        for cx, evals in (("sbx", 200), ("blend", 50)):
            final = 0.25 * (1 + 1e-14 * (seed - 2.5))
            _run(root / "runs", f"{cx}-{seed}", "puma", cx, seed, final=final, floor=0.25, evals=evals)
    t = report.write_report([root / "runs"], root / "out", formats=("png",))
    return t, root / "out"


def test_runs_all_at_the_floor_are_equivalent_and_compared_on_evaluations(at_the_floor):
    t, out = at_the_floor
    first = " ".join(conclusions.sentences(t)["In short"])
    assert "All configurations reach the floor on its instance" in first and "equivalent" in first
    said = _within(t, "puma")
    assert "compared on evaluations to reach the floor" in said
    # evaluations, paired by seed: blend 50 against sbx 200 on six of six seeds: exact p = 2 / 2^6
    assert "Lowest median: blend crossover" in said and "better than 1" in said
    pair = t["within"][(t["within"]["a"] != "all") & t["within"]["question"]].iloc[0]
    assert pair["p"] == pytest.approx(sps.wilcoxon(np.full(6, 150.0)).pvalue) == pytest.approx(2 / 64)
    recs = json.loads((out / "conclusions.json").read_text())["conclusions"]
    final = [c for c in recs if c["scope"]["kind"] == "within instance" and c["question"].startswith("final cost")]
    evals = [c for c in recs if c["scope"]["kind"] == "within instance" and c["question"].startswith("evaluations")]
    assert [c["verdict"] for c in final] == ["equivalent"] and final[0]["test"] == stats.ALL_TIED
    side = {c["scope"]["a"]: c["verdict"] for c in evals}
    assert side.get("sbx crossover") == "worse" or side.get("blend crossover") == "better"
    page = (out / "index.html").read_text()
    assert "All configurations reach the floor" in page and "Evaluations to reach the floor" in page
    assert not any(BROKEN.search(s) for s in _all_sentences(t))


def test_unrelated_runs_are_grouped_and_never_compared_across(tmp_path):
    """GA runs on one instance, LM on another, CMA-ES on a third: three groups, no pair across them."""
    for seed in range(3):
        _run(tmp_path / "runs", f"ga-{seed}", "A", "blend", seed, final=1.2 + 0.1 * seed)
    fake_run(tmp_path / "runs" / "lm", "B", "lm", [(1, 9.0), (5, 5.0)])
    for seed in range(2):
        fake_run(tmp_path / "runs" / f"cma-{seed}", "C", "cmaes", [(10, 7.0), (20, 3.0 + seed)], seed=seed, validation=None)
    t = report.write_report([tmp_path / "runs"], tmp_path / "out", formats=("png",))
    said = _all_sentences(t)
    assert any("3 unrelated groups that never shared an instance" in s for s in said)
    assert not any(BROKEN.search(s) for s in said), [s for s in said if BROKEN.search(s)]
    assert not any(s.startswith("Across") for s in said)
    on = t["runs"].groupby("configuration")["instance"].agg(set)
    recs = json.loads((tmp_path / "out" / "conclusions.json").read_text())["conclusions"]
    for c in recs:
        a, b = c["scope"]["a"], c["scope"]["b"]
        if a in on and b in on:
            assert on[a] & on[b], c  # compared only where both ran
    assert len(t["within"]) == 0 and t["friedman"] is None


def test_unrelated_runs_of_two_varied_settings_are_not_pooled_across_instances(tmp_path):
    """One run each, every run on its own instance: a GA with the pseudo-inverse step on P, a GA
    without on Q, LM on R, CMA-ES on S (two settings vary, algorithm and refine). No value of a
    setting shares an instance with another, so no setting is compared (neither pooled across the
    instances nor "makes no significant difference" from no test); and one run per instance ties
    with nothing, so no sentence says that all configurations reach the floor."""
    def ga(refine):
        cfg = {**_ga("blend"), "refine": {"op": {"_target_": "zrp_ga.operators.refine.pinv"} if refine == "pinv" else None,
                                         "share": 0.1 if refine == "pinv" else 0.0}}  # fmt: skip
        return dict(config=cfg, choices={"algorithm": "ga", "refine": refine})

    fake_run(tmp_path / "runs" / "ga-pinv", "P", "ga", [(10, 5.0), (200, 1e-18)], nominal=0.05, **ga("pinv"))
    fake_run(tmp_path / "runs" / "ga-none", "Q", "ga", [(10, 5.0), (200, 0.07)], **ga("none"))
    fake_run(tmp_path / "runs" / "lm", "R", "lm", [(1, 9.0), (11, 0.002)], choices={"algorithm": "lm"})
    fake_run(tmp_path / "runs" / "cma", "S", "cmaes", [(10, 7.0), (220, 0.09)], choices={"algorithm": "cmaes"})
    runs = report.find_runs([tmp_path / "runs"])[0]
    t = report.build_tables(runs)
    assert t["runs"]["configuration"].nunique() == 4 and t["runs"]["instance"].nunique() == 4
    said = conclusions.sentences(t)
    assert any("4 unrelated groups that never shared an instance" in s for s in said["In short"]), said
    assert not any("reach the floor" in s or "reach the same cost" in s for s in said["In short"]), said["In short"]
    assert not any(q["tied"] for q in t["questions"].values())  # no "Evaluations to reach the floor" figure either
    assert said["Each setting over the others"] == [], said["Each setting over the others"]
    assert not any(BROKEN.search(s) for lines in said.values() for s in lines)
    recs = conclusions.records(t)["conclusions"]
    assert not [c for c in recs if c["scope"].get("instance") == "all"], recs
    assert len(t["factor_medians"]) == 0  # nor a main-effects figure setting one instance's value beside another's
    assert len(t["interactions"]) == 0  # nor an interaction test on an instance where a setting has one value
    with pytest.MonkeyPatch.context() as mp:  # the figures' descriptions, without drawing them: no lowest and highest across groups
        mp.setattr(drawing, "_each", lambda work, specs, meanwhile=None: ["" for _ in specs])
        figs, _ = drawing.draw(runs, t, tmp_path, ("png",), t["rule"])
    described = [f for f in figs if f["name"] != "fig2_convergence"]  # (Fig. 2 draws one instance)
    assert {f["name"] for f in described} >= {"convergence_by_configuration", "ecdf_evals_to_target", "validation_error_boxplot"}
    for f in described:
        assert not re.search(r"lowest|highest|reaches", f["alt"]), f["alt"]
        assert "4 groups that never shared an instance" in f["alt"], f["alt"]
    assert list(t["summary"]["group"]) == sorted(t["summary"]["group"])



def test_conclusions_json_gives_the_tolerance_each_instance_used(tmp_path):
    """Runs at the round-off floor (final 1e-18 on a nominal cost of 0.05): f_ref = 1e-9 x 0.05
    and the tolerance is never below it, so each test there tied costs within 1 x f_ref, not
    the 1% the setting says; the page says 100% of f_ref and conclusions.json must agree."""
    for seed in range(2):
        for cx in ("blend", "sbx"):
            _run(tmp_path / "runs", f"{cx}-{seed}", "P", cx, seed, final=1e-18 * (1 + seed), floor=None)
            _run(tmp_path / "runs", f"Q-{cx}-{seed}", "Q", cx, seed, final=2.0 + 0.5 * seed)
    for path in (tmp_path / "runs").glob("*/summary.json"):  # nominal 0.05 on P: round-off floor 5e-11
        if path.parent.name[0] != "Q":
            path.write_text(path.read_text().replace('"nominal_cost": 100.0', '"nominal_cost": 0.05'))
    t = report.build_tables(report.find_runs([tmp_path / "runs"])[0])
    found = conclusions.records(t)
    assert found["tolerance"] == 0.01  # the setting: the tightest level 1.01 - 1, without its round-off
    assert found["tolerance_by_instance"] == {"P": 1.0, "Q": 0.01}
    assert json.loads(json.dumps(found))["tolerance_by_instance"]["P"] == 1.0
    first = conclusions.sentences(t)["In short"]  # P's runs tie within its tolerance, Q's do not: the sentence gives P's
    assert any(s.startswith("On 1 of the 2 instances (P) every run ends within the tolerance (100% of f_ref)") for s in first), first

# --- every template with empty, single and NaN inputs ------------------------------------------------
NAN = math.nan
ANSWER = dict(best="blend", instances=1, runs=1, ratio=NAN, ratio_lo=NAN, ratio_hi=NAN, val=NAN, lm_val=NAN, tol=0.01, within=0,
              evals=NAN, nevals=NAN, lm_evals=NAN, lm_source="", round_off=False, all_runs=1, all_within_11=0, closest=NAN,
              test="", p=NAN, p_equivalence=NAN, verdict=stats.UNDECIDED, tied=False)  # fmt: skip


@pytest.mark.parametrize("sentences", [
    conclusions.reference_sentence(None), conclusions.reference_sentence({}), conclusions.reference_sentence(ANSWER),
    conclusions.reference_sentence({**ANSWER, "runs": 3, "all_runs": 9, "within": 1, "evals": 12.0}),
    conclusions.reference_sentence({**ANSWER, "round_off": True}),
    conclusions.tied_sentence([], 0, True, NAN), conclusions.tied_sentence(["A"], 1, True, 0.01),
    conclusions.tied_sentence(["A"], 2, False, NAN), conclusions.no_reference_sentence([]),
    conclusions.no_reference_sentence(["A"]), conclusions.seed_instance_sentence(0), conclusions.seed_instance_sentence(1),
    conclusions.seed_instance_sentence(2), conclusions.groups_sentence([]), conclusions.groups_sentence([(1, 1)]),
    conclusions.groups_sentence([(1, 1), (0, 0)]), conclusions.across_sentence(None, ""), conclusions.across_sentence(None, "one instance"),
    conclusions.across_sentence(dict(mean_ranks=pd.Series(dtype=float), instances=0, configurations=0, test="Friedman", p=NAN,
                                     statistic=NAN, cd=NAN), ""),
    conclusions.across_sentence(dict(mean_ranks=pd.Series({"a": 1.0}), instances=1, configurations=1, test="Friedman", p=NAN,
                                     statistic=NAN, cd=NAN), ""),
    [conclusions.setting_sentence("", 0, 0, "", NAN, NAN, "", 0, "")],
    [conclusions.setting_sentence("crossover", 1, 1, "Wilcoxon signed-rank", 0.01, 0.01, "blend", 1, "")],
    [conclusions.setting_sentence("crossover", 2, 0, "Friedman", NAN, NAN, "", 0, "")],
    [conclusions.within_sentence("A", "2 configurations", "", "x", "", {}, "", "", "")],
    [conclusions.within_sentence("A", "2 configurations", "", "x", " (1 x f_ref)", {stats.BETTER: 1}, "Wilcoxon", "", "")],
])  # fmt: skip
def test_every_template_reads_whole_with_empty_single_and_nan_inputs(sentences):
    for s in sentences:
        assert s and not BROKEN.search(s), s
        assert s[0].isupper() and s.endswith("."), s


def test_sentences_of_one_run_and_of_one_configuration_read_whole(tmp_path):
    _run(tmp_path / "one", "r", "A", "blend", 0, final=1.5, validation=None)
    for seed in range(3):
        _run(tmp_path / "single", f"r{seed}", "A", "blend", seed, final=1.5 + seed, validation=None)
    for where in ("one", "single"):
        t = report.build_tables(report.find_runs([tmp_path / where])[0])
        said = _all_sentences(t)
        assert not any(BROKEN.search(s) for s in said), said


@pytest.mark.parametrize("within, verb", [(1, "comes"), (2, "come")])
def test_the_reference_sentence_agrees_its_verb_with_the_count(within, verb):
    first, rest = conclusions.reference_sentence({**ANSWER, "runs": 3, "all_runs": 9, "within": within, "evals": 12.0,
                                                  "all_within_11": within})  # fmt: skip
    assert f"; {within} of its 3 runs {verb} within 1% of LM's cost" in first, first
    assert rest.startswith(f"Of the 9 runs of every configuration but the references, {within} {verb} within 1.1 x"), rest
