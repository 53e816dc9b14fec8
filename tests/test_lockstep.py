"""Runs evolved together (lockstep) write exactly what each writes alone.

A batch mixes operator families (every crossover, mutation, inversion, rotation and selection
of zrp_ga), survival strategies, budgets (generations, evaluations), stop criteria (target
cost, stagnation: runs that stop early leave the batch) and the pseudo-inverse step. Each run
of the batch is compared with the same job run alone, through the run layer, file by file: its
convergence.csv in every non-timing column, its summary.json but for timing, its checkpoint's
arrays and random states, and its other files byte for byte.
"""

from __future__ import annotations

import csv
import json
import random
from pathlib import Path

import numpy as np
import pytest

from zrp_ga import config
from zrp_ga.operators.base import Streams
from zrp_ga.run import directory
from zrp_ga.run.callbacks import WALL_CLOCK_COLUMNS
from zrp_ga.run.directory import Sweep
from zrp_ga.run.shared import Cache
from zrp_ga.run.sweep import SweepJob, batch_key, sweep_batch, sweep_job

BASE = ["problem=multipose", "problem.n_poses=8", "problem.n_validation=6", "seed=3", "progress=false",
        "population.mu=12", "population.lambda_=16", "checkpoint_every=4", "outputs=full"]  # fmt: skip
MIXED = [
    ["crossover=sbx", "mutation=gaussian", "inversion=segment", "rotation=segment", "refine=none", "population.generations=9"],
    ["crossover=blend", "mutation=polynomial", "inversion=block", "rotation=none", "refine=none", "population.generations=12"],
    ["crossover=one_point", "mutation=uniform_reset", "inversion=none", "rotation=block", "refine=none",
     "population.generations=null", "population.max_evals=150"],
    ["crossover=two_point", "mutation=gaussian", "selection=truncation", "refine=none", "population.generations=7",
     "algorithm.strategy=mu_comma_lambda"],
    ["crossover=uniform", "mutation=polynomial", "selection=random", "refine=none", "population.generations=10",
     "algorithm.strategy=generational", "algorithm.elite=2"],
    ["crossover=sbx", "mutation=gaussian", "inversion=segment", "rotation=segment", "refine=pinv", "refine.share=0.25",
     "population.generations=5"],
    ["crossover=sbx", "mutation=gaussian", "refine=none", "population.generations=40", "+algorithm.stagnation=2"],
    ["crossover=blend", "mutation=gaussian", "refine=none", "population.generations=30", "+algorithm.target_cost=1.0"],
    ["crossover=sbx", "mutation=gaussian", "inversion=segment", "rotation=segment", "refine=none", "population.generations=9",
     "mutation.op.sigma=0.3"],
    # about one changed child a generation: its cost computed as for one genome alone
    ["crossover=none", "mutation=gaussian", "mutation.prob=0.07", "inversion=none", "rotation=none", "refine=none",
     "population.generations=12"],
]  # fmt: skip


def _jobs(where: Path, lines: list[list[str]]) -> list[SweepJob]:
    return [SweepJob(config.load([*BASE, *extra]), where / str(k), Sweep(where, k, tuple(extra), str(k)))
            for k, extra in enumerate(lines)]  # fmt: skip


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k not in WALL_CLOCK_COLUMNS} for row in csv.DictReader(f)]


def _summary(path: Path) -> dict:
    s = json.loads(path.read_text())
    for key in ("wall_s", "time", "started", "ended", "versions", "eval_s", "bookkeeping_s"):
        s.pop(key, None)
    return s


def _checkpoint(path: Path) -> dict:
    with np.load(path) as data:
        state = {k: data[k] for k in data.files}
    meta = json.loads(str(state.pop("__json__")))
    meta.pop("wall_s")
    return {**state, "__json__": meta}


