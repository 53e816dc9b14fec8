"""Model choice that cannot fool its user (``problem.model``; docs/model.md, "Beyond geometry").

The **candidates** are fixed before any validation number is computed (:func:`candidates`): the
geometric model, the geometric model with the non-geometric terms of a ``problem.terms`` value
(:mod:`zrp_ga.model.terms`), each optionally with a Gaussian-process residual model on joint
space (:mod:`zrp_ga.model.residual`), in this order (simplest first).

Each candidate is judged by **cross-validation on the calibration data only**: in every fold the
whole calibration runs again on the other folds' poses (registration, the identified genome,
Levenberg-Marquardt on the geometry and the candidate's terms, then the residual model on the
fit's residuals), and the held-out poses' position errors are pooled into one RMS per candidate.

The **fold scheme** follows the targets (the validation poses, or a program's joint values):
:func:`folds` makes ``K`` random folds when the targets lie within the calibration's joint ranges;
when more than :data:`OUTSIDE_SHARE` of them lie beyond a joint's range, one fold per joint end
the targets go beyond, each holding out the calibration poses in that end's extreme
:data:`EXTREME` of the joint's range (random folds stay inside the ranges and reward models
that extrapolate badly), and a one-line warning says that the choice judges extrapolation.

The **choice** (:func:`choose`): the lowest cross-validated RMS; a simpler candidate (earlier in
the order) within :data:`TOLERANCE` of it is preferred. The validation data are used once, after
the choice, by the run's judge; nothing here reads their measured points (only their joint
values, to pick the fold scheme).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zrp_ga.model import metrics
from zrp_ga.model.coverage import Coverage
from zrp_ga.model.poses import Measurements
from zrp_ga.model.residual import Residual

Array = NDArray[np.float64]
log = logging.getLogger(__name__)
K_FOLDS = 5
EXTREME = 0.2  # an extreme-range fold holds out this share of the joint's range at one end
OUTSIDE_SHARE = 0.05  # targets beyond a joint end: more than this share of them makes it a fold
MIN_HELD = 0.03  # an extreme fold holds at least this share of the poses (else the extreme 20% of the poses by value)
TOLERANCE = 0.02  # a simpler candidate within 2% of the best cross-validated RMS is chosen
GP_SUFFIX = "+gp"
NAMES = ("geometric", "geometric+gp", "terms", "terms+gp")


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A model to choose among: its ``name``, the ``problem.terms`` value it fits with the
    geometry (None: the geometric model) and whether a Gaussian-process ``residual`` is added."""

    name: str
    terms: Any = None
    residual: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "terms": _plain(self.terms), "residual": self.residual}


def _plain(v: Any) -> Any:
    if hasattr(v, "items"):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def candidates(model: Any, terms: Any = None) -> list[Candidate]:
    """The candidates of ``problem.model`` (module docstring), in their fixed order:
    ``geometric`` (one candidate: today's model, no choice), ``auto`` (geometric,
    geometric+gp, and with ``problem.terms`` set: terms, terms+gp), or a list of those names;
    a list item may also be a mapping ``{name: ..., terms: {...}, gp: true|false}`` (a candidate
    with its own terms). Bad names: one line naming the setting."""
    if model is None or model == "geometric":
        return [Candidate("geometric")]
    names: list[Any]
    if model == "auto":
        names = list(NAMES) if terms else list(NAMES[:2])
    elif isinstance(model, str):
        raise ValueError(f"problem.model: {model!r}; expected auto, geometric or a list of {', '.join(NAMES)}")
    else:
        names = list(model)
    if not names:
        raise ValueError("problem.model: an empty list; name at least one candidate")
    out: list[Candidate] = []
    for item in names:
        if hasattr(item, "items"):
            bad = set(item) - {"name", "terms", "gp"}
            if bad or "name" not in item:
                raise ValueError(f"problem.model: a candidate mapping has keys name, terms, gp; got {sorted(map(str, item))}")
            out.append(Candidate(str(item["name"]), item.get("terms"), bool(item.get("gp", False))))
            continue
        name = str(item).strip()
        if name not in NAMES:
            raise ValueError(f"problem.model: unknown candidate {name!r}; expected {', '.join(NAMES)}")
        if name.startswith("terms") and not terms:
            raise ValueError(f"problem.model: candidate {name!r} needs problem.terms (the terms it fits)")
        out.append(Candidate(name, terms if name.startswith("terms") else None, name.endswith(GP_SUFFIX)))
    if len({c.name for c in out}) != len(out):
        raise ValueError(f"problem.model: candidates named twice: {[c.name for c in out]}")
    return out


