"""The IOHprofiler export against what the ``ioh`` package's own logger writes for the same runs:
each made-up run is replayed through ``ioh.logger.Analyzer`` evaluation by evaluation, and the
two folders must hold the same files, meta data and (evaluations, best cost) records."""

import json

import numpy as np
import pytest
from report_fakes import fake_run

from zrp_ga import report

ioh = pytest.importorskip("ioh")
X = [0.5, -0.25]  # report_fakes' best genome

RUNS = {  # name: (instance, algorithm, convergence rows, initial population costs, seed)
    "a1": ("zrp-fake-A", "ga", [(4, 2.0), (8, 1.0), (12, 1.0)], [5.0, 2.5, 3.0, 2.0], 0),
    "a2": ("zrp-fake-A", "ga", [(4, 3.0), (8, 3.0), (12, 1.5)], [3.0, 4.0, 3.5, 3.25], 7),
    "b1": ("zrp-fake-B", "ga", [(4, 6.0), (8, 4.0)], [6.0, 7.0, 8.0, 9.0], 0),
    "a3": ("zrp-fake-A", "lm", [(0, 8.0), (1, 8.0), (2, 4.0), (5, 0.5)], [8.0], 3),
}  # fmt: skip


def _replay(trace_e, trace_b, nevals):
    """Costs of evaluations 1..nevals whose best so far is the trace: the new best where it
    improves, something worse elsewhere, the best again at the last evaluation."""
    best_at = dict(zip(trace_e.tolist(), trace_b.tolist()))
    out, best = [], np.inf
    for k in range(1, nevals + 1):
        if k in best_at and best_at[k] < best:
            best = best_at[k]
            out.append(best)
        else:
            out.append(best if k == nevals else best + 1.0)
    return out


def _reference(runs, labels, root):
    """The folder ``ioh.logger.Analyzer`` writes for ``runs``: one logger per configuration,
    one wrapped problem per instance, each run with its seed as ioh's instance id."""
    for label in dict.fromkeys(labels):
        logger = ioh.logger.Analyzer(root=str(root), folder_name=report.ioh_export.safe_name(label), algorithm_name=label,
                                     algorithm_info="", store_positions=False)  # fmt: skip
        for instance in sorted({r.instance for r in runs}):
            mine = [r for r, lab in zip(runs, labels) if lab == label and r.instance == instance]
            if not mine:
                continue
            replay = {"costs": iter([])}  # the run being replayed
            ioh.wrap_problem(lambda x, replay=replay: next(replay["costs"]), name=instance,
                             optimization_type=ioh.OptimizationType.MIN, lb=-1, ub=1)  # fmt: skip
            for r in mine:
                problem = ioh.get_problem(instance, dimension=2, instance=r.summary["seed"])
                problem.attach_logger(logger)
                replay["costs"] = iter(_replay(r.evals, r.best, r.nevals))
                for _ in range(r.nevals):
                    problem(np.array(X))
                problem.reset()
                problem.detach_logger()
        logger.close()


def _records(dat):
    """The (evaluations, cost) records of each run of a data file."""
    runs = []
    for line in dat.read_text().splitlines():
        if line.startswith("evaluations"):
            runs.append([])
        else:
            e, y = line.split()
            runs[-1].append((int(e), float(y)))
    return runs


