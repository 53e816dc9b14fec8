"""The report's figures and the targets behind its ECDFs, checked by hand: which configurations a
figure draws and says it draws, integer generations, the COCO-style targets, the
critical-difference diagram only where the test separates something."""

import copy
import re

import numpy as np
import pandas as pd
import pytest
from report_fakes import ALGORITHMS, fake_run

from zrp_ga import report
from zrp_ga.report import drawing, figures, targets


def _ga(cx):
    cfg = copy.deepcopy(ALGORITHMS["ga"])
    cfg["crossover"]["op"]["_target_"] = f"zrp_ga.operators.crossover.{cx}"
    return cfg


def test_ecdf_targets_are_log_spaced_down_to_the_tightest_level(tmp_path):
    fake_run(tmp_path / "a", "I", "ga", [(1, 10.0), (4, 3.0)], floor=1.0)
    fake_run(tmp_path / "b", "I", "ga", [(1, 20.0), (4, 2.0)], floor=1.0, seed=1)
    runs = report.find_runs([tmp_path])[0]
    floors = targets.floors(runs, targets.TargetRule())
    t = targets.ecdf_targets(runs, floors)["I"]
    # f0 = median(10, 20) = 15, f_ref = 1: excesses from 14 down to 0.01 in 50 equal ratios r
    r = (0.01 / 14) ** (1 / 50)
    assert len(t) == 51 and t[0] == pytest.approx(15.0) and t[-1] == pytest.approx(1.01)
    assert t[10] == pytest.approx(1 + 14 * r**10)
    hits = targets.runtime_hits(runs, ["GA", "GA"], {"I": t})
    a = hits[hits["run"].str.endswith("/a")].set_index("level")
    assert a.loc["t00", "hit"] == pytest.approx(1 / 2)  # evaluation 1 of a 2-gene genome
    # run a's best is 10 from evaluation 1 and 3 from evaluation 4. Target k >= 10 while r^k >= 9/14:
    # k <= ln(9/14) / ln r = 3.05, so k = 0..3 are hit at evaluation 1; target k >= 3 while
    # r^k >= 1/7: k <= ln(1/7) / ln r = 13.4, so k = 4..13 at evaluation 4; none after.
    hit = a["hit"].to_numpy()
    assert (hit[:4] == 0.5).all() and (hit[4:14] == 2.0).all() and np.isinf(hit[14:]).all()


def test_fig2_draws_every_configuration_or_says_which(tmp_path):
    crossovers = ["blend", "sbx", "two_point", "one_point", "uniform", "a1", "a2", "a3", "a4", "a5"]
    for i, cx in enumerate(crossovers):
        fake_run(tmp_path / cx, "I", "ga", [(10, 5.0 + i), (20, 1e-30), (30, 1e-31)], floor=1e-20, config=_ga(cx), nominal=1.0,
                 choices={"algorithm": "ga", "crossover": cx})  # fmt: skip
    runs = report.find_runs([tmp_path])[0]
    labels, _ = report.configurations(runs)
    chosen = drawing.median_runs(runs, labels, sorted(set(labels))[:3])
    with figures.style("paper"):
        svg = figures.convergence_runs(chosen, 3, "I", 1e-9, True, tmp_path, (), page=True)
    assert "median run of all 3 configurations" in svg and "round-off floor" in svg  # short enough for one line
    assert not re.search(r">\s*\d+\.\d+\s*<", svg.split("generation")[0])  # generation ticks: integers only
    chosen = drawing.median_runs(runs, labels, sorted(set(labels)))[: figures.MAX_LINES]
    with figures.style("paper"):
        svg = figures.convergence_runs(chosen, 10, "I", 1e-9, True, tmp_path, (), page=True)
    assert f"median run of the {figures.MAX_LINES} best of 10" in svg  # the legend's title, wrapped after it


def test_costs_below_the_round_off_floor_are_drawn_at_it(tmp_path, monkeypatch):
    fake_run(tmp_path / "r", "I", "ga", [(10, 5.0), (20, 1e-30)], nominal=1.0)
    run = report.find_runs([tmp_path])[0][0]
    drawn = {}
    original = figures.Figure.subplots

    def spy(self, *a, **k):
        ax = original(self, *a, **k)
        drawn["ax"] = ax
        return ax

    monkeypatch.setattr(figures.Figure, "subplots", spy)
    figures.convergence_runs([("GA", run)], 1, "I", 1e-9, True, tmp_path, ())
    lowest = min(np.min(line.get_ydata()) for line in drawn["ax"].get_lines())
    assert lowest == pytest.approx(1e-9)


def test_critical_difference_rows_stay_readable_at_48_configurations(tmp_path):
    rng = np.random.default_rng(0)
    names = [f"configuration number {i}" for i in range(48)]
    scores = pd.DataFrame(rng.random((6, 48)) + np.arange(48) / 20, columns=names)
    result = report.stats.friedman(scores)
    with figures.style("paper"):
        svg = figures.critical_difference(result, tmp_path, ("svg",), page=True)
    assert all(f">{n}  (" in svg for n in names)  # every configuration named once, on its own row
    assert (tmp_path / "critical_difference.svg").exists()


def test_no_critical_difference_diagram_for_two_configurations(tmp_path):
    for inst in ("I1", "I2", "I3"):
        for i, cx in enumerate(("blend", "sbx")):
            fake_run(tmp_path / "runs" / f"{inst}{cx}", inst, "ga", [(10, 5.0), (20, 1.0 + i)], floor=0.5, config=_ga(cx),
                     choices={"algorithm": "ga", "crossover": cx})  # fmt: skip
    t = report.write_report([tmp_path / "runs"], tmp_path / "out", formats=("png",))
    assert t["friedman"]["test"] == "sign test"
    assert not (tmp_path / "out" / "critical_difference.png").exists()
    assert "two configurations, the sign test says it all" in (tmp_path / "out" / "index.html").read_text()


@pytest.mark.parametrize("name", ["paper", "screen"])
def test_styles_keep_text_between_8_and_10_points(name):
    sizes = [v for k, v in figures.STYLES[name]["rc"].items() if k.endswith("size") and "marker" not in k]
    assert sizes and all(8 <= s <= 10 for s in sizes)
    assert figures.STYLES["paper"]["width"] == 3.5
