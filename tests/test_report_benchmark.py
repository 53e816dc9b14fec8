"""The report's benchmarking numbers on made-up runs, against hand computations: floors and
targets, ERT, the ECDF, fixed budgets, Friedman's and Nemenyi's tests, labels."""

import copy
import math

import numpy as np
import pytest
from report_fakes import ALGORITHMS, fake_run
from scipy import stats

from zrp_ga import report
from zrp_ga.report import targets
from zrp_ga.report.targets import TargetRule


@pytest.fixture
def two_instances(tmp_path):
    """Instance A (floor 1.0 in summary.json): GA runs r1, r2 and an LM run r3; instance B (no
    floor): GA run r4 and LM run r5. Costs chosen so that every target is easy to follow."""
    fake_run(tmp_path / "r1", "A", "ga", [(10, 3.0), (20, 1.2), (30, 1.0)], floor=1.0, seed=1)
    fake_run(tmp_path / "r2", "A", "ga", [(10, 2.0), (20, 1.6), (40, 1.4)], floor=1.0, seed=2)
    fake_run(tmp_path / "r3", "A", "lm", [(0, 10.0), (1, 10.0), (2, 1.04), (3, 1.009)], floor=1.0)
    fake_run(tmp_path / "r4", "B", "ga", [(10, 8.0), (20, 4.0)])
    fake_run(tmp_path / "r5", "B", "lm", [(1, 9.0), (5, 5.0)])
    return tmp_path


def _tables(where, **kw):
    runs, left = report.find_runs([where])
    assert left == []
    return report.build_tables(runs, **kw)


def test_floor_comes_from_summary_else_best_known(two_instances):
    floors = _tables(two_instances)["floors"].set_index("instance")
    assert floors.loc["A", "floor"] == 1.0 and floors.loc["A", "floor_source"] == "summary.json floor"
    assert floors.loc["B", "floor"] == 4.0 and floors.loc["B", "floor_source"].startswith("best known (lowest final cost of 2 runs")
    assert not floors["round_off"].any()
    assert [floors.loc["B", f"target_{c}"] for c in ("1.5", "1.1", "1.05", "1.01")] == pytest.approx([6.0, 4.4, 4.2, 4.04])


def test_round_off_floor_scales_targets_by_the_nominal_cost(tmp_path):
    fake_run(tmp_path / "ga", "paper", "ga", [(20, 0.03), (40, 4e-18)], nominal=0.05)
    fake_run(tmp_path / "lm", "paper", "lm", [(1, 0.05), (9, 4e-16)], nominal=0.05)
    t = _tables(tmp_path)
    row = t["floors"].iloc[0]
    assert row["floor"] == 4e-18 and row["round_off"]
    assert row["reference"] == pytest.approx(5e-11)  # 1e-9 x the nominal cost
    assert row["target_1.01"] == pytest.approx(5.05e-11)
    assert (t["per_instance"]["success_1.01"] == 1.0).all()  # both solve it
    looser = report.build_tables(report.find_runs([tmp_path])[0], TargetRule(round_off=1e-20))  # --round-off 1e-20
    assert looser["floors"].iloc[0]["reference"] == 4e-18 and not looser["floors"].iloc[0]["round_off"]


def test_ert_by_hand(two_instances):
    ert = _tables(two_instances)["ert"]

    def value(config, instance, level):
        row = ert[(ert.configuration == config) & (ert.instance == instance) & (ert.level == level)]
        return float(row["ert"].iloc[0])

    # A, GA: 1.5 -> r1 at 20, r2 at 40; tighter levels: r1 at 30, r2 never (40 evaluations in full)
    assert value("GA", "A", "1.5") == 30 and value("GA", "A", "1.1") == 70 and value("GA", "A", "1.01") == 70
    # A, LM: the row at 0 evaluations counts as evaluation 1; 1.04 at 2 evaluations, 1.009 at 3
    assert value("Levenberg-Marquardt", "A", "1.05") == 2 and value("Levenberg-Marquardt", "A", "1.01") == 3
    # B (floor 4.0): r4 hits everything at 20; r5 (best 5.0) only 1.5 x 4 = 6, at 5
    assert value("Levenberg-Marquardt", "B", "1.5") == 5 and math.isinf(value("Levenberg-Marquardt", "B", "1.1"))
    # pooled over instances: every run a trial
    assert value("GA", "all", "1.5") == pytest.approx((20 + 40 + 20) / 3)
    assert value("GA", "all", "1.1") == pytest.approx((30 + 40 + 20) / 2)
    assert value("Levenberg-Marquardt", "all", "1.1") == pytest.approx((2 + 5) / 1)
    assert value("Levenberg-Marquardt", "all", "1.01") == pytest.approx((3 + 5) / 1)


