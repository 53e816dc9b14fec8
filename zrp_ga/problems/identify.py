"""What a calibration problem passes before an optimiser sees it (docs/model.md, section 3.2):

1. a first fit, Levenberg-Marquardt within the directions the calibration poses see at all at
   the nominal arm (:func:`zrp_ga.model.subspace.identify` without a noise estimate);
2. the noise: the instrument's standard deviations where the data give them (``sx, sy, sz``),
   else the first fit's residual, ``s_g^2 = |r_g|^2 / (n_g (1 - r / n))`` per group of rows
   (positions, orientations), with the median absolute deviation
   (``1.4826 median |r_g|``, same correction) for a robust fit and for finding outliers;
3. outliers: points whose standardised residual ``d^2 = sum (r / sigma)^2`` over their rows is
   beyond the chi-square quantile ``1 - 0.01 / M`` (M points: one false alarm in a hundred
   clean data sets), named by file and line with their size; ``problem.outliers=drop`` fits
   again without them and records what changed;
4. a robust cost (``problem.loss``, :mod:`zrp_ga.problems.robust`) with ``problem.loss_scale``
   (default 1.345 x the robust noise of the last fit, Huber's constant (95% efficiency on
   normal noise): the least-squares fit's, then each robust fit's, until the scale changes by less than
   10%, at most ten robust fits: the first scale is inflated by the outliers); the outliers
   are found on the robust fit's residual;
5. the genome restricted to the combinations the data identify at the first fit's point
   (``problem.subspace=identified``, the default; :func:`zrp_ga.model.subspace.identify` with
   the noise), with gene ranges mapped into it (:func:`zrp_ga.model.subspace.half_widths`);
   its axes only turn, and the unit-length rows are left out of its cost (``unit_weight=0``:
   they would measure ``|du0|^2 / 2``, a bias; the model normalises the axes).

The expected errors ``prior`` are each gene's range over ``search_scale``.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.schema import Loss, Outliers, ProblemConf
from zrp_ga.core.schema import Subspace as SubspaceChoice
from zrp_ga.model import subspace as sub
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.problems.least_squares import levenberg_marquardt
from zrp_ga.problems.robust import RobustProblem

if TYPE_CHECKING:
    from zrp_ga.model.uncertainty import Uncertainty

Array = NDArray[np.float64]
OUTLIER_ALPHA = 0.01  # chance of naming any point of a clean data set
MAD = 1.4826  # median absolute deviation -> standard deviation, normal noise
ROUND_OFF_M = 1e-9  # a point off by less than this is never an outlier (noise-free data: the residual is round-off)
LOSS_SCALE = 1.345  # default problem.loss_scale, in robust noise (3: validation up to 1.17 x the clean fit's, experiments/outliers.py)
CONSISTENT = 0.01  # the instrument's deviations describe a residual whose chi^2 is below its 1 - this quantile
ROBUST_ROUNDS = 10  # robust fits at most, each with the scale from the last one's residual


@dataclasses.dataclass
class Noise:
    """The noise of the weighted pose rows: ``row_sigma`` (rows,) (None: unknown, no residual
    degrees of freedom), per group (``position``, ``orientation``; m on the weighted rows) the
    least-squares and the robust (MAD) estimate, where it comes from (``instrument``: the data's
    standard deviations, ``residual``, ``none``), the residual degrees of freedom and, with the
    instrument's deviations, the position rows' chi^2 per degree of freedom."""

    row_sigma: Array | None
    sigma: dict[str, float]
    robust: dict[str, float]
    source: str
    dof: int
    chi2_dof: float | None = None  # of the position rows under the instrument's standard deviations

    def to_dict(self) -> dict[str, Any]:
        mm = lambda d: {k: v * 1e3 for k, v in d.items()}
        return {"sigma_mm": mm(self.sigma), "robust_sigma_mm": mm(self.robust), "source": self.source, "dof": self.dof,
                "chi2_dof": self.chi2_dof}  # fmt: skip


FirstFit = tuple[Array, float, int, int, Noise]  # a first fit's genome, cost, evaluations, directions and noise (_fit)


@dataclasses.dataclass
class Setup:
    """What :func:`prepare` found (module docstring): the problem's genome before the
    restriction (``layout``) and its expected errors ``prior``; the identified subspace (None:
    ``problem.subspace=full``) and the directions the poses see at all at the nominal arm
    (``exact_rank``); the first fit's genome ``x`` (``layout``'s) and cost; the noise; the
    outliers (row, file, line, size m, d^2) and whether they were dropped, and what changed."""

    layout: Layout
    prior: Array
    subspace: sub.Subspace | None
    exact_rank: int
    x: Array
    cost: float
    nevals: int
    noise: Noise
    outliers: list[dict] = dataclasses.field(default_factory=list)
    dropped: bool = False
    change: dict = dataclasses.field(default_factory=dict)
    loss_scale: float | None = None
    problem: CalibrationProblem | None = None  # the problem before the restriction (``layout``'s genome)


class _Within:
    """A least-squares problem on the genomes ``x = N z`` of ``problem`` (z (r,)): what
    :func:`levenberg_marquardt` asks for, the robust loss included."""

    def __init__(self, problem: CalibrationProblem, N: Array) -> None:
        self.p, self.N = problem, N
        self.lower, self.upper = np.full(N.shape[1], -np.inf), np.full(N.shape[1], np.inf)
        self.names = [f"z{k + 1}" for k in range(N.shape[1])]  # the directions' coefficients
        self.n_rows = problem.n_rows
        if isinstance(problem, RobustProblem):
            self.loss, self.loss_scale = problem.loss, problem.loss_scale
            self.plain_residual = lambda z: problem.plain_residual(N @ z)
            self.plain_jacobian = lambda z: problem.plain_jacobian(N @ z) @ N

    def costs(self, Z: ArrayLike) -> Array:
        return self.p.costs(np.atleast_2d(Z) @ self.N.T)

    def residual(self, z: ArrayLike) -> Array:
        return self.p.residual(self.N @ np.asarray(z, dtype=float))

    def jacobian(self, z: ArrayLike) -> Array:
        return self.p.jacobian(self.N @ np.asarray(z, dtype=float)) @ self.N


def pose_rows(problem: CalibrationProblem) -> int:
    """The number of pose rows (the residual's rows before the n unit rows)."""
    return problem.n_rows - problem.nominal.n


def row_groups(problem: CalibrationProblem) -> NDArray[np.str_]:
    """``"orientation"`` or ``"position"`` for every pose row, in the residual's order."""
    per = ["position"] * 3 if problem.data.position_only else ["orientation"] * 3 + ["position"] * 3
    return np.tile(np.array(per), problem.data.M)


def plain(problem: CalibrationProblem, what: str, x: Array) -> Array:
    """The plain (not robustified) residual or Jacobian of ``problem`` at ``x``."""
    if isinstance(problem, RobustProblem):
        return problem.plain_residual(x) if what == "residual" else problem.plain_jacobian(x)
    return problem.residual(x) if what == "residual" else problem.jacobian(x)


def first_fit(problem: CalibrationProblem, prior: Array) -> tuple[Array, float, int, int]:
    """Levenberg-Marquardt within the directions the poses see at the nominal arm: the genome
    (K,), its cost, the evaluations and the number of directions."""
    n = problem.nominal.n
    J = problem.plain_jacobian(np.zeros(problem.layout.size)) if isinstance(problem, RobustProblem) else problem.J_nominal
    S0 = sub.identify(J[:-n], J[-n:], prior, None)
    fit = levenberg_marquardt(_Within(dataclasses.replace(problem, unit_weight=0.0), S0.basis))  # axes that only turn
    z = fit.x if fit.x is not None else np.zeros(S0.rank)
    return S0.basis @ z, float(fit.cost), fit.nevals, S0.rank


def noise(problem: CalibrationProblem, residual: Array, rank: int) -> Noise:
    """The noise of the pose rows (module docstring, step 2) from the ``residual`` (pose rows)
    of a fit with ``rank`` parameters. With the instrument's standard deviations, their
    position rows' ``chi^2 / dof`` is recorded, and they are the noise when the residual is
    consistent with them (chi^2 below its 99% quantile); otherwise the residual's own (the
    model, not the instrument, limits the fit: on the UR10 data chi^2/dof is in the hundreds)."""
    groups, m = row_groups(problem), residual.size
    dof = m - rank
    sigma, robust = {}, {}
    row = np.full(m, np.nan)
    share = dof / m if m else 0.0  # a group's degrees of freedom, in proportion to its rows
    for g in ("orientation", "position"):
        r = residual[groups == g]
        if not r.size or dof <= 0:
            continue
        sigma[g] = float(np.sqrt(r @ r / (r.size * share)))
        robust[g] = float(MAD * np.median(np.abs(r)) / np.sqrt(share))
        row[groups == g] = sigma[g]
    source, chi2 = ("residual" if sigma else "none"), None
    data = problem.data
    if data.std is not None:
        from scipy.special import chdtri

        w = np.ones_like(data.std) if data.weights is None else data.weights
        stated = (data.std * w).ravel()
        position = residual[groups == "position"]
        n_dof = position.size * share
        chi2 = float(np.sum((position / stated) ** 2) / n_dof) if dof > 0 else None
        if chi2 is None or chi2 <= chdtri(n_dof, CONSISTENT) / n_dof:  # the stated deviations describe the residual
            row[groups == "position"] = stated
            source = "instrument"
        else:
            source = f"residual (the instrument's deviations do not describe it: chi2/dof = {chi2:.3g})"
    ok = np.isfinite(row).all() and (row > 0).all()
    return Noise(row if ok else None, sigma, robust, source if ok else "none", int(dof), chi2)


def outliers(problem: CalibrationProblem, residual: Array, nz: Noise) -> list[dict]:
    """Points whose residual is far beyond the robust noise (module docstring, step 3): their
    row, file, line, tool, position error (m) and ``d^2``, largest first."""
    from scipy.special import chdtri  # the chi-square quantile (scipy.stats.chi2.isf), without scipy.stats' import

    if not nz.robust:
        return []
    groups, data = row_groups(problem), problem.data
    sigma = np.array([nz.robust.get(g, np.nan) for g in groups])
    if not np.all(sigma > 0):
        return []
    per = 3 if data.position_only else 6
    d2 = np.sum(((residual / sigma) ** 2).reshape(data.M, per), axis=1)
    limit = chdtri(per, OUTLIER_ALPHA / data.M)
    w = np.ones((data.M, 3)) if data.weights is None else data.weights
    dp = (residual[groups == "position"].reshape(data.M, 3)) / w
    size = np.linalg.norm(dp, axis=1)
    assert data.lines is not None  # Measurements numbers its rows
    out = [{"row": int(k), "file": data.source, "line": int(data.lines[k]), "where": data.where(int(k)),
            "size_mm": float(size[k] * 1e3), "d2": float(d2[k])}
           for k in np.flatnonzero((d2 > limit) & (size > ROUND_OFF_M))]  # fmt: skip
    return sorted(out, key=lambda o: -o["d2"])


def prepare(problem: CalibrationProblem, prior: Array, search_scale: float, c: ProblemConf) -> tuple[CalibrationProblem, Setup]:
    """``problem`` as the optimisers see it and what its set-up found (module docstring)."""
    layout, n = problem.layout, problem.nominal.n
    fit = _fit(problem, prior)
    scale = None
    if c.loss is not Loss.linear:
        problem, fit, scale = _robust(problem, prior, fit, c)
    found = outliers(problem, plain(problem, "residual", fit[0])[:-n], fit[4])
    change: dict[str, Any] = {}
    dropped = bool(found and c.outliers is Outliers.drop)
    if dropped:
        keep = np.ones(problem.data.M, dtype=bool)
        keep[[o["row"] for o in found]] = False
        before, before_x = problem, fit[0]
        problem = dataclasses.replace(problem, data=problem.data.subset(keep))
        fit = _fit(problem, prior)
        change = _change(before, before_x, problem, fit[0], keep)
    x, cost, nevals, rank0, nz = fit
    if isinstance(problem, RobustProblem):  # the covariance and the rule take the robust noise
        nz = dataclasses.replace(nz, row_sigma=_robust_rows(problem, nz), source=nz.source if nz.source == "instrument" else "robust residual")
    setup = Setup(layout, prior, None, rank0, x, cost, nevals, nz, found, dropped, change, scale, problem)
    if c.subspace is SubspaceChoice.full:
        return problem, setup
    J = plain(problem, "jacobian", x)
    try:
        setup.subspace = sub.identify(J[:-n], J[-n:], prior, nz.row_sigma, c.max_se)
    except ValueError as exc:
        if not layout.is_masked:
            raise
        noise_mm = "" if nz.row_sigma is None else f" (the residual's noise: {np.median(nz.row_sigma) * 1e3:.3g} mm)"
        raise ValueError(f"{exc}{noise_mm}; with parameters fixed (problem.fixed, problem.free), their errors stay in the "
                         "residual and may hide every free one: fix fewer, or calibrate the free ones all the same with "
                         "problem.subspace=full") from None  # fmt: skip
    half = sub.half_widths(setup.subspace, search_scale)
    restricted = sub.restricted(layout, setup.subspace)
    return dataclasses.replace(problem, layout=restricted, lower=-half, upper=half, unit_weight=0.0), setup


def _fit(problem: CalibrationProblem, prior: Array) -> FirstFit:
    """:func:`first_fit` and the :func:`noise` of its residual."""
    x, cost, nevals, rank = first_fit(problem, prior)
    return x, cost, nevals, rank, noise(problem, plain(problem, "residual", x)[:-problem.nominal.n], rank)


def _robust(problem: CalibrationProblem, prior: Array, fit: FirstFit, c: ProblemConf) -> tuple[RobustProblem, FirstFit, float]:
    """The robust problem (module docstring, step 4), its first fit and its loss scale: the
    stated one, or 1.345 x the robust noise of the last fit until it changes by less than 10%."""
    fields, scale = _fields(problem), None
    robust: RobustProblem | None = None
    for _ in range(ROBUST_ROUNDS if c.loss_scale is None else 1):
        robust_sigma = max(fit[4].robust.values(), default=0.0)
        new = c.loss_scale or (LOSS_SCALE * robust_sigma if robust_sigma > 0 else None)
        if new is None:
            raise ValueError("problem.loss_scale: the data leave no degrees of freedom to estimate the noise; state it (m)")
        if scale is not None and abs(new / scale - 1) < 0.1:
            break
        scale = float(new)
        robust = RobustProblem(**fields, loss=c.loss.value, loss_scale=scale)
        fit = _fit(robust, prior)
    assert robust is not None and scale is not None  # the first round builds it
    return robust, fit, scale


def _robust_rows(problem: CalibrationProblem, nz: Noise) -> Array | None:
    if nz.source == "instrument" or nz.row_sigma is None:
        return nz.row_sigma
    groups = row_groups(problem)
    return np.array([nz.robust[g] for g in groups])


def _fields(problem: CalibrationProblem) -> dict[str, Any]:
    """The constructor's arguments of ``problem`` (a CalibrationProblem's fields)."""
    return {f.name: getattr(problem, f.name) for f in dataclasses.fields(CalibrationProblem)}


def _change(before: CalibrationProblem, x0: Array, after: CalibrationProblem, x1: Array, keep: NDArray[np.bool_]) -> dict[str, Any]:
    """What dropping the outliers changed in the first fit: the RMS residual of the points kept
    (m) and how far the model moved at them (largest and RMS change of the predicted
    positions, mm)."""
    from zrp_ga.model import metrics

    data = after.data
    e0 = metrics.position_errors(before.layout, before.nominal, x0, data)
    e1 = metrics.position_errors(after.layout, after.nominal, x1, data)
    p0 = metrics.predicted_positions(before.layout, before.nominal, x0, data)[0]
    p1 = metrics.predicted_positions(after.layout, after.nominal, x1, data)[0]
    moved = np.linalg.norm(p1 - p0, axis=1)
    rms = lambda e: float(np.sqrt(np.mean(e**2)) * 1e3)
    return {"points_dropped": int((~keep).sum()), "kept_rms_mm": {"with": rms(e0), "without": rms(e1)},
            "model_moved_mm": {"max": float(moved.max() * 1e3), "rms": rms(moved)}}  # fmt: skip


def uncertainty(problem: CalibrationProblem, z: Array, setup: Setup | None) -> Uncertainty | None:
    """The calibration's :class:`zrp_ga.model.uncertainty.Uncertainty` at its genome ``z``
    (``problem``'s): the covariance of the identified combinations from the Jacobian at z and
    the noise (the instrument's, else this fit's residual: robust for a robust cost), and the
    prior of what was left at nominal; None when the data leave no degrees of freedom."""
    from zrp_ga.model.uncertainty import Uncertainty, covariance, factor

    n = problem.nominal.n
    J, r = plain(problem, "jacobian", z)[:-n], plain(problem, "residual", z)[:-n]
    rank = problem.layout.size if setup is not None and setup.subspace is not None else int(np.linalg.matrix_rank(J))
    nz = noise(problem, r, rank)
    if isinstance(problem, RobustProblem):
        nz = dataclasses.replace(nz, row_sigma=_robust_rows(problem, nz))
    if nz.row_sigma is None:
        return None
    M = problem.layout.matrix
    cov = M @ factor(covariance(J, nz.row_sigma))
    prior = np.zeros((M.shape[0], 0))
    if setup is not None and setup.subspace is not None:
        prior = setup.layout.expand(setup.subspace.prior_factor.T).T  # the fixed genes' rows zero
    position = nz.row_sigma[row_groups(problem) == "position"]
    return Uncertainty(problem.layout.unmasked, problem.nominal, problem.layout.expand(z), cov, prior,
                       float(np.sqrt(np.mean(position**2))), nz.source)  # fmt: skip
