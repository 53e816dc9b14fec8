"""Benchmarking across instances as COCO and IOHprofiler do: reference floors, targets, hitting
times, expected running time (ERT), the fixed-target ECDF and fixed-budget values. The
definitions are in the package docstring (:mod:`zrp_ga.report`); runtime is in evaluations."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pandas as pd

from zrp_ga.report.common import BUDGETS, LEVELS, ROUND_OFF  # the command's defaults  # noqa: F401
from zrp_ga.report.runs import Run, number


@dataclasses.dataclass(frozen=True)
class TargetRule:
    """How targets are set: ``levels`` c (target c x f_ref per instance) or one ``absolute``
    cost for every instance; ``round_off``: a floor below round_off x nominal cost is round-off;
    ``tolerance``: final costs closer than ``tolerance`` x f_ref are the same result (default:
    the targets' resolution, the tightest level - 1: 0.01 with the default levels)."""

    levels: tuple[float, ...] = LEVELS
    absolute: float | None = None
    round_off: float = ROUND_OFF
    tolerance: float | None = None

    def resolution(self) -> float:
        """The tolerance, relative to f_ref."""
        if self.tolerance is not None:
            return float(self.tolerance)
        return float(min(self.levels) - 1.0) if self.levels and min(self.levels) > 1.0 else 0.01

    def names(self) -> list[str]:
        return [f"cost<={self.absolute:g}"] if self.absolute is not None else [f"{c:g}" for c in self.levels]

    def primary(self) -> str:
        """The level the single-target columns use: 1.05 when among the levels, else the tightest."""
        if self.absolute is not None:
            return self.names()[0]
        return "1.05" if 1.05 in self.levels else f"{min(self.levels):g}"


def floors(runs: list[Run], rule: TargetRule) -> pd.DataFrame:
    """One row per instance: its runs, nominal cost (median of the runs'), floor f* and where it
    comes from, whether it is at round-off level, the reference f_ref the targets scale and the
    targets, one column ``target_<level>`` per level.

    f* is summary.json's ``floor`` when the runs carry one (the lowest if they differ; then
    ``by_lm`` is True), else the lowest final cost among the runs (best known: the best run is at
    1 x f* by definition). f_ref = f*, except where f* < round_off x nominal cost: there f_ref =
    round_off x nominal cost. ``tolerance``: final costs closer than ``tolerance`` x f_ref are one
    result, the rule's resolution and at least the round-off floor (round_off x nominal cost).
    """
    rows = []
    for instance, group in _by_instance(runs).items():
        nominals = [v for v in (number(r.summary.get("nominal_cost")) for r in group) if math.isfinite(v)]
        nominal = float(np.median(nominals)) if nominals else math.nan
        fields = (r.summary.get("floor") for r in group)  # a number, or an object holding it as ``cost``
        given = [v for v in (number(f.get("cost") if isinstance(f, dict) else f) for f in fields) if math.isfinite(v)]
        finals = [r.final_cost for r in group if math.isfinite(r.final_cost)]
        if given:
            floor, source = min(given), "summary.json floor"
        elif finals:
            floor, source = min(finals), f"best known (lowest final cost of {len(group)} run{'s' * (len(group) > 1)})"
        else:
            floor, source = math.nan, "none: no run has a finite final cost"
        exact = bool(math.isfinite(floor) and math.isfinite(nominal) and nominal > 0 and floor < rule.round_off * nominal)
        reference = rule.round_off * nominal if exact else floor
        off = rule.round_off * nominal / reference if math.isfinite(nominal) and reference > 0 else 0.0
        row = dict(instance=instance, runs=len(group), nominal_cost=nominal, floor=floor, floor_source=source,
                   round_off=exact, reference=reference, by_lm=bool(given), tolerance=max(rule.resolution(), off))  # fmt: skip
        if rule.absolute is not None:
            row[f"target_{rule.names()[0]}"] = rule.absolute
        else:
            row.update({f"target_{c:g}": c * reference for c in rule.levels})
        rows.append(row)
    return pd.DataFrame(rows)


def _by_instance(runs: list[Run]) -> dict[str, list[Run]]:
    out: dict[str, list[Run]] = {}
    for r in runs:
        out.setdefault(r.instance, []).append(r)
    return out


def first_hit(evals: np.ndarray, best: np.ndarray, target: float) -> float:
    """Evaluations until the best-so-far cost first reaches ``target`` (<=); inf if never.

    >>> first_hit(np.array([10, 20, 30]), np.array([5.0, 2.0, 1.0]), 2.0)
    20.0
    """
    hit = np.flatnonzero(best <= target)
    return float(evals[hit[0]]) if hit.size and math.isfinite(target) else math.inf


def hits(runs: list[Run], labels: list[str], table: pd.DataFrame, rule: TargetRule) -> pd.DataFrame:
    """One row per (run, level): run, configuration, instance, level, target, ``hit`` (evaluations
    to reach it, inf if never) and ``nevals`` (the run's evaluations in all). Instances without a
    finite reference have no targets."""
    names = rule.names()
    per = {i: [float(v) for v in row] for i, row in zip(table["instance"], table[[f"target_{n}" for n in names]].to_numpy())}
    cols: dict[str, list] = {k: [] for k in ("run", "configuration", "instance", "level", "target", "hit", "nevals")}
    for r, label in zip(runs, labels):
        for level, target in zip(names, per[r.instance]):
            if math.isnan(target):
                continue
            for key, value in zip(cols.values(), (str(r.path), label, r.instance, level, target, first_hit(r.evals, r.best, target),
                                                  r.nevals)):  # fmt: skip
                key.append(value)
    if not cols["run"]:
        return pd.DataFrame(columns=list(cols))
    return pd.DataFrame(cols)


def ert(hits_: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Expected running time per group of ``by``: the evaluations of all runs (successful ones to
    their hit, the others in full) over the number of successful runs; inf when none succeeds.
    Also the runs, the successes and the success rate."""

    columns = [*by, "runs", "successes", "success_rate", "ert"]
    if not len(hits_):
        return pd.DataFrame(columns=columns)
    hit = hits_["hit"].to_numpy(dtype=float)
    ok = np.isfinite(hit)
    # the evaluations are whole numbers: their sums are exact in any order
    each = pd.DataFrame({"ok": ok.astype(np.int64), "spent": np.where(ok, hit, hits_["nevals"].to_numpy(dtype=float))})
    g = each.groupby([hits_[k] for k in by], sort=False)
    out = g.agg(runs=("ok", "size"), successes=("ok", "sum"), spent=("spent", "sum")).reset_index()
    out["runs"], out["successes"] = out["runs"].astype(np.int64), out["successes"].astype(np.int64)
    out["success_rate"] = out["successes"] / out["runs"]
    with np.errstate(divide="ignore", invalid="ignore"):
        out["ert"] = np.where(out["successes"] > 0, out["spent"] / out["successes"], math.inf)
    return out[columns]


def ecdf(hits_: pd.DataFrame, start: float = 1.0) -> pd.DataFrame:
    """The fixed-target ECDF per configuration, aggregated over (instance, level) pairs: at each
    budget b, the mean over the configuration's pairs of the share of its runs on that instance
    that hit the level's target within b evaluations (each pair weighs the same, however many
    runs it has). Rows (configuration, evaluations, fraction) at each step, from (``start``, 0)."""
    labels: list[Any] = []
    evaluations: list[np.ndarray] = []
    fractions: list[np.ndarray] = []
    if not len(hits_):
        return pd.DataFrame(columns=["configuration", "evaluations", "fraction"])
    code, names = pd.factorize(hits_["configuration"])  # the configurations in their first rows' order
    pair = hits_.groupby([hits_["configuration"], hits_["instance"], hits_["level"]], sort=False)["run"]
    runs_per_pair = pair.transform("size").to_numpy()
    n_pairs = np.bincount(code[np.unique(pair.ngroup().to_numpy(), return_index=True)[1]], minlength=len(names))
    weight = 1.0 / (n_pairs[code] * runs_per_pair)
    hit = hits_["hit"].to_numpy(dtype=float)
    ok = np.isfinite(hit)
    # each configuration's steps: the weights of its hits summed per evaluation count (in the rows' order)
    steps = pd.Series(weight[ok]).groupby([code[ok], hit[ok]]).sum()
    at = steps.index.get_level_values(0).to_numpy()
    where = np.searchsorted(at, np.arange(len(names) + 1))
    for k, label in enumerate(names):
        part = steps.iloc[where[k]:where[k + 1]]
        labels += [label] * (len(part) + 1)  # the starting point, then one row per step
        evaluations.append(np.r_[float(start), part.index.get_level_values(1).to_numpy(dtype=float)])
        fractions.append(np.r_[0.0, np.cumsum(part.to_numpy())])
    df = pd.DataFrame({"configuration": labels, "evaluations": np.concatenate(evaluations), "fraction": np.concatenate(fractions)})
    # a hit at evaluation 1 replaces the starting point
    return df.drop_duplicates(["configuration", "evaluations"], keep="last").reset_index(drop=True)


def ecdf_at(curve: pd.DataFrame, budget: float) -> float:
    """The ECDF ``curve`` of one configuration (rows of :func:`ecdf`) at ``budget`` evaluations."""
    before = curve[curve["evaluations"] <= budget]
    return float(before["fraction"].iloc[-1]) if len(before) else 0.0


def best_at(evals: np.ndarray, best: np.ndarray, budget: float) -> float:
    """The best cost within ``budget`` evaluations (a run that stopped earlier: its final best).

    >>> best_at(np.array([1, 20, 40]), np.array([9.0, 5.0, 3.0]), 30)
    5.0
    """
    i = np.searchsorted(evals, budget, side="right") - 1
    return float(best[i]) if i >= 0 else math.nan


BUDGET_STOPS = ("generations", "max_evals", "maxfevals", "samples", "maximum number of function evaluations", "maxiter")


def stopped_by_budget(run: Run) -> bool:
    """Whether the run stopped because its budget ran out (generations, evaluations) rather than
    by itself (converged): then its best beyond its evaluations is unknown. Unknown: budget."""
    reason = str(run.summary.get("stop_reason") or "").lower()
    return not reason or any(s in reason for s in BUDGET_STOPS)


def default_budgets(runs: list[Run]) -> tuple[int, ...]:
    """Budgets the runs made: 100, 1,000, ... up to the most evaluations a run made, and that count."""
    top = max((r.nevals for r in runs), default=0)
    decades = [10**k for k in range(2, 12) if 10**k < top]
    return tuple(decades + [top]) if top > 0 else ()


def fixed_budget(runs: list[Run], labels: list[str], table: pd.DataFrame, budgets: tuple[int, ...]) -> pd.DataFrame:
    """Per configuration, instance and budget: the runs and the median over them of (best cost
    within the budget) / f_ref; NaN (no number) where a run stopped by its own budget before
    it (a run that stopped by itself, converged, keeps its final best)."""
    reference = dict(zip(table["instance"], table["reference"].astype(float)))
    keys: dict[tuple[str, str, int], list[float]] = {}  # (configuration, instance, budget): the runs' ratios, in order
    for r, label in zip(runs, labels):
        ref = reference[r.instance]
        cut = stopped_by_budget(r)
        for b in budgets:
            value = best_at(r.evals, r.best, b) if (b <= r.nevals or not cut) else math.nan
            keys.setdefault((label, r.instance, b), []).append(value / ref if ref > 0 else math.nan)
    columns = ["configuration", "instance", "budget", "runs", "median_cost_over_ref"]
    if not keys:
        return pd.DataFrame(columns=columns)
    rows = [(c, i, b, len(v), float(np.median(v)) if not any(map(math.isnan, v)) else math.nan) for (c, i, b), v in keys.items()]
    out = pd.DataFrame(rows, columns=columns)
    out["budget"] = out["budget"].astype(np.int64)
    return out


ECDF_TARGETS = 51  # as many as COCO's (five per decade over ten decades there)


def dimension(run: Run) -> int:
    """The genome's length, from summary.json's ``best_genome`` (0 when it is missing)."""
    genome = run.summary.get("best_genome")
    return len(genome) if isinstance(genome, (dict, list)) else 0


def ecdf_targets(runs: list[Run], table: pd.DataFrame, n: int = ECDF_TARGETS, tightest: float = 1.01) -> dict[str, np.ndarray]:
    """The runtime ECDF's targets per instance, as COCO sets them above the optimum: ``n``
    targets f_ref + d_k, the excesses d_k log-spaced from d_0 = f0 - f_ref (f0 the instance's
    starting cost: the median over its runs of the cost of the first evaluation) down to
    d_{n-1} = (``tightest`` - 1) f_ref, so that the last target is the tightest headline level
    (1.01 x f_ref). None for an instance whose f0 or f_ref is not finite, or f0 <= ``tightest``
    x f_ref."""
    reference = table.set_index("instance")["reference"]
    out = {}
    for instance, group in _by_instance(runs).items():
        f0 = float(np.median([r.best[0] for r in group]))
        ref = float(reference.loc[instance])
        if math.isfinite(f0) and math.isfinite(ref) and ref > 0 and f0 > tightest * ref:
            out[instance] = ref + np.geomspace(f0 - ref, (tightest - 1) * ref, n)
    return out


def runtime_hits(runs: list[Run], labels: list[str], targets_: dict[str, np.ndarray]) -> pd.DataFrame:
    """One row per (run, ECDF target): as :func:`hits` (``level`` the target's number k) with
    ``hit`` and ``nevals`` divided by the run's genome length (evaluations per gene, as COCO
    divides by the dimension; by 1 when the length is unknown)."""
    cols: dict[str, list] = {k: [] for k in ("run", "configuration", "instance", "level", "target", "hit", "nevals")}
    for r, label in zip(runs, labels):
        if r.instance not in targets_:
            continue
        dim = max(dimension(r), 1)
        tg = targets_[r.instance]
        at = np.searchsorted(-r.best, -tg, side="left")  # the first index where best <= target (best non-increasing)
        hit = np.where(at < len(r.best), r.evals[np.minimum(at, len(r.evals) - 1)], np.inf) / dim
        n = len(tg)
        for key, value in (("run", str(r.path)), ("configuration", label), ("instance", r.instance)):
            cols[key] += [value] * n
        cols["level"] += [f"t{k:02d}" for k in range(n)]
        cols["target"].append(np.asarray(tg, dtype=float))
        cols["hit"].append(np.asarray(hit, dtype=float))
        cols["nevals"].append(np.full(n, r.nevals / dim))
    if not cols["run"]:
        return pd.DataFrame(columns=list(cols))
    return pd.DataFrame({k: np.concatenate(v) if k in ("target", "hit", "nevals") else v for k, v in cols.items()})