def _same_run(a: Path, b: Path) -> None:
    assert (a / directory.CONVERGENCE).read_bytes().count(b"\r\n") == (b / directory.CONVERGENCE).read_bytes().count(b"\r\n")
    assert _rows(a / directory.CONVERGENCE) == _rows(b / directory.CONVERGENCE), a.name
    assert _summary(a / directory.SUMMARY) == _summary(b / directory.SUMMARY), a.name
    ca, cb = _checkpoint(a / directory.CHECKPOINT), _checkpoint(b / directory.CHECKPOINT)
    assert ca.keys() == cb.keys()
    for k in ca:
        if isinstance(ca[k], np.ndarray):
            np.testing.assert_array_equal(ca[k], cb[k], err_msg=f"{a.name}: checkpoint {k}")
        else:
            assert ca[k] == cb[k], f"{a.name}: checkpoint {k}"
    skip = {directory.CONVERGENCE, directory.SUMMARY, directory.CHECKPOINT, directory.LOCK}
    files = sorted(f.name for f in a.iterdir() if f.is_file() and f.name not in skip)
    assert files == sorted(f.name for f in b.iterdir() if f.is_file() and f.name not in skip)
    for name in files:
        assert (a / name).read_bytes() == (b / name).read_bytes(), f"{a.name}/{name}"


@pytest.fixture(scope="module")
def batch_and_alone(tmp_path_factory):
    together, alone = tmp_path_factory.mktemp("together"), tmp_path_factory.mktemp("alone")
    cache = Cache()
    jobs = _jobs(together, MIXED)
    assert len({batch_key(job.cfg) for job in jobs}) == 1  # one batch
    values = sweep_batch(jobs, cache)
    singles = [sweep_job(job, cache) for job in _jobs(alone, MIXED)]
    return together, alone, values, singles


def test_every_run_of_a_mixed_batch_writes_what_it_writes_alone(batch_and_alone):
    together, alone, values, singles = batch_and_alone
    assert not [v for v in values if isinstance(v, Exception)], values
    assert values == singles
    for k in range(len(MIXED)):
        _same_run(together / str(k), alone / str(k))


def test_the_batch_mixes_budgets_and_stops(batch_and_alone):
    together = batch_and_alone[0]
    reasons = {json.loads((together / str(k) / directory.SUMMARY).read_text())["stop_reason"] for k in range(len(MIXED))}
    gens = {len(_rows(together / str(k) / directory.CONVERGENCE)) for k in range(len(MIXED))}
    assert {"generations", "max_evals", "stagnation", "target_cost"} <= reasons
    assert len(gens) >= 5  # runs left the batch at different generations
    nevals = [int(r["nevals"]) for r in _rows(together / str(len(MIXED) - 1) / directory.CONVERGENCE)]
    assert 1 in np.diff(nevals)  # a generation with one changed child
    states = [r["status"] for r in directory.job_states(together)]
    assert states == ["done"] * len(MIXED)


def test_streams_draw_each_runs_numbers_from_its_own_generator():
    """An operator applied once to the rows of three runs gives each run the rows it gets alone."""
    from zrp_ga.operators import crossover, inversion, mutation, rotation, selection

    K, counts = 7, [3, 1, 4]
    low, up = -np.ones(K), np.ones(K)
    blocks = [(0, 3), (3, 7)]
    rows = np.random.default_rng(0).uniform(-1, 1, size=(sum(counts), K))
    ops = [
        (crossover.sbx, dict(low=low, up=up)), (crossover.blend, {}), (crossover.one_point, {}), (crossover.two_point, {}),
        (crossover.uniform, {}), (mutation.gaussian, dict(low=low, up=up)), (mutation.polynomial, dict(low=low, up=up)),
        (mutation.uniform_reset, dict(low=low, up=up)), (inversion.segment, {}), (inversion.block, dict(blocks=blocks)),
        (rotation.segment, {}), (rotation.block, dict(blocks=blocks)),
    ]  # fmt: skip
    ends = np.cumsum(counts)
    for op, params in ops:
        two = op.__module__.endswith("crossover")
        joined = [rows.copy(), rows[::-1].copy()] if two else [rows.copy()]
        op(*joined, rng=Streams([np.random.default_rng(s) for s in range(3)], counts), **params)
        for s, (a, b) in enumerate(zip(ends - counts, ends)):
            own = [rows[a:b].copy(), rows[::-1][a:b].copy()] if two else [rows[a:b].copy()]
            op(*own, rng=np.random.default_rng(s), **params)
            for x, y in zip(own, joined):
                np.testing.assert_array_equal(x, y[a:b], err_msg=op.__qualname__)
    costs = np.random.default_rng(1).random((3, 10))
    for op, params in [(selection.tournament, {}), (selection.truncation, {}), (selection.random, {})]:
        picked = op(costs, sum(counts), rng=Streams([np.random.default_rng(s) for s in range(3)], counts), **params)
        for s, (a, b) in enumerate(zip(ends - counts, ends)):
            np.testing.assert_array_equal(picked[a:b], op(costs[s], counts[s], rng=np.random.default_rng(s), **params))
    random.seed(0)