def test_ecdf_by_hand(two_instances):
    curves = _tables(two_instances)["ecdf"]

    def at(config, b):
        return targets.ecdf_at(curves[curves.configuration == config], b)

    # GA: 8 (instance, level) pairs; A's two runs weigh 1/16 each, B's one run 1/8
    assert [at("GA", b) for b in (19, 20, 29, 30, 40, 1e6)] == pytest.approx([0, 9 / 16, 9 / 16, 12 / 16, 13 / 16, 13 / 16])
    # LM: one run per instance, 1/8 per hit: three levels at 2, 1.01 at 3, B's 1.5 at 5
    assert [at("Levenberg-Marquardt", b) for b in (1, 2, 3, 4, 5)] == pytest.approx([0, 3 / 8, 4 / 8, 4 / 8, 5 / 8])


def test_absolute_target_replaces_the_levels(two_instances):
    t = _tables(two_instances, rule=TargetRule(absolute=1.3))
    ert = t["ert"].set_index(["configuration", "instance"])
    assert list(t["ert"]["level"].unique()) == ["cost<=1.3"]
    assert ert.loc[("GA", "A"), "ert"] == 60  # r1 reaches 1.2 at 20, r2 never: (20 + 40) / 1
    assert math.isinf(ert.loc[("GA", "B"), "ert"])


def test_fixed_budget_by_hand(two_instances):
    t = _tables(two_instances, budgets=(15, 25, 1000))
    fb = t["fixed_budget"].set_index(["configuration", "instance", "budget"])
    # A's GA runs within 15 evaluations: 3.0 and 2.0; within 25: 1.2 and 1.6 (f_ref 1.0)
    assert [fb.loc[("GA", "A", b), "median_cost_over_ref"] for b in (15, 25)] == pytest.approx([2.5, 1.4])
    assert fb.loc[("GA", "B", 15), "median_cost_over_ref"] == pytest.approx(8.0 / 4.0)
    # 1,000 evaluations: the runs stopped by their budget at 30 and 40: no number for a budget never run
    assert math.isnan(fb.loc[("GA", "A", 1000), "median_cost_over_ref"])
    assert math.isnan(t["fixed_budget_all"].set_index(["configuration", "budget"]).loc[("GA", 1000), "median_cost_over_ref"])


def test_a_run_that_stopped_by_itself_keeps_its_final_cost_and_default_budgets_are_the_runs(tmp_path):
    fake_run(tmp_path / "r1", "A", "ga", [(10, 3.0), (30, 1.0)], floor=1.0, stop_reason="stagnation")
    fake_run(tmp_path / "r2", "A", "ga", [(10, 2.0), (250, 1.4)], floor=1.0, seed=2)
    t = _tables(tmp_path)
    assert t["budgets"] == (100, 250)  # the decades below the longest run, and the longest run
    fb = t["fixed_budget"].set_index("budget")["median_cost_over_ref"]
    # at 100: r1 converged (1.0, carried), r2 at 2.0; at 250 both: 1.0 and 1.4
    assert fb.loc[100] == pytest.approx(1.5) and fb.loc[250] == pytest.approx(1.2)


