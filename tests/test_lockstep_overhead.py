"""What runs evolved together share to cost less than a run each (issue 32, item 3) changes no
number: a convergence row's line is the line Python's csv writer writes for it, and the
assessment of a genome, whose parts that do not depend on the genome are computed once per
problem instance, is that of the same genome on an instance assessed for the first time."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from zrp_ga import config
from zrp_ga.problems import assessment
from zrp_ga.run.build import prepare
from zrp_ga.run.callbacks import COLUMNS, _line
from zrp_ga.run.shared import Cache

SMALL = ["problem=multipose", "problem.n_poses=8", "problem.n_validation=6", "seed=3", "progress=false", "refine=none"]


def test_a_convergence_line_is_what_the_csv_writer_writes():
    """Python and numpy floats (repr of the float: every digit), ints, booleans, NaN and inf,
    missing columns and text that needs quotes, against ``csv.DictWriter`` with floats by repr."""
    row = {"gen": 7, "nevals": np.int64(350), "best": 0.1 + 0.2, "mean": np.float64(1 / 3), "median": np.float32(0.1),
           "std": float("nan"), "worst": float("inf"), "n_nonfinite": True, "val_rms_mm": None,
           "param_err": 'a "b", c', "eval_s": -1e-300, "bookkeeping_s": 5e-324}  # fmt: skip
    text = io.StringIO()
    csv.DictWriter(text, fieldnames=COLUMNS, restval="").writerow(
        {k: repr(float(v)) if isinstance(v, (float, np.floating)) else v for k, v in row.items()})  # fmt: skip
    assert _line(row) == text.getvalue()
    assert _line({}) == "," * (len(COLUMNS) - 1) + "\r\n"


def _entries(task, x) -> str:
    a = assessment.assess(task, x, 1e-3)
    return json.dumps({"entries": a.entries, "warnings": a.warnings, "worse": a.predicted_worse, "beyond": a.beyond},
                      sort_keys=True, default=repr)  # fmt: skip


@pytest.fixture(scope="module")
def tasks():
    """Two instances of one problem, built apart (the second assessed for the first time only
    in the test), and two genomes within its ranges."""
    one, two = (prepare(config.load(SMALL), None, cache=Cache()).task for _ in range(2))  # a cache each: two instances
    assert one is not two
    p = one.problem
    x1, x2 = (np.random.default_rng(s).uniform(p.lower, p.upper) * 0.5 for s in (0, 1))
    return one, two, x1, x2


def test_an_assessment_after_another_genomes_is_that_of_a_fresh_instance(tasks):
    one, two, x1, x2 = tasks
    assert one.setup is not None and one.setup.subspace is not None  # the identified entry's part at the result is tested
    first = _entries(one, x1)
    assert first != _entries(one, x2)  # the genomes' assessments differ
    assert _entries(one, x2) == _entries(two, x2)
    assert _entries(one, x1) == first


def test_an_assessment_entries_are_the_runs_own(tasks):
    """A run's summary that changes its entries does not change the next run's."""
    one, _, x1, x2 = tasks
    expected = _entries(one, x2)
    a = assessment.assess(one, x1, 1e-3)
    a.entries["coverage"]["gap"] = -1.0
    a.entries["identified"]["rank"] = -1
    a.entries["outliers"]["found"].append("planted")
    assert _entries(one, x2) == expected
