"""Problem kinds: what the config's ``problem`` group builds. Each kind is one module (here, or
anywhere Python imports it from) with a ``build(robot, run_seed, **settings) -> Task`` function,
a ``size(robot, **settings) -> ProblemSize`` function that declares the instance's size before
it is built (:mod:`zrp_ga.problems.size`; the run's memory and time estimate asks it,
:mod:`zrp_ga.run.budget`), and one config file in ``conf/problem`` naming it by ``_target_``
(the kinds here also have a schema in :mod:`zrp_ga.core.schema`; a kind's own needs none,
and may check its settings itself). ``run_seed`` is the run's seed; ``settings`` are the ``problem`` node's keys,
its own ``seed`` among them (a named instance's, which the run's seed must not replace).

A :class:`Task` is a problem instance (:class:`zrp_ga.model.cost.CalibrationProblem`, what the
optimisers see) with what judges its answers (:class:`zrp_ga.model.metrics.Judge`: validation poses,
the truth in simulation) and what a run writes about it beyond the common files.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from zrp_ga.core.schema import ProblemConf
from zrp_ga.model import dh, terms
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout, dh_mask, fixed_summary, mask
from zrp_ga.model.metrics import Judge
from zrp_ga.model.robot import ZRPRobot

if TYPE_CHECKING:
    from zrp_ga.model.error_model import IdentifiabilityReport
    from zrp_ga.problems.identify import Setup

Array = NDArray[np.float64]


@dataclasses.dataclass
class Task:
    """A calibration problem instance, named, with its judge; ``robot`` is the arm as given
    (before any registration), ``info`` goes into ``summary.json``, ``warnings`` (found while
    building it) into its warnings. ``nominal_if_worse``: the kind's default for a result worse
    than the nominal arm (on the calibration or validation data, or predicted over its own
    coverage): replaced by the nominal arm (:mod:`zrp_ga.run.summary`); ``if_worse`` the
    setting that overrides it."""

    name: str
    problem: CalibrationProblem
    judge: Judge
    robot: ZRPRobot
    info: dict[str, Any] = dataclasses.field(default_factory=dict)
    warnings: list[str] = dataclasses.field(default_factory=list)
    setup: Setup | None = None  # what the problem's set-up found (None: none)
    if_worse: str | None = None  # problem.if_worse: nominal or keep (None: the kind's nominal_if_worse)
    nominal_if_worse: ClassVar[bool] = False

    @property
    def returns_nominal(self) -> bool:
        """Whether a model worse than the nominal arm is replaced by it (``problem.if_worse``)."""
        return self.nominal_if_worse if self.if_worse is None else self.if_worse == "nominal"

    @property
    def truth(self) -> Array | None:
        return self.judge.truth

    @property
    def layout(self) -> Layout:
        """The genome before the restriction to the identified combinations (masked as
        configured): what the identifiability report covers."""
        return self.problem.layout if self.setup is None else self.setup.layout

    def identifiability(self) -> IdentifiabilityReport:
        """The identifiability report (:func:`zrp_ga.model.error_model.identifiability`) of the
        calibration poses at the nominal arm, over :attr:`layout`'s parameters."""
        if self.setup is None:
            return self.problem.identifiability()
        assert self.setup.problem is not None  # prepare() gives it
        return self.setup.problem.identifiability()

    def calibrated_robot(self, x: Array) -> ZRPRobot:
        p = self.problem
        return p.layout.robot(p.nominal, x, name=f"{p.nominal.name} calibrated")

    def export(self, x: Array) -> tuple[ZRPRobot, Array | None, dict[str, Array]]:
        """The calibrated arm as robot files carry it: the arm, the pose (4, 4) of its base frame
        in the outer frame (None: the same), and tool frames (4, 4) in its hand frame by name."""
        return self.calibrated_robot(x), None, {}

    def report(self, x: Array) -> dict[str, Any]:
        """Entries of this kind for ``summary.json`` about the calibrated genome ``x``."""
        return self.dh_report(x)

    def dh_report(self, x: Array) -> dict[str, Any]:
        """With fixed DH parameters: ``dh_fixed_change``, each one's change from the nominal arm
        to the calibrated one (m, rad; held only to first order, so second-order small)."""
        layout = self.problem.layout
        if not layout.dh_fixed:
            return {}
        source = self.robot.source
        assert isinstance(source, dh.DHTable)  # DH parameters are fixed on an arm read from a DH table only (masked)
        convention = source.convention
        base_x = dh.to_dh(self.problem.nominal, convention, samples=1)[0].base[:3, 0]
        before = dh.parameters(self.problem.nominal, convention, base_x)
        after = dh.parameters(self.calibrated_robot(x), convention, base_x)
        change = {k: float(np.angle(np.exp(1j * (after[k] - before[k])))) if k.split("_")[1] in ("alpha", "theta", "beta")
                  else after[k] - before[k] for k in layout.dh_fixed}  # fmt: skip
        return {"dh_fixed_change": change}

    def write(self, out: Path, x: Array) -> None:
        """Files of this kind beyond the common ones."""

    def fit_residual(self, x: Array | None) -> None:
        """Fit the residual model (if the task's model has one) to genome ``x``'s residuals on the
        calibration data, so that the judge's ``corrected`` errors use it; None: drop it (the
        nominal arm is returned). Without a residual model: nothing."""