def test_trace_uses_the_initial_population_evaluation_by_evaluation(tmp_path):
    fake_run(tmp_path / "r", "A", "ga", [(4, 2.0), (8, 1.0)], initial=[5.0, 2.0, 3.0, 2.5])
    run = report.find_runs([tmp_path])[0][0]
    assert run.evals.tolist() == [1, 2, 3, 4, 8] and run.best.tolist() == [5.0, 2.0, 2.0, 2.0, 1.0]
    assert targets.first_hit(run.evals, run.best, 2.0) == 2.0


FRIEDMAN = {  # final costs: instance -> (GA, LM, CMA-ES)
    "I1": (2.0, 1.0, 3.0), "I2": (1.5, 1.0, 1.2), "I3": (1.0, 2.0, 3.0), "I4": (2.0, 1.0, 2.0),
}  # fmt: skip


def test_friedman_and_nemenyi_by_hand(tmp_path):
    for instance, costs in FRIEDMAN.items():
        for algorithm, cost in zip(("ga", "lm", "cmaes"), costs):
            fake_run(tmp_path / f"{instance}-{algorithm}", instance, algorithm, [(10, 5.0), (20, cost)])
    f = _tables(tmp_path)["friedman"]
    ranks = f["mean_ranks"]
    # ranks per instance: I1 (2, 1, 3), I2 (3, 1, 2), I3 (1, 2, 3), I4 (2.5, 1, 2.5)
    assert ranks["GA"] == 8.5 / 4 and ranks["Levenberg-Marquardt"] == 5 / 4 and ranks["CMA-ES"] == 10.5 / 4
    q = 12 * 4 / (3 * 4) * ((8.5 / 4 - 2) ** 2 + (5 / 4 - 2) ** 2 + (10.5 / 4 - 2) ** 2)
    ties = 1 - (2**3 - 2) / (4 * 3 * (3**2 - 1))  # one pair tied in I4
    assert f["test"] == "Friedman" and f["statistic"] == pytest.approx(q / ties)
    assert f["statistic"] == pytest.approx(stats.friedmanchisquare(*np.array(list(FRIEDMAN.values())).T).statistic)
    assert f["p"] == pytest.approx(math.exp(-f["statistic"] / 2))  # chi-square, 2 degrees of freedom
    # Demšar (2006), Table 5: q_0.05 = 2.343 for k = 3; CD = q sqrt(k (k + 1) / (6 N))
    assert f["cd"] == pytest.approx(2.343 * math.sqrt(3 * 4 / (6 * 4)), rel=1e-3)
    for row in f["pairs"].itertuples():
        assert (row.p_nemenyi < 0.05) == (abs(row.rank_a - row.rank_b) > f["cd"])


def test_two_configurations_get_the_sign_test(tmp_path):
    wins = [(1.0, 2.0), (1.0, 2.0), (1.0, 2.0), (1.0, 2.0), (3.0, 2.0)]  # GA lower on 4 of 5 instances
    for i, (ga, lm) in enumerate(wins):
        fake_run(tmp_path / f"{i}-ga", f"I{i}", "ga", [(10, 5.0), (20, ga)])
        fake_run(tmp_path / f"{i}-lm", f"I{i}", "lm", [(10, 5.0), (20, lm)])
    f = _tables(tmp_path)["friedman"]
    assert f["test"] == "sign test" and f["p"] == pytest.approx(2 * (5 + 1) / 2**5)  # P(X >= 4) + P(X <= 1)


def test_costs_within_the_tightest_target_tie(tmp_path):
    for i, (ga, lm, cma) in enumerate([(1.0, 1.005, 2.0), (1.0, 1.02, 2.0)]):  # 1.005 is within 1.01 x 1.0, 1.02 is not
        for algorithm, cost in zip(("ga", "lm", "cmaes"), (ga, lm, cma)):
            fake_run(tmp_path / f"{i}-{algorithm}", f"I{i}", algorithm, [(10, 5.0), (20, cost)])
    f = _tables(tmp_path)["friedman"]
    assert f["ranks"].loc["I0"].tolist() == [3.0, 1.5, 1.5] and f["ranks"].loc["I1"].tolist() == [3.0, 1.0, 2.0]  # CMA-ES, GA, LM


