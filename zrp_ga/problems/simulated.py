"""Simulated problems: the paper's case study and its multi-pose forms (``problem=paper``,
``problem=multipose``): a true robot drawn around the nominal one, calibration and validation
poses measured on it (:mod:`zrp_ga.model.simulation`)."""

from __future__ import annotations

import numpy as np

from zrp_ga.core.schema import SimulatedConf, section
from zrp_ga.model import metrics, simulation
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.metrics import Judge
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.problems import Task, half_ranges, identify, masked, term_scales, with_terms
from zrp_ga.problems.size import ProblemSize, calibration


def build(robot: ZRPRobot, run_seed: int = 0, **settings) -> Task:
    """The instance of ``settings`` (``zrp_ga.core.schema.SimulatedConf``'s keys) for ``robot``.
    The problem draws from a random stream of its own, ``[problem.seed or run_seed, 1]`` (with
    the optimiser's, the first genome would be the true errors): a named instance keeps its
    ``problem.seed`` whatever the run's seed. Fixed parameters (``problem.fixed``) are the
    calibration's choice, not the arm's: the true arm, its poses and the truth the judge holds
    (the full genome) are the same with and without them."""
    c: SimulatedConf = section(SimulatedConf, settings, "problem")
    info = {"kind": "simulated"}
    full = Layout(robot.n, base=c.identify_base, hand=c.identify_hand)
    with_t, nominal = with_terms(c, full, robot, info)  # the true arm stays geometric; the calibration may add terms
    layout = masked(c, with_t, info, robot)
    instance_seed = run_seed if c.seed is None else c.seed
    sim = simulation.simulate(
        robot, full, np.random.default_rng([instance_seed, 1]), n_poses=c.n_poses, n_validation=c.n_validation,
        axis_error=c.axis_error, body_error=c.body_error, joint_noise=c.joint_noise, position_noise=c.position_noise,
        orientation_noise=c.orientation_noise, position_only=c.position_only,
    )  # fmt: skip
    half = half_ranges(c, layout, term_scales(nominal, layout.unmasked, sim.calibration.q))
    problem = CalibrationProblem(nominal, sim.calibration, layout, -half, half, c.cost, c.norm, c.orientation_weight, c.kernel)
    problem, setup = identify.prepare(problem, half / c.search_scale, c.search_scale, c)
    validation = sim.validation if c.n_validation else None
    q = sim.calibration.q if validation is None else np.vstack([sim.calibration.q, validation.q])
    projector = metrics.identifiable_projector(robot, full, q, c.position_only)
    true_x = sim.true_x
    if with_t.terms:  # param_err: the geometric genes' distance (the true arm has no terms)
        F = with_t.terms.size
        true_x, projector = np.concatenate([true_x, np.zeros(F)]), np.pad(projector, ((0, F), (0, F)))
    name = c.name or f"{robot.name}-{c.n_poses}pose{'s' if c.n_poses > 1 else ''}-{c.cost.value}-seed{instance_seed}"
    return Task(name, problem, Judge(problem.layout, nominal, validation, true_x, projector), robot,
                info | {"seed": instance_seed}, setup=setup,
                if_worse=c.if_worse.value if c.if_worse else None)  # fmt: skip


def size(robot: ZRPRobot, **settings) -> ProblemSize:
    """The size of the instance :func:`build` makes of ``settings``, before it is built
    (:func:`zrp_ga.problems.size.calibration`): the genes of its whole layout (fixed ones
    included: the Jacobians hold them), ``n_poses`` and ``n_validation`` poses."""
    c: SimulatedConf = section(SimulatedConf, settings, "problem")
    genes = Layout(robot.n, base=c.identify_base, hand=c.identify_hand).size
    return calibration(robot.n, genes, c.n_poses, c.n_validation, 3 if c.position_only else 6)
