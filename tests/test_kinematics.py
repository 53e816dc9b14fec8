import dataclasses

import numpy as np
import pytest
from dh_reference import dh_fk

from zrp_ga import robots
from zrp_ga.io.robot_files import read_dh
from zrp_ga.model import _kernels, kinematics, so3
from zrp_ga.model.cost import CalibrationProblem
from zrp_ga.model.layout import Layout
from zrp_ga.model.robot import ZRPRobot
from zrp_ga.model.simulation import simulate


@pytest.fixture(params=["numpy", "compiled"])
def path(request, monkeypatch):
    """Each kernel through its numpy twin and compiled (zrp_ga.core.compiled.call's two paths)."""
    monkeypatch.setenv("ZRP_GA_KERNELS", request.param)
    return request.param


def _table(name):
    """The preset's DH table as tests/dh_reference.py takes it."""
    dh = read_dh(robots.path(name))
    return dict(d=dh.d, a=dh.a, alpha=dh.alpha, offset=dh.theta, joint_types=dh.joint_types)


@pytest.mark.parametrize("name", robots.names())
def test_forward_matches_independent_dh_chain(name, rng, path):
    robot, table = robots.get(name), _table(name)
    Q = rng.uniform(-np.pi, np.pi, size=(25, robot.n))
    Q[:, robot.prismatic] = rng.uniform(0.3, 1.2, size=(25, robot.prismatic.sum()))
    R, p = kinematics.forward(robot, Q)
    for m, q in enumerate(Q):
        T = dh_fk(table, q)
        np.testing.assert_allclose(R[m], T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p[m], T[:3, 3], atol=1e-12)


def test_modified_dh_matches_independent_chain(rng, path):
    table = dict(
        d=[0.3, 0.1, -0.2, 0.4, 0.0], a=[0.0, 0.05, 0.35, 0.0, 0.1],
        alpha=[0.0, np.pi / 2, 0.1, -np.pi / 2, np.pi / 2], offset=[0.1, 0.0, 0.2, 0.0, -0.3], joint_types="RRPRR",
    )
    robot = ZRPRobot.from_mdh(**table)
    for q in rng.uniform(-2, 2, size=(10, 5)):
        R, p = kinematics.forward(robot, q)
        T = dh_fk(table, q, modified=True)
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p, T[:3, 3], atol=1e-12)


def test_puma_wrist_centre_at_zero():
    R, p = kinematics.forward(robots.get("puma560"), np.zeros(6))
    np.testing.assert_allclose(p, [0.4521, -0.15005, 1.10363], atol=1e-12)
    np.testing.assert_allclose(R, np.eye(3), atol=1e-12)


def test_batch_over_population_equals_each_robot(rng, path):
    base = robots.get("stanford")
    P, M = 7, 11
    u0 = base.u0 + rng.normal(scale=0.01, size=(P, 6, 3))
    u0 /= np.linalg.norm(u0, axis=-1, keepdims=True)
    b0 = base.b0 + rng.normal(scale=0.01, size=(P, 7, 3))
    q = rng.uniform(-1, 1, size=(M, 6))
    R, p = kinematics.forward_batch(u0, b0, base.R_h0, q, base.prismatic)
    assert R.shape == (P, M, 3, 3) and p.shape == (P, M, 3)
    for k in range(P):
        robot_k = base.replace(u0=u0[k], b0=b0[k])
        Rk, pk = kinematics.forward(robot_k, q)
        np.testing.assert_allclose(R[k], Rk, atol=1e-14)
        np.testing.assert_allclose(p[k], pk, atol=1e-14)


def test_residual_sums_by_hand(rng, path):
    robot = robots.get("ur10")
    P, M = 4, 9
    u0 = robot.u0 + rng.normal(scale=0.02, size=(P, 6, 3))
    b0 = robot.b0 + rng.normal(scale=0.02, size=(P, 7, 3))
    q = rng.uniform(-3, 3, size=(M, 6))
    R_meas, p_meas = kinematics.forward(robot, q)
    R, p = kinematics.forward_batch(u0, b0, robot.R_h0, q)
    W = R_meas[None] @ np.swapaxes(R, -1, -2)
    dr = 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], -1)
    expected = np.stack([(dr**2).sum(axis=(1, 2)), ((p_meas - p) ** 2).sum(axis=(1, 2))], -1)
    got = kinematics.residual_sums(u0, b0, robot.R_h0, q, p_meas, R_meas)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    got = kinematics.residual_sums(u0, b0, robot.R_h0, q, p_meas)  # position only
    np.testing.assert_allclose(got[:, 0], 0.0)
    np.testing.assert_allclose(got[:, 1], expected[:, 1], rtol=1e-12)