def test_a_diverged_run_counts_hits_nothing_and_ranks_last(tmp_path):
    fake_run(tmp_path / "ga", "A", "ga", [(10, 5.0), (20, 1.0)])
    fake_run(tmp_path / "lm", "A", "lm", [(1, float("inf")), (5, float("inf"))], final=None)
    fake_run(tmp_path / "ga2", "B", "ga", [(10, 5.0), (20, 2.0)])
    fake_run(tmp_path / "lm2", "B", "lm", [(1, 4.0), (5, 3.0)])
    t = _tables(tmp_path)
    assert t["floors"].set_index("instance").loc["A", "floor"] == 1.0
    ert = t["ert"].set_index(["configuration", "instance", "level"])["ert"]
    assert math.isinf(ert[("Levenberg-Marquardt", "A", "1.5")]) and ert[("Levenberg-Marquardt", "all", "1.5")] == (5 + 5) / 1
    assert t["friedman"]["mean_ranks"]["GA"] == 1.0 and t["friedman"]["test"] == "sign test"
    written = report.write_report([tmp_path], tmp_path / "r", formats=())
    assert f"not in the IOH export: {tmp_path / 'lm'} (no finite cost)" in written["notes"]  # JSON has no infinity
    assert f"no Table 2 or 3: {tmp_path / 'ga' / 'best_params.csv'} cannot be read" in written["notes"]  # made-up runs lack it


def test_ranks_need_two_instances_with_every_configuration(two_instances, tmp_path):
    t = _tables(two_instances)
    assert t["friedman"] is not None and t["friedman"]["instances"] == 2
    fake_run(tmp_path / "x", "only-one", "ga", [(10, 5.0)])
    one = _tables(tmp_path / "x")
    assert one["friedman"] is None and "one configuration" in one["friedman_note"]


def test_labels_name_what_tells_configurations_apart(tmp_path):
    sbx = copy.deepcopy(ALGORITHMS["ga"])
    sbx["crossover"]["op"]["_target_"] = "zrp_ga.operators.crossover.sbx"
    fake_run(tmp_path / "a", "A", "ga", [(10, 1.0)], choices={})  # made without Hydra: names from _target_
    fake_run(tmp_path / "b", "A", "ga", [(10, 1.0)], config=sbx, choices={})
    fake_run(tmp_path / "c", "A", "lm", [(10, 1.0)], choices={})
    labels, shown = report.configurations(report.find_runs([tmp_path])[0])
    assert labels == ["GA, blend crossover", "GA, sbx crossover", "Levenberg-Marquardt"]
    assert shown["GA, sbx crossover"] == {"algorithm": "ga", "crossover": "sbx"}
    bigger = copy.deepcopy(ALGORITHMS["ga"])
    bigger["population"]["mu"] = 50
    fake_run(tmp_path / "d", "A", "ga", [(10, 1.0)], config=bigger, choices={})
    labels, _ = report.configurations(report.find_runs([tmp_path])[0])
    assert labels[0] == "GA, blend crossover, mu 10" and labels[3] == "GA, blend crossover, mu 50"


def test_only_keeps_the_runs_given_a_setting(two_instances, tmp_path):
    t = report.write_report([two_instances], tmp_path / "r", only=["algorithm=lm"], formats=())
    assert set(t["runs"]["configuration"]) == {"Levenberg-Marquardt"} and len(t["runs"]) == 2
    t = report.write_report([two_instances], tmp_path / "r", only=["population.mu=10"], formats=())  # a key of the config
    assert set(t["runs"]["configuration"]) == {"GA"} and not (tmp_path / "r" / "fig2_convergence.png").exists()
    with pytest.raises(ValueError, match="no finished run under .* with algorithm=cmaes"):
        report.write_report([two_instances], tmp_path / "r", only=["algorithm=cmaes"])


def test_settings_in_words():
    assert report.describe("crossover", "two_point") == "two point crossover"
    assert report.describe("inversion", "none") == "no inversion"
    assert report.describe("algorithm", "lm") == "Levenberg-Marquardt"
    assert report.describe("population.mu", "50") == "mu 50"