def masked(c: ProblemConf, layout: Layout, info: dict[str, Any] | None = None, robot: ZRPRobot | None = None) -> Layout:
    """``layout`` with the parameters ``problem.fixed`` / ``problem.free`` name held at nominal
    (:func:`zrp_ga.model.layout.mask`; an unknown name is one line naming the key and the valid
    names); what is fixed goes into ``info["fixed"]`` (``summary.json``). DH names in
    ``problem.fixed`` (``dh_theta_2``: :func:`zrp_ga.model.layout.dh_mask`) need ``robot``, the nominal
    arm read from a DH or modified-DH table file; their nominal values go into
    ``info["dh_fixed_nominal"]``."""
    fixed = None if c.fixed is None else [c.fixed] if isinstance(c.fixed, str) else list(c.fixed)
    free = None if c.free is None else [c.free] if isinstance(c.free, str) else list(c.free)
    dh_names = [str(k).strip() for k in fixed or () if str(k).strip().startswith("dh_")]
    for name in free or ():
        if str(name).strip().startswith("dh_"):
            raise ValueError(f"problem.free: {str(name).strip()!r}: DH parameters are named in problem.fixed only")
    table: dh.DHTable | None = None  # the nominal DH table of the DH parameters named
    if dh_names:
        if robot is None:
            raise ValueError(f"problem.fixed: {dh_names[0]!r}: DH parameters can be fixed in simulated problems only "
                             "(problem=paper or multipose)")  # fmt: skip
        if not isinstance(robot.source, dh.DHTable):
            raise ValueError(f"problem.fixed: {dh_names[0]!r} names a DH parameter, but the arm {robot.name!r} was not read from a "
                             "DH table file (robot.file: a DH or modified-DH table, or a preset); fix it by kind (u0_i, b0_i, ...)")  # fmt: skip
        table = robot.source
        fixed = [k for k in fixed or () if not str(k).strip().startswith("dh_")]
    out = mask(layout, fixed, free, "problem")
    if table is not None:
        assert robot is not None  # checked with the table
        out = dh_mask(out, robot, table.convention, dh_names, "problem")
    if info is not None and out.is_masked:
        info["fixed"] = fixed_summary(out) + list(out.dh_fixed)
    if info is not None and out.dh_fixed:
        assert robot is not None and isinstance(robot.source, dh.DHTable)  # DH parameters are fixed on a DH table's arm only
        nominal = dh.parameters(robot, robot.source.convention)
        info["dh_fixed_nominal"] = {k: nominal[k] for k in out.dh_fixed}
    return out


def with_terms(c: ProblemConf, layout: Layout, robot: ZRPRobot, info: dict[str, Any] | None = None) -> tuple[Layout, ZRPRobot]:
    """``layout`` with the non-geometric terms ``problem.terms`` names (:func:`zrp_ga.model.terms.parse`)
    and ``robot`` with the mass model they use (the robot's own, from its URDF's inertials or
    robot file, else :func:`zrp_ga.model.terms.generic`; ``problem.terms.payload`` added); the
    terms, the mass model's source and the payload go into ``info["terms"]``. Without terms: both
    as they are."""
    spec, payload = terms.parse(getattr(c, "terms", None), "problem.terms")
    if not spec:
        if payload is not None:
            raise ValueError("problem.terms.payload: a payload acts through joint compliance; name the joints in problem.terms.compliance")
        return layout, robot
    spec.check(robot, "problem.terms")
    mass = robot.mass or terms.generic(robot)
    if payload is not None:
        mass = mass.with_payload(*payload)
    if info is not None:
        info["terms"] = spec.to_dict() | {"names": spec.names, "mass_model": mass.source, "payload_kg": mass.payload_mass,
                                          "payload_com_m": mass.payload_com.tolist()}  # fmt: skip
    return dataclasses.replace(layout, terms=spec), robot.replace(mass=mass)


def term_scales(problem_or_nominal: ZRPRobot, layout: Layout, q: Array) -> Array:
    """Per term gene (F,), the largest size of its feature over the poses ``q`` (N m for a
    compliance, 1 for a harmonic): a gene range of ``axis_error / scale`` lets the term turn
    its joint by up to ``axis_error`` rad."""
    if not layout.terms:
        return np.zeros(0)
    phi = terms.features(layout.terms, problem_or_nominal, q)
    return np.maximum(np.abs(phi).max(axis=0), 1e-9)


def half_ranges(c: ProblemConf, layout: Layout, term_scale: Array | None = None) -> Array:
    """Half widths (K,) of the gene ranges: ``axis_error`` on the axes and the hand (rad),
    ``body_error`` on the body vectors and the base point (m), times ``search_scale``. With a
    basis N (fixed DH parameters), gene k's is ``sum_j |N_jk| h_j`` over the full genome's
    half widths h: the largest z_k = N[:, k] . x over the box |x_j| <= h_j."""
    full = layout.unmasked
    half = np.empty(full.size)
    for name, block in full.blocks.items():
        half[block] = c.axis_error if name in ("u0", "hand", "terms") else c.body_error
    if full.terms:  # a term may turn its joint by up to axis_error (rad) over the poses
        half[full.blocks["terms"]] /= np.ones(full.terms.size) if term_scale is None else term_scale
    half = np.abs(layout.matrix).T @ half if layout.is_masked else half
    return half * c.search_scale