@pytest.mark.slow  # 4-12 s: out of the default run for its time (pytest -m slow runs it)
def test_calibrate_over_many_seeds_gives_each_seeds_calibration(tmp_path):
    """``zrp_ga.calibrate(seed=[...])`` on measured data evolves the seeds together; each
    calibration is the one ``seed=s`` alone gives, and each run's files go to ``out/seed_S``."""
    import zrp_ga
    from zrp_ga import robots
    from zrp_ga.model import kinematics

    arm = robots.load("puma560")
    q = np.random.default_rng(1).uniform(-1, 1, (50, 6))
    p = kinematics.forward(arm, q)[1] + np.random.default_rng(2).normal(0, 1e-4, (50, 3))
    kw = dict(validation=(q[40:], p[40:]), population={"mu": 12, "lambda_": 12, "generations": 8}, refine="none",
              problem={"length_unit": "m", "angle_unit": "rad"})  # fmt: skip
    many = zrp_ga.calibrate(arm, (q[:40], p[:40]), seed=[0, 5, 9], out=tmp_path / "many", **kw)
    for seed, cal in zip([0, 5, 9], many):
        alone = zrp_ga.calibrate(arm, (q[:40], p[:40]), seed=seed, **kw)
        keep = [c for c in alone.history.columns if c not in WALL_CLOCK_COLUMNS]
        assert cal.history[keep].equals(alone.history[keep])
        assert cal.summary["seed"] == seed and _rows(tmp_path / "many" / f"seed_{seed}" / directory.CONVERGENCE)
    assert not many[0].history["best"].equals(many[1].history["best"])  # the seeds differ
    with pytest.raises(ValueError, match="distinct seeds"):
        zrp_ga.calibrate(arm, (q[:40], p[:40]), seed=[1, 1], **kw)


def test_an_interrupted_batch_continues_to_the_files_of_an_uninterrupted_one(batch_and_alone, tmp_path, monkeypatch):
    """Ctrl-C in the middle of a batch: every unfinished run saves its checkpoint and its rows
    up to it and is recorded interrupted; the same jobs run again continue from there to the
    files the uninterrupted batch wrote."""
    from zrp_ga.run import callbacks

    together = batch_and_alone[0]
    original = callbacks.Checkpoint.on_generation

    def interrupted(self, algorithm, row):
        if algorithm.gen == 6 and "/3/" in str(self.path):
            raise KeyboardInterrupt
        original(self, algorithm, row)

    monkeypatch.setattr(callbacks.Checkpoint, "on_generation", interrupted)
    cache = Cache()
    with pytest.raises(KeyboardInterrupt):
        sweep_batch(_jobs(tmp_path, MIXED), cache)
    states = {r["job"]: r["status"] for r in directory.job_states(tmp_path)}
    assert "interrupted" in states.values()
    for k, state in states.items():
        if state == "interrupted":
            saved = _checkpoint(tmp_path / str(k) / directory.CHECKPOINT)["__json__"]["gen"]
            assert int(_rows(tmp_path / str(k) / directory.CONVERGENCE)[-1]["gen"]) >= saved  # the rows reach the checkpoint
    monkeypatch.setattr(callbacks.Checkpoint, "on_generation", original)
    values = sweep_batch(_jobs(tmp_path, MIXED), cache)
    assert not [v for v in values if isinstance(v, Exception)]
    for k in range(len(MIXED)):
        _same_run(tmp_path / str(k), together / str(k))
    assert [r["status"] for r in directory.job_states(tmp_path)] == ["done"] * len(MIXED)


def test_a_batch_runs_a_job_that_cannot_be_evolved_together_alone(tmp_path):
    """sweep_batch takes any job: one of an optimiser other than the GA (Levenberg-Marquardt)
    runs alone, to the objective sweep_job gives it in another directory."""
    lines = [["algorithm=lm"]]
    (value,) = sweep_batch(_jobs(tmp_path / "batch", lines), Cache())
    assert value == sweep_job(_jobs(tmp_path / "job", lines)[0], Cache())
    assert directory.job_states(tmp_path / "batch")[0]["status"] == "done"