@dataclasses.dataclass(frozen=True)
class Folds:
    """Held-out rows of each fold (index arrays into the calibration poses), their names, the
    scheme (``random`` or ``extremes``) and the warning an extrapolating choice carries."""

    held: list[NDArray[np.int64]]
    names: list[str]
    scheme: str
    warning: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"scheme": self.scheme, "folds": [{"name": n, "held_out": len(h)} for n, h in zip(self.names, self.held)],
                **({"warning": self.warning} if self.warning else {})}  # fmt: skip


def folds(q: Array, targets: Array | None = None, k: int = K_FOLDS, seed: int = 0) -> Folds:
    """The fold scheme for calibration poses ``q`` (M, n) and ``targets`` (T, n) joint values
    (None: random folds) (module docstring)."""
    q = np.asarray(q, dtype=float)
    ends = [] if targets is None or not len(targets) else beyond_ends(q, np.asarray(targets, dtype=float))
    if not ends:
        order = np.random.default_rng([seed, 30]).permutation(len(q))
        held = [np.sort(part) for part in np.array_split(order, k)]
        return Folds(held, [f"random {i + 1}/{k}" for i in range(k)], "random")
    lo, hi = q.min(axis=0), q.max(axis=0)
    held, names = [], []
    for j, end, share in ends:
        width = hi[j] - lo[j]
        rows = (
            np.flatnonzero(q[:, j] <= lo[j] + EXTREME * width)
            if end == "low"
            else np.flatnonzero(q[:, j] >= hi[j] - EXTREME * width)
        )
        if len(rows) < MIN_HELD * len(q):  # a thin tail: the extreme 20% of the poses by value
            cut = np.quantile(q[:, j], EXTREME if end == "low" else 1 - EXTREME)
            rows = np.flatnonzero(q[:, j] <= cut) if end == "low" else np.flatnonzero(q[:, j] >= cut)
        if len(rows) < len(q):
            held.append(rows)
            names.append(f"joint {j + 1} {end} {EXTREME:.0%} (targets beyond: {share:.0%})")
    listed = ", ".join(f"joint {j + 1} {end}" for j, end, _ in ends)
    warning = (f"model choice: the targets lie beyond the calibration poses' joint ranges ({listed}); the cross-validation "
               "holds out those joints' extreme ranges, and its figures judge extrapolation")  # fmt: skip
    return Folds(held, names, "extremes", warning)


def beyond_ends(q: Array, targets: Array) -> list[tuple[int, str, float]]:
    """The joint ends (joint index, ``low``/``high``, share of targets beyond) that more than
    :data:`OUTSIDE_SHARE` of the ``targets`` lie beyond, by more than 1% of the joint's range."""
    region = Coverage(q)
    lo, hi = region.lower, region.upper
    slack = 0.01 * np.maximum(hi - lo, 1e-9)
    out = []
    for j in range(q.shape[1]):
        for end, share in (
            ("low", np.mean(targets[:, j] < lo[j] - slack[j])),
            ("high", np.mean(targets[:, j] > hi[j] + slack[j])),
        ):
            if share > OUTSIDE_SHARE:
                out.append((j, end, float(share)))
    return out


@dataclasses.dataclass
class Fitted:
    """A candidate fitted on some poses: its task (the parametric model), genome and residual
    model (None without)."""

    task: Any
    x: Array
    residual: Residual | None = None

    def predict(self, data: Measurements) -> Array:
        """Predicted positions (M, 3) m at ``data``'s poses (instrument frame)."""
        p = self.task.problem
        out = metrics.predicted_positions(p.layout, p.nominal, self.x, data)[0]
        return out if self.residual is None else out + self.residual.predict(data.q)


Fit = Callable[[Measurements, Any], tuple[Any, Array]]  # (poses, terms) -> (task, genome)


def fit_candidate(fit: Fit, data: Measurements, candidate: Candidate, parametric: tuple[Any, Array] | None = None) -> Fitted:
    """``candidate`` fitted on ``data``: ``fit`` (the parametric model; or ``parametric``, a fit
    of the same terms already made), then the residual model on its residuals."""
    task, x = parametric if parametric is not None else fit(data, candidate.terms)
    fitted = Fitted(task, x)
    if candidate.residual:
        fitted.residual = residual_model(task, x, data)
    return fitted