def test_export_matches_what_ioh_writes(tmp_path):
    for name, (instance, algorithm, rows, initial, seed) in RUNS.items():
        fake_run(tmp_path / "runs" / name, instance, algorithm, rows, initial=initial, seed=seed)
    runs = report.find_runs([tmp_path / "runs"])[0]
    labels, shown = report.configurations(runs)
    assert report.ioh_export.export(runs, labels, shown, tmp_path / "ours") == []
    _reference(runs, labels, tmp_path / "ioh")
    ours = sorted(p.relative_to(tmp_path / "ours") for p in (tmp_path / "ours").rglob("*.json"))
    theirs = sorted(p.relative_to(tmp_path / "ioh") for p in (tmp_path / "ioh").rglob("*.json"))
    assert [p.parent for p in ours] == [p.parent for p in theirs] and len(ours) == 3  # GA on A and B, LM on A
    for mine, ref in zip(ours, theirs):
        a = json.loads((tmp_path / "ours" / mine).read_text())
        b = json.loads((tmp_path / "ioh" / ref).read_text())
        assert set(a) == set(b)
        assert a["version"] == b["version"]  # the format of the installed ioh
        fid = b["function_id"]
        assert ref.name == mine.name.replace(f"_f{a['function_id']}_", f"_f{fid}_")
        for key in ("function_name", "maximization", "algorithm", "attributes"):
            assert a[key] == b[key] or (key == "algorithm" and a[key]["name"] == b[key]["name"]), key
        (sa,), (sb,) = a["scenarios"], b["scenarios"]
        assert sa["dimension"] == sb["dimension"] == 2
        assert sb["path"] == sa["path"].replace(f"_f{a['function_id']}", f"_f{fid}")
        assert [(r["instance"], r["evals"], r["best"]["evals"], r["best"]["y"], r["best"]["x"]) for r in sa["runs"]] == [
            (r["instance"], r["evals"], r["best"]["evals"], r["best"]["y"], r["best"]["x"]) for r in sb["runs"]]  # fmt: skip
        records = _records(tmp_path / "ours" / mine.parent / sa["path"])
        assert records == _records(tmp_path / "ioh" / ref.parent / sb["path"])
        assert all(run[0][0] == 1 for run in records)  # every block starts at evaluation 1
    seeds = {json.loads(p.read_text())["function_name"]: [r["instance"] for r in json.loads(p.read_text())["scenarios"][0]["runs"]]
             for p in (tmp_path / "ours" / "GA").glob("*.json")}  # fmt: skip
    assert seeds == {"zrp-fake-A": [0, 7], "zrp-fake-B": [0]}  # one function per instance, its seeds as instance ids


def test_the_first_generations_records_by_hand(tmp_path):
    fake_run(tmp_path / "r", "zrp-fake-C", "ga", [(4, 2.0), (8, 1.0), (12, 1.0)], initial=[5.0, 2.5, 3.0, 2.0])
    runs = report.find_runs([tmp_path])[0]
    report.ioh_export.export(runs, ["GA"], {"GA": {}}, tmp_path / "out")
    dat = tmp_path / "out" / "GA" / "data_f1_zrp-fake-C" / "IOHprofiler_f1_DIM2.dat"
    assert dat.read_text() == "evaluations raw_y\n1 5.0\n2 2.5\n4 2.0\n8 1.0\n12 1.0\n"


def test_iohinspector_reads_the_export_back(tmp_path):
    """IOHprofiler's own reader (iohinspector) finds one function per problem instance and
    configuration, each seed as an instance id, and every run's (evaluations, best) records."""
    iohinspector = pytest.importorskip("iohinspector")
    for name, (instance, algorithm, rows, initial, seed) in RUNS.items():
        fake_run(tmp_path / "runs" / name, instance, algorithm, rows, initial=initial, seed=seed)
    runs = report.find_runs([tmp_path / "runs"])[0]
    labels, shown = report.configurations(runs)
    report.ioh_export.export(runs, labels, shown, tmp_path / "ours")
    manager = iohinspector.DataManager()
    for folder in sorted(p for p in (tmp_path / "ours").iterdir() if p.is_dir()):
        manager.add_folder(str(folder))
    meta = manager.overview.to_pandas()
    found = sorted(zip(meta["algorithm_name"], meta["function_name"], meta["instance"]))
    assert found == [("GA", "zrp-fake-A", 0), ("GA", "zrp-fake-A", 7), ("GA", "zrp-fake-B", 0), ("Levenberg-Marquardt", "zrp-fake-A", 3)]
    data = manager.load(monotonic=True, include_meta_data=True).to_pandas()
    a7 = data[(data["function_name"] == "zrp-fake-A") & (data["instance"] == 7) & (data["algorithm_name"] == "GA")]
    # run a2: initial population costs 3, 4, 3.5, 3.25 (best 3 at evaluation 1), then 1.5 at 12
    assert list(zip(a7["evaluations"], a7["raw_y"])) == [(1, 3.0), (12, 1.5)]