@pytest.mark.parametrize(
    "q, message",
    [(np.zeros(5), r"q: expected shape \(6,\) or \(M, 6\)"), (np.zeros((2, 3, 6)), "q: expected shape"),
     ([0, 0, np.nan, 0, 0, 0], r"q: NaN or inf at index \(2,\)")],
)
def test_forward_refuses_bad_q(q, message):
    with pytest.raises(ValueError, match=message):
        kinematics.forward(robots.get("puma560"), q)


# --- the reference forward kinematics and the cost kernels -------------------------------------

def _joints(robot, M, rng):
    q = rng.uniform(-np.pi, np.pi, size=(M, robot.n))
    q[:, robot.prismatic] = rng.uniform(0.3, 1.2, size=(M, robot.prismatic.sum()))
    return q


@pytest.mark.parametrize("name", robots.names())
def test_reference_matches_forward_and_independent_dh_chain(name, rng):
    robot, table = robots.get(name), _table(name)
    Q = _joints(robot, 10, rng)
    R, p = kinematics.forward_reference(robot, Q)
    R1, p1 = kinematics.forward(robot, Q)
    np.testing.assert_allclose(R, R1, atol=1e-12)
    np.testing.assert_allclose(p, p1, atol=1e-12)
    for m, q in enumerate(Q):
        T = dh_fk(table, q)
        np.testing.assert_allclose(R[m], T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p[m], T[:3, 3], atol=1e-12)


def _case(rng, name="puma560", P=5, M=4, scale=0.02):
    """P unit-axis parameter sets near a preset arm, M joint vectors and the poses of a perturbed arm."""
    robot = robots.get(name)
    u0 = robot.u0 + rng.uniform(-scale, scale, size=(P, robot.n, 3))
    u0 /= np.linalg.norm(u0, axis=-1, keepdims=True)
    b0 = robot.b0 + rng.uniform(-scale, scale, size=(P, robot.n + 1, 3))
    q = _joints(robot, M, rng)
    truth = robot.replace(u0=robot.u0 + rng.uniform(-scale, scale, size=(robot.n, 3)), normalize=True)
    R_meas, p_meas = kinematics.forward(truth, q)
    return robot, u0, b0, q, p_meas, R_meas


def _reference_norms(robot, u0, b0, q, p_meas, R_meas, weights):
    """Norms of the orientation and weighted position residual vectors (rad, m), (P, 2), from forward_reference."""
    out = []
    for u, b in zip(u0, b0):
        R, p = kinematics.forward_reference(robot.replace(u0=u, b0=b), q)
        dr = so3.vee(R_meas @ np.swapaxes(R, -1, -2)) if R_meas is not None else np.zeros(3)
        out.append([np.linalg.norm(dr), np.linalg.norm(weights * (p_meas - p))])
    return np.array(out)


LANES = _kernels.LANES  # parameter sets per chunk of the kernels
# float32: the chain's rounding is a few float32 units (6e-8) of the arm's reach (about 1 m) per
# pose and joint; 1e-6 m (or rad) per pose, 16 units, bounds what was seen (2e-7) with room.
TOLERANCE = {"rodrigues": 1e-12, "matrix": 1e-12, "float32": 1e-6}