def residual_model(task: Any, x: Array, data: Measurements) -> Residual:
    """The Gaussian process on the position residuals of genome ``x`` of ``task`` at ``data``'s
    poses (one tool point: the process is on joint space only)."""
    if len(np.unique(data.tools)) > 1:
        raise ValueError("problem.model: a residual model (+gp) takes data of one tool point; these measure several")
    p = task.problem
    r = data.p - metrics.predicted_positions(p.layout, p.nominal, x, data)[0]
    return Residual.fit(data.q, r)


def cross_validate(fit: Fit, data: Measurements, cands: Sequence[Candidate], scheme: Folds,
                   progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:  # fmt: skip
    """Every candidate's cross-validated position error (mm) over the folds of ``scheme``:
    pooled RMS, each fold's RMS, the calibration RMS of the fits (module docstring). The
    parametric fit of a fold is shared by the candidates that differ only by the residual."""
    errors: dict[str, list[Array]] = {c.name: [] for c in cands}
    fit_rms: dict[str, list[float]] = {c.name: [] for c in cands}
    for held, fold_name in zip(scheme.held, scheme.names):
        mask = np.zeros(data.M, dtype=bool)
        mask[held] = True
        train, test = data.subset(~mask), data.subset(mask)
        shared: dict[str, tuple[Any, Array]] = {}
        for c in cands:
            key = repr(_plain(c.terms))
            if key not in shared:
                shared[key] = fit(train, c.terms)
            f = fit_candidate(fit, train, c, shared[key])
            errors[c.name].append(np.linalg.norm(test.p - f.predict(test), axis=1))
            fit_rms[c.name].append(_rms(np.linalg.norm(train.p - f.predict(train), axis=1)))
            if progress is not None:
                progress(f"{fold_name}: {c.name} {_rms(errors[c.name][-1]) * 1e3:.4g} mm")
    return [{"name": c.name, "terms": _plain(c.terms), "residual": c.residual,
             "cv_rms_mm": _rms(np.concatenate(errors[c.name])) * 1e3,
             "fold_rms_mm": [_rms(e) * 1e3 for e in errors[c.name]],
             "fit_rms_mm": float(np.mean(fit_rms[c.name])) * 1e3} for c in cands]  # fmt: skip


def _rms(e: Array) -> float:
    return float(np.sqrt(np.mean(np.square(e)))) if len(e) else float("nan")


def choose(table: list[dict[str, Any]]) -> tuple[int, str]:
    """The chosen row of a :func:`cross_validate` table and why (module docstring)."""
    cv = np.array([row["cv_rms_mm"] for row in table], dtype=float)
    cv = np.where(np.isfinite(cv), cv, np.inf)
    best = int(np.argmin(cv))
    chosen = int(np.flatnonzero(cv <= cv[best] * (1 + TOLERANCE))[0])
    why = f"lowest cross-validated RMS ({cv[best]:.4g} mm)"
    if chosen != best:
        why = (f"the simplest candidate within {TOLERANCE:.0%} of the lowest cross-validated RMS ({table[best]['name']}, "
               f"{cv[best]:.4g} mm): {cv[chosen]:.4g} mm")  # fmt: skip
    elif len(table) > 1:
        rest = sorted(cv[np.arange(len(cv)) != best])
        why += f"; the next is {rest[0]:.4g} mm"
    return chosen, why


@dataclasses.dataclass
class Choice:
    """What :func:`select` found: the candidates, the fold scheme, the CV table, the chosen
    candidate and why."""

    candidates: list[Candidate]
    scheme: Folds
    table: list[dict[str, Any]]
    chosen: int
    why: str

    @property
    def candidate(self) -> Candidate:
        return self.candidates[self.chosen]

    def to_dict(self) -> dict[str, Any]:
        return {"candidates": [c.to_dict() for c in self.candidates], "folds": self.scheme.to_dict(),
                "cross_validation": self.table, "chosen": self.candidate.name, "why": self.why,
                "refit": "Levenberg-Marquardt per fold (registration and identified genome again)"}  # fmt: skip


def select(fit: Fit, data: Measurements, cands: Sequence[Candidate], targets: Array | None, k: int = K_FOLDS, seed: int = 0,
           progress: Callable[[str], None] | None = None) -> Choice:  # fmt: skip
    """Choose among ``cands`` by cross-validation on ``data`` (the calibration poses) with the
    fold scheme ``targets`` (joint values, (T, n), or None) call for (module docstring); one
    candidate: no cross-validation."""
    cands = list(cands)
    scheme = folds(data.q, targets, k, seed)
    if len(cands) == 1:
        return Choice(cands, scheme, [], 0, "the only candidate (problem.model)")
    table = cross_validate(fit, data, cands, scheme, progress)
    chosen, why = choose(table)
    return Choice(cands, scheme, table, chosen, why)
