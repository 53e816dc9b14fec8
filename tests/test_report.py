"""zrp-ga-report on a real 3-configuration x 3-seed sweep (each seed its own problem instance),
checked against hand computations from the runs' files."""

import itertools
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from zrp_ga import report
from zrp_ga.cli import report as report_cli
from zrp_ga.run.directory import MANIFEST, read_manifest

CROSSOVERS = ["blend", "sbx", "two_point"]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    where = tmp_path_factory.mktemp("sweep") / "sweep"
    proc = subprocess.run(
        [sys.executable, "-m", "zrp_ga.cli", "-m", f"crossover={','.join(CROSSOVERS)}", "seed=0,1,2",
         "problem=multipose", "problem.n_poses=6", "problem.n_validation=5", "refine=none", "population.mu=10",
         "population.lambda_=10", "population.generations=6", f"hydra.sweep.dir={where}"],
        capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    return where


def _finals(sweep):
    """Final costs by crossover, straight from each job's summary.json."""
    out = {c: [] for c in CROSSOVERS}
    for job in read_manifest(sweep).itertuples():
        summary = json.loads((sweep / str(job.dir) / "summary.json").read_text())
        out[summary["choices"]["crossover"]].append(summary["final_cost"])
    return {c: np.array(v) for c, v in out.items()}


def _u_greater(x, y):
    return sum((a > b) + 0.5 * (a == b) for a in x for b in y)


def _exact_two_sided_p(x, y):
    """Exact Mann-Whitney p by enumerating every split of the pooled values (no ties here)."""
    pooled = np.concatenate([x, y])
    u_obs = _u_greater(x, y)
    n1 = len(x)
    us = [_u_greater(pooled[list(c)], np.delete(pooled, list(c))) for c in itertools.combinations(range(len(pooled)), n1)]
    mean = n1 * len(y) / 2
    return min(1.0, np.mean([abs(u - mean) >= abs(u_obs - mean) - 1e-12 for u in us]))


def test_every_file_is_written(sweep, tmp_path):
    out = tmp_path / "report"
    t = report.write_report([sweep], out)
    for name in ["index.html", "within_instances.csv", "ecdf_targets.csv", "runs.csv", "tidy.csv", "summary.csv", "summary.md",
                 "statistics.csv", "factors.csv", "left_out.csv", "table2_initial_population.md", "table3_best_params.md",
                 "targets.csv", "targets.md", "ert.csv", "ert.md", "ecdf.csv", "fixed_budget.csv", "fixed_budget.md",
                 "per_instance.csv", "per_instance.md", "ranks.csv", "ranks.md", "conclusions.json", "reference.csv"]:  # fmt: skip
        assert (out / name).stat().st_size > 0, name
    assert not (out / "factors.md").exists()  # one setting varies: its values are the configurations, compared once
    drawn = t["friedman"]["p"] < 0.05  # the critical-difference diagram only where the test separates something
    for fig in ["fig2_convergence", "convergence_by_configuration", "ecdf_evals_to_target", "ecdf_by_instance",
                "validation_error_boxplot"] + ["critical_difference"] * drawn:  # fmt: skip
        assert (out / f"{fig}.png").stat().st_size > 10_000 and (out / f"{fig}.pdf").exists(), fig
    assert (out / "critical_difference.png").exists() == drawn
    assert drawn or "No critical-difference diagram: Friedman finds no difference" in (out / "index.html").read_text()
    tidy = pd.read_csv(out / "tidy.csv")
    assert len(tidy) == 9 * 7 and set(tidy["crossover"]) == set(CROSSOVERS)  # 9 runs x (gen 0..6)
    assert {"run", "configuration", "instance", "gen", "nevals", "best", "val_rms_mm"} <= set(tidy.columns)
    assert len(list((out / "ioh").glob("*/IOHprofiler_f*.json"))) == 9  # 3 configurations x 3 instances
    assert not list(tmp_path.glob(".report.*"))  # the staging folder is gone


def test_summary_by_hand_and_the_seed_that_drew_the_instance_is_named(sweep, tmp_path):
    finals = _finals(sweep)
    target = float(np.median(np.concatenate(list(finals.values()))))
    tables = report.build_tables(report.find_runs([sweep])[0], report.TargetRule(absolute=target))
    summary = tables["summary"].set_index("configuration")
    labels = {c: f"{c.replace('_', ' ')} crossover" for c in CROSSOVERS}
    for c, x in finals.items():
        row = summary.loc[labels[c]]
        s = np.sort(x)
        assert row["runs"] == 3 and row["final_cost_median"] == pytest.approx(s[1])
        # numpy's linear percentile of three values: q1 halfway between the first two
        assert row["final_cost_q1"] == pytest.approx((s[0] + s[1]) / 2) and row["final_cost_q3"] == pytest.approx((s[1] + s[2]) / 2)
        assert row["success_rate"] == pytest.approx(np.mean(x <= target))
    # each seed drew its own instance (problem.seed unset): one run per configuration and instance, so nothing is
    # compared within an instance, and the page says how to hold the instance instead of asking for more seeds
    assert tables["seed_drew_instance"] and not len(tables["within"])
    said = report.conclusions.sentences(tables)
    first = " ".join(said["In short"])
    assert "Each of the 3 seeds drew its own problem instance" in first and "problem.seed=N" in first
    assert not any("more seeds are needed" in x for lines in said.values() for x in lines)


def test_evaluations_to_target_and_area_under_curve_by_hand(sweep, tmp_path):
    tables = report.build_tables(report.find_runs([sweep])[0], report.TargetRule(absolute=1.0))
    runs = tables["runs"]
    budget = min(pd.read_csv(f"{r}/convergence.csv")["nevals"].iloc[-1] for r in runs["run"])
    for r in runs.itertuples():
        conv = pd.read_csv(f"{r.run}/convergence.csv")
        initial = pd.read_csv(f"{r.run}/initial_population.csv")["cost"].tolist()
        # the initial population one evaluation at a time, then the generations' ends
        evaluations = list(range(1, len(initial) + 1)) + list(conv["nevals"][1:])
        hits = [e for e, b in zip(evaluations, initial + list(conv["best"][1:])) if b <= 1.0]
        assert r.evals_to_target == (hits[0] if hits else np.inf)
        total, best = 0.0, np.inf
        rows = list(zip(conv["nevals"], conv["best"]))
        for (e0, b0), (e1, _) in zip(rows, rows[1:] + [(budget, None)]):
            best = min(best, b0)
            if e0 < budget:
                total += math.log10(best) * (min(e1, budget) - e0)
        assert r.auc == pytest.approx(total / (budget - rows[0][0]))


def test_ranks_across_the_sweeps_instances(sweep, tmp_path):
    """Each seed is its own instance: Friedman's test over 3 instances of the 3 crossovers,
    against scipy on the final costs read from summary.json, over the instance's best (no LM
    floor here), costs within the report's tolerance (1 % of that best) one result."""
    table = {}
    for job in read_manifest(sweep).itertuples():
        s = json.loads((sweep / str(job.dir) / "summary.json").read_text())
        table.setdefault(s["instance"], {})[s["choices"]["crossover"]] = s["final_cost"]
    assert len(table) == 3
    costs = np.array([[table[i][c] for c in CROSSOVERS] for i in sorted(table)])
    scores = costs / costs.min(axis=1, keepdims=True)
    for row in scores:  # a tie starts at a score and takes every score up to it + 0.01
        order = np.argsort(row)
        start = -np.inf
        for j in order:
            start = row[j] if row[j] > start + 0.01 else start
            row[j] = start
    assert all(len(set(row)) > 1 for row in scores)  # no instance where every crossover ties (then evaluations are ranked)
    f = report.build_tables(report.find_runs([sweep])[0])["friedman"]
    assert f["instances"] == 3 and f["statistic"] == pytest.approx(stats.friedmanchisquare(*scores.T).statistic)
    ranks = stats.rankdata(scores, axis=1).mean(axis=0)
    for c, rank in zip(CROSSOVERS, ranks):
        assert f["mean_ranks"][f"{c.replace('_', ' ')} crossover"] == pytest.approx(rank)


def test_partial_sweep_reports_what_it_left_out(sweep, tmp_path, capsys):
    partial = tmp_path / "partial"
    shutil.copytree(sweep, partial)
    manifest = read_manifest(partial)
    failed, running = manifest.loc[1], manifest.loc[2]
    (partial / str(running.dir) / "summary.json").unlink()
    with open(partial / MANIFEST, "a") as f:
        f.write(json.dumps({**failed.to_dict(), "status": "failed", "error": "ValueError: made to fail"}) + "\n")
        f.write(json.dumps({**running.to_dict(), "status": "running", "error": None}) + "\n")
    report_cli.main([str(partial), "--out", str(tmp_path / "r"), "--formats", "none"])
    printed = capsys.readouterr().out
    assert printed.startswith("7 runs of 3 configurations on 3 instance(s)")
    assert f"left out {partial / str(failed.dir)}: failed: ValueError: made to fail" in printed
    assert f"left out {partial / str(running.dir)}: still running" in printed
    left = pd.read_csv(tmp_path / "r" / "left_out.csv")
    assert len(left) == 2


def test_a_job_read_alone_takes_its_settings_from_hydra(sweep):
    job = read_manifest(sweep).iloc[4]
    (run,), left = report.find_runs([sweep / str(job.dir)])  # no manifest: .hydra/overrides.yaml
    assert left == [] and run.overrides == dict(o.split("=", 1) for o in job.overrides.split())


def test_nothing_to_report_is_one_clear_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        report_cli.main([str(tmp_path)])
    assert exit_.value.code == 2 and capsys.readouterr().err.startswith("zrp-ga-report: error: no finished run under")
    assert list(tmp_path.iterdir()) == []




def test_the_page_says_how_the_runs_were_made_without_absolute_paths(sweep, tmp_path):
    import re
    import shlex

    out = tmp_path / "report"
    report.write_report([sweep], out, formats=("png",), latex=True)
    text = (out / "index.html").read_text()
    # the command, from the jobs' records: the swept keys as comma lists, the rest as every job had them
    commands = [shlex.split(html_unescape(m)) for m in re.findall(r"<pre>(zrp-ga -m .*?)</pre>", text)]
    assert len(commands) == 1
    words = commands[0]
    assert words[:2] == ["zrp-ga", "-m"]
    assert f"crossover={','.join(CROSSOVERS)}" in words and "seed=0,1,2" in words and "population.generations=6" in words
    sweep_dir = next(w for w in words if w.startswith("hydra.sweep.dir="))
    assert not sweep_dir.split("=", 1)[1].startswith("/")  # relative to the folder it ran in
    assert not re.search(r"""[\s>("'=]/(tmp|work|home|root|Users)/""", text)  # no absolute path of this machine
    # settings held fixed and varied, from the runs' resolved configs
    fixed = text[text.index("Settings held fixed"):text.index("The report</h3>")]
    varied = text[text.index("Settings varied"):text.index("Settings held fixed")]
    assert "<td>population.mu</td><td>10</td>" in fixed and "algorithm.population.mu" not in text  # one name for one setting
    assert ">seed<" in varied and ">crossover.op._target_<" in varied
    # the version, with its commit when installed from a clone (this test runs from one)
    commit = subprocess.run(["git", "-C", str(Path(report.__file__).parents[2]), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()  # fmt: skip
    if commit:
        assert f"zrp_ga 0.1.0 (commit {commit}" in text
    # LaTeX: the configurations' table as booktabs, the numbers those of summary.csv
    tex = (out / "summary.tex").read_text()
    assert tex.count("\\toprule") == tex.count("\\midrule") == tex.count("\\bottomrule") == 1
    summary = pd.read_csv(out / "summary.csv")
    for row in summary.itertuples():
        line = next(ln for ln in tex.splitlines() if ln.startswith(row.configuration.replace("_", "\\_") + " & "))
        assert f"& {row.runs} & {row.final_over_ref_median:.4g} &" in line


def html_unescape(s):
    import html

    return html.unescape(s)