@pytest.mark.parametrize("kernel", kinematics.KERNELS)
@pytest.mark.parametrize(
    "name, P, M",
    [("puma560", 1, 1), ("puma560", 31, 3), ("stanford", LANES + 1, 5), ("ur10", 67, 2)],
)
def test_every_kernel_matches_the_reference(kernel, name, P, M, rng, path):
    """Residual norms of every kernel against forward_reference, for P = 1, odd P across chunk
    boundaries, M = 1 and a prismatic arm (stanford); weights on the positions, full and
    position-only data."""
    robot, u0, b0, q, p_meas, R_meas = _case(rng, name, P, M)
    weights = rng.uniform(0.5, 2.0, size=(M, 3))
    U, B, H = kinematics._population(u0, b0, robot.R_h0)
    terms = kinematics.joint_terms(q, robot.prismatic)
    tol = TOLERANCE[kernel] * np.sqrt(M)
    lanes = sorted({0, P // 2, P - 1} | {k for k in (LANES - 1, LANES) if k < P})  # chunk edges
    for R in (R_meas, None):
        got = np.sqrt(kinematics.residual_sums_unchecked(U, B, H, terms, p_meas, R, weights, kernel=kernel).T)
        expected = _reference_norms(robot, u0[lanes], b0[lanes], q, p_meas, R, weights)
        np.testing.assert_allclose(got[lanes], expected, rtol=0, atol=tol)


@pytest.mark.parametrize("kernel", kinematics.KERNELS)
def test_kernels_take_non_contiguous_input_and_threads(kernel, rng, path):
    robot, u0, b0, q, p_meas, R_meas = _case(rng, P=70, M=3)
    U, B, H = kinematics._population(u0, b0, robot.R_h0)
    terms = kinematics.joint_terms(q, robot.prismatic)
    expected = kinematics.residual_sums_unchecked(U, B, H, terms, p_meas, R_meas, kernel=kernel)
    Uf = np.asfortranarray(U)  # same values, other strides
    Bs = np.repeat(B, 2, axis=2)[:, :, ::2]  # a strided view
    p_wide = np.hstack([p_meas, p_meas])[:, :3]
    got = kinematics.residual_sums_unchecked(Uf, Bs, H, terms, p_wide, R_meas, kernel=kernel)
    np.testing.assert_array_equal(got, expected)
    for threads in (2, 3, None):
        got = kinematics.residual_sums_unchecked(U, B, H, terms, p_meas, R_meas, kernel=kernel, threads=threads)
        np.testing.assert_array_equal(got, expected)


def test_rodrigues_kernel_is_bit_identical_to_forward_batch(rng, path):
    """The default kernel does zrp_ga 0.1's operations in 0.1's order: its sums equal, bit for bit,
    the same formula evaluated in numpy on forward_batch's poses (whose kernel is 0.1's)."""
    robot, u0, b0, q, p_meas, R_meas = _case(rng, "stanford", P=45, M=6)
    weights = rng.uniform(0.5, 2.0, size=(6, 3))
    R, p = kinematics.forward_batch(u0, b0, robot.R_h0, q, robot.prismatic)
    rot, pos = np.zeros(45), np.zeros(45)
    for m in range(6):
        e = (p_meas[m] - p[:, m]) * weights[m]
        pos += e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1] + e[:, 2] * e[:, 2]
        Rm, Rh = R_meas[m], R[:, m]

        def w(a, b):  # (R_meas R_h^T)[a, b], summed left to right as the kernel does
            return Rm[a, 0] * Rh[:, b, 0] + Rm[a, 1] * Rh[:, b, 1] + Rm[a, 2] * Rh[:, b, 2]

        d = 0.5 * (w(2, 1) - w(1, 2)), 0.5 * (w(0, 2) - w(2, 0)), 0.5 * (w(1, 0) - w(0, 1))
        rot += d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    U, B, H = kinematics._population(u0, b0, robot.R_h0)
    terms = kinematics.joint_terms(q, robot.prismatic)
    got = kinematics.residual_sums_unchecked(U, B, H, terms, p_meas, R_meas, weights)
    np.testing.assert_array_equal(got, np.stack([rot, pos]))


def test_unknown_kernel_is_refused():
    robot = robots.get("puma560")
    args = robot.u0[None], robot.b0[None], robot.R_h0, np.zeros(6), np.zeros((1, 3))
    with pytest.raises(ValueError, match="kernel: unknown kernel 'float16'; known: rodrigues, matrix, float32"):
        kinematics.residual_sums(*args, kernel="float16")


# float32 ranks a population like float64 where their costs differ by more than twice the
# float32 resolution of a cost: DELTA bounds |cost32 - cost64| (seen: 1.4e-7 on these problems;
# a cost is the norm of 6 * 30 + 6 rows, each off by a few 6e-8 units of the 1 m arm).
DELTA = 1e-6


@pytest.mark.parametrize("where", ["uniform in +-2x the paper's ranges", "near convergence"])
def test_float32_ranks_a_ga_population_like_float64(where):
    """PUMA 560, 30 poses with the paper's errors and joint noise, genes within +-2x the paper's
    error ranges (axes 0.02, body vectors 1 mm), or within 0.1% of those ranges around the truth.
    Rule: |cost32 - cost64| <= DELTA for every genome, hence every pair whose float64 costs differ
    by more than 2 DELTA is in the same order, and the best 50 are the same genomes."""
    rng = np.random.default_rng(7)
    arm, layout = robots.get("puma560"), Layout(6)
    sim = simulate(arm, layout, rng, n_poses=30, n_validation=0)
    half = np.r_[np.full(18, 0.02), np.full(18, 1e-3)]
    prob = CalibrationProblem(arm, sim.calibration, layout, -half, half, cost="nonlinear")
    scale = 1.0 if where.startswith("uniform") else 1e-3
    centre = 0.0 if where.startswith("uniform") else sim.true_x
    de = centre + rng.uniform(-scale * half, scale * half, size=(200, 36))
    c64 = prob.costs(de)
    c32 = dataclasses.replace(prob, kernel="float32").costs(de)
    assert np.abs(c32 - c64).max() <= DELTA
    apart = np.abs(c64[:, None] - c64[None, :]) > 2 * DELTA
    same_order = np.sign(c64[:, None] - c64[None, :]) == np.sign(c32[:, None] - c32[None, :])
    assert np.all(same_order[apart])
    best64, best32 = np.argsort(c64)[:50], np.argsort(c32)[:50]
    if np.sort(c64)[50] - np.sort(c64)[49] > 2 * DELTA:
        assert set(best64) == set(best32)
