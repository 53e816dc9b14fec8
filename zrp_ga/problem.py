"""Calibration problems: measured poses, the identified parameters, their ranges, and the cost.

A genome is the vector of parameter errors ``de`` (K,) added to the nominal robot, laid out
as :func:`zrp_ga.error_model.parameter_names`: ``du0_1 .. du0_n, db0_2 .. db0_{n+1}`` (the
paper's 6n), then optionally ``db0_1`` (``base``) and a small hand rotation ``dphi_h``
(``hand``). The unit-length rows of Eq. (19-20) keep ``|u0 + du0| = 1``, as in the paper; the
forward kinematics of the nonlinear cost and of the validation turns about the normalised axis
``(u0 + du0) / |u0 + du0|``. Rodrigues' formula with a stretched axis no longer leaves the axis
fixed, and a least-squares solver then fits noise with points slid metres along the axes
(seen with LM before this choice: b0 genes of 14 m).

Costs of a whole population (P, K) are one vectorised call:

- ``linear`` (the paper): ``|| [dr; dp; 0] - J de ||`` with J the error Jacobian at the
  nominal parameters and ``[dr; dp]`` the measured pose errors of the nominal robot;
- ``nonlinear``: the forward-kinematics residual over all poses plus the unit rows
  ``(|u0_i + du0_i|^2 - 1) / 2`` (equal to ``u0_i^T du0_i`` to first order).

``norm="spectral"`` is the 2-norm of the residual vector, ``"rms"`` divides by the square root
of its length. Orientation rows are multiplied by ``orientation_weight`` (m per rad).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import lsq_linear
from scipy.spatial.transform import Rotation

from zrp_ga import error_model, kinematics, so3
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]

COSTS = ("linear", "nonlinear")
NORMS = ("spectral", "rms")


def _unit(u: Array) -> Array:
    """Axes (..., 3) scaled to unit length."""
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


@dataclasses.dataclass(frozen=True)
class Layout:
    """Which parameter errors a genome holds; K = 6n (+3 base, +3 hand)."""

    n: int
    base: bool = False
    hand: bool = False

    @property
    def names(self) -> list[str]:
        return error_model.parameter_names(self.n, self.base, self.hand)

    @property
    def size(self) -> int:
        return 6 * self.n + 3 * self.base + 3 * self.hand

    @property
    def blocks(self) -> dict[str, slice]:
        """Gene blocks: ``u0`` (axes), ``b0`` (body vectors 2..n+1), ``base``, ``hand``."""
        n = self.n
        out = {"u0": slice(0, 3 * n), "b0": slice(3 * n, 6 * n)}
        k = 6 * n
        for name, on in (("base", self.base), ("hand", self.hand)):
            if on:
                out[name] = slice(k, k + 3)
                k += 3
        return out

    def unpack(self, nominal: ZRPRobot, de: ArrayLike) -> tuple[Array, Array, Array]:
        """Parameters of a population of genomes de (P, K): u0 (P, n, 3), b0 (P, n+1, 3), R_h0 (P, 3, 3)."""
        de = np.atleast_2d(np.asarray(de, dtype=float))
        P, n, blocks = de.shape[0], self.n, self.blocks
        u0 = nominal.u0 + de[:, blocks["u0"]].reshape(P, n, 3)
        b0 = np.repeat(nominal.b0[None], P, axis=0)
        b0[:, 1:] += de[:, blocks["b0"]].reshape(P, n, 3)
        if self.base:
            b0[:, 0] += de[:, blocks["base"]]
        R_h0 = nominal.R_h0
        if self.hand:
            R_h0 = Rotation.from_rotvec(de[:, blocks["hand"]]).as_matrix() @ nominal.R_h0
        return u0, b0, np.broadcast_to(R_h0, (P, 3, 3))

    def robot(self, nominal: ZRPRobot, de: ArrayLike, name: str | None = None) -> ZRPRobot:
        """The calibrated robot of one genome, axes renormalised."""
        u0, b0, R_h0 = self.unpack(nominal, de)
        return nominal.replace(u0=u0[0], b0=b0[0], R_h0=R_h0[0], normalize=True, name=name or nominal.name)


@dataclasses.dataclass(frozen=True)
class Measurements:
    """Measured poses: joint values q (M, n) given to the model, positions p (M, 3) m, and
    orientations R (M, 3, 3), or None for position-only data; optional position weights (M, 3)."""

    q: Array
    p: Array
    R: Array | None = None
    weights: Array | None = None  # (M, 3) on the position errors, e.g. a typical sigma / each row's sigma

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        M = q.shape[0]
        checks = [("q", q, q.shape if q.ndim == 2 else (M, -1)), ("p", self.p, (M, 3))]
        if self.R is not None:
            checks.append(("R", self.R, (M, 3, 3)))
        if self.weights is not None:
            checks.append(("weights", self.weights, (M, 3)))
        for name, value, shape in checks:
            a = np.asarray(value, dtype=float)
            if a.shape != shape:
                raise ValueError(f"measurements.{name}: expected shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"measurements.{name}: NaN or inf at index {tuple(np.argwhere(~np.isfinite(a))[0])}")
            object.__setattr__(self, name, a)

    @property
    def M(self) -> int:
        return self.q.shape[0]

    @property
    def position_only(self) -> bool:
        return self.R is None


@dataclasses.dataclass
class CalibrationProblem:
    """A nominal robot, calibration (and validation) poses, the genome layout and gene ranges."""

    nominal: ZRPRobot
    calibration: Measurements
    layout: Layout
    lower: Array
    upper: Array
    validation: Measurements | None = None
    cost: str = "linear"
    norm: str = "spectral"
    orientation_weight: float = 1.0
    true_de: Array | None = None
    rcond: float = 1e-9

    def __post_init__(self) -> None:
        K, n = self.layout.size, self.nominal.n
        if self.layout.n != n:
            raise ValueError(f"layout: made for {self.layout.n} joints, the robot has {n}")
        if self.cost not in COSTS:
            raise ValueError(f"problem.cost: unknown cost {self.cost!r}; known: {', '.join(COSTS)}")
        if self.norm not in NORMS:
            raise ValueError(f"problem.norm: unknown norm {self.norm!r}; known: {', '.join(NORMS)}")
        if not (np.isfinite(self.orientation_weight) and self.orientation_weight >= 0):
            raise ValueError(f"problem.orientation_weight: must be >= 0, got {self.orientation_weight}")
        self.lower = np.broadcast_to(np.asarray(self.lower, dtype=float), (K,)).copy()
        self.upper = np.broadcast_to(np.asarray(self.upper, dtype=float), (K,)).copy()
        if not np.all(self.lower < self.upper):
            k = int(np.argmin(self.upper - self.lower))
            raise ValueError(f"gene range of {self.layout.names[k]}: lower {self.lower[k]} is not below upper {self.upper[k]}")
        for data in (self.calibration, self.validation):
            if data is not None and data.q.shape[1] != n:
                raise ValueError(f"measurements.q: {data.q.shape[1]} joints, the robot has {n}")
        data = self.calibration
        self._pose_rows = 3 if data.position_only else 6
        self.n_rows = self._pose_rows * data.M + n
        wp = np.ones((data.M, 3)) if data.weights is None else data.weights
        self._position_weights = wp
        pose = wp if data.position_only else np.hstack([np.full((data.M, 3), self.orientation_weight), wp])
        self._row_weights = np.concatenate([pose.ravel(), np.ones(n)])
        self._terms = kinematics.joint_terms(data.q, self.nominal.prismatic)
        self.J_nominal = self._jacobian_at(np.zeros(K))
        self.y_nominal = self._residual_one(np.zeros(K))  # [dr; dp; 0] of the nominal robot

    # --- residuals and costs -------------------------------------------------------------------
    def _jacobian_at(self, de: Array, exact: bool = False) -> Array:
        """Stacked error Jacobian at ``de`` (rows weighted). ``exact``: the orientation rows are
        the derivative of this problem's residual ``vee(skew(W))``, ``W = R_meas R^T``, which is
        ``(tr(W) I - W^T) / 2`` times the paper's J1 rows (equal when W = I)."""
        u0, b0, R_h0 = self.layout.unpack(self.nominal, de)
        data, n = self.calibration, self.nominal.n
        length = np.linalg.norm(u0[0], axis=1)
        unit = u0[0] / length[:, None]
        J = error_model.jacobian_arrays(unit, b0[0], self.nominal.prismatic, data.q, self.layout.base, self.layout.hand)
        if data.position_only:
            J = J[:, 3:]
        elif exact:
            if self.layout.hand:  # dexp of the hand rotation vector: its left Jacobian
                hand = self.layout.blocks["hand"]
                J[:, :3, hand] = J[:, :3, hand] @ so3.left_jacobian(np.atleast_2d(de)[0, hand])
            R, _ = kinematics.forward_batch(unit[None], b0, R_h0, data.q, self.nominal.prismatic)
            W = data.R @ np.swapaxes(R[0], -1, -2)
            G = 0.5 * (np.trace(W, axis1=1, axis2=2)[:, None, None] * np.eye(3) - np.swapaxes(W, -1, -2))
            J[:, :3] = G @ J[:, :3]
        # chain rule through the normalisation u / |u|: (I - u_hat u_hat^T) / |u|
        N = (np.eye(3) - unit[:, :, None] * unit[:, None, :]) / length[:, None, None]
        Ju = J[..., : 3 * n].reshape(J.shape[:2] + (n, 3))
        J[..., : 3 * n] = np.einsum("mrik,ikl->mril", Ju, N).reshape(J.shape[:2] + (3 * n,))
        U = np.zeros((self.nominal.n, self.layout.size))
        for i in range(self.nominal.n):
            U[i, 3 * i : 3 * i + 3] = u0[0, i]
        return np.vstack([J.reshape(-1, J.shape[-1]), U]) * self._row_weights[:, None]

    def _residual_one(self, de: Array) -> Array:
        """Weighted nonlinear residual of one genome: per pose [w dr; dp] (or dp), then -(|u|^2-1)/2."""
        u0, b0, R_h0 = self.layout.unpack(self.nominal, de)
        data = self.calibration
        R, p = kinematics.forward_batch(_unit(u0), b0, R_h0, data.q, self.nominal.prismatic)
        dp = data.p - p[0]
        if data.position_only:
            pose = dp
        else:
            dr, _ = error_model.pose_error(data.R, data.p, R[0], p[0])
            pose = np.hstack([dr, dp])
        unit = -0.5 * (np.sum(u0[0] ** 2, axis=1) - 1.0)
        return np.concatenate([pose.ravel(), unit]) * self._row_weights

    def residual(self, de: ArrayLike) -> Array:
        """Weighted residual vector (rows,) of one genome under this problem's cost."""
        de = np.asarray(de, dtype=float)
        if self.cost == "linear":
            return self.y_nominal - self.J_nominal @ de
        return self._residual_one(de)

    def jacobian(self, de: ArrayLike) -> Array:
        """Jacobian of the model with respect to de, so that ``residual(de + d) ~ residual(de) - J d``."""
        return self.J_nominal if self.cost == "linear" else self._jacobian_at(np.asarray(de, dtype=float), exact=True)

    def costs(self, de: ArrayLike) -> Array:
        """Cost of every genome of a population de (P, K), (P,); NaN or inf where the genes break the model."""
        de = np.atleast_2d(np.asarray(de, dtype=float))
        if self.cost == "linear":
            r = self.y_nominal[None] - de @ self.J_nominal.T
            total = np.einsum("pr,pr->p", r, r)
        else:
            with np.errstate(all="ignore"):
                U, B, H, length2 = self._kernel_layout(de)
                data = self.calibration
                sums = kinematics.residual_sums_unchecked(U, B, H, self._terms, data.p, data.R, self._position_weights)
                unit = 0.5 * (length2 - 1.0)
                total = self.orientation_weight**2 * sums[0] + sums[1] + np.einsum("ip,ip->p", unit, unit)
        with np.errstate(all="ignore"):
            if self.norm == "rms":
                total = total / self.n_rows
            return np.sqrt(total)

    def _kernel_layout(self, de: Array) -> tuple[Array, Array, Array, Array]:
        """Genomes (P, K) straight into the compiled kernel's layout, population last:
        unit axes U (n, 3, P), B (n+1, 3, P), H (3, 3, P), and |u0 + du0|^2 (n, P)."""
        P, n, blocks = de.shape[0], self.nominal.n, self.layout.blocks
        D = np.ascontiguousarray(de.T)  # the kernel needs C order: its loops vectorise over P
        U = self.nominal.u0[:, :, None] + D[blocks["u0"]].reshape(n, 3, P)
        length2 = np.einsum("ikp,ikp->ip", U, U)
        U /= np.sqrt(length2)[:, None, :]
        B = np.repeat(self.nominal.b0[:, :, None], P, axis=2)
        B[1:] += D[blocks["b0"]].reshape(n, 3, P)
        if self.layout.base:
            B[0] += D[blocks["base"]]
        if self.layout.hand:
            H = (Rotation.from_rotvec(de[:, blocks["hand"]]).as_matrix() @ self.nominal.R_h0).transpose(1, 2, 0)
        else:
            H = np.broadcast_to(self.nominal.R_h0[:, :, None], (3, 3, P))
        return U, B, np.ascontiguousarray(H), length2

    def refine(self, de: ArrayLike) -> Array:
        """The pseudo-inverse step (the paper's step 8): ``de + pinv(J) r``, with J and r at ``de``.

        Singular values below ``rcond * s_max`` are cut off, so unidentifiable directions are
        left where they are. For the linear cost one step reaches the least-squares solution.
        When that step would carry a gene out of its range (clipping it would undo the step),
        the step is taken by bounded linear least squares instead (``scipy.optimize.lsq_linear``),
        which uses the unidentifiable directions to stay inside the ranges.
        """
        de = np.asarray(de, dtype=float)
        J, r = self.jacobian(de), self.residual(de)
        new = de + np.linalg.lstsq(J, r, rcond=self.rcond)[0]
        if np.all((new >= self.lower) & (new <= self.upper)):
            return new
        return de + lsq_linear(J, r, bounds=(self.lower - de, self.upper - de)).x

    def canonical(self, de: ArrayLike) -> Array:
        """The same calibration with the points on the axes slid back: ``de`` minus its
        components along the exact null directions of the model (the slide of each axis point
        along its own, normalised axis, and any shift of a prismatic joint's point). Every pose
        and every cost stays the same; the body-vector errors become comparable between runs.
        LM, whose damping moves freely along these directions, otherwise reports metres."""
        de = np.asarray(de, dtype=float).copy()
        layout, n = self.layout, self.nominal.n
        u = _unit(layout.unpack(self.nominal, de)[0][0])
        start = {i: layout.blocks["b0"].start + 3 * (i - 2) for i in range(2, n + 2)}
        if layout.base:
            start[1] = layout.blocks["base"].start
        vectors = []
        for i in range(1, n + 1):
            if i not in start:
                continue
            dirs = np.eye(3) if self.nominal.joint_types[i - 1] == "P" else u[i - 1][None]
            for d in dirs:
                v = np.zeros(layout.size)
                v[start[i] : start[i] + 3] += d
                v[start[i + 1] : start[i + 1] + 3] -= d
                vectors.append(v)
        if vectors:
            Q = np.linalg.qr(np.array(vectors).T)[0]
            de -= Q @ (Q.T @ de)
        return de

    # --- judging a calibration ------------------------------------------------------------------
    def position_errors(self, de: ArrayLike, data: Measurements) -> Array:
        """Distance (mm) between measured and predicted position at every pose of ``data``: (M,)
        for one genome, (P, M) for a population (NaN where the genes break the model)."""
        de = np.asarray(de, dtype=float)
        u0, b0, R_h0 = self.layout.unpack(self.nominal, de)
        with np.errstate(all="ignore"):
            _, p = kinematics.forward_batch(_unit(u0), b0, R_h0, data.q, self.nominal.prismatic)
            err = np.linalg.norm(data.p[None] - p, axis=2) * 1e3
        return err[0] if de.ndim == 1 else err

    def validation_error(self, de: ArrayLike) -> tuple[Array, Array]:
        """RMS and max position error (mm) on the validation poses, each (P,); NaN without them."""
        de = np.atleast_2d(np.asarray(de, dtype=float))
        if self.validation is None:
            nan = np.full(de.shape[0], np.nan)
            return nan, nan
        err = self.position_errors(de, self.validation)
        return np.sqrt(np.mean(err**2, axis=1)), np.max(err, axis=1)

    def identifiable_projector(self) -> Array:
        """Orthogonal projector (K, K) onto the parameter directions the calibration and validation
        poses can see (row space of their stacked Jacobian at the nominal parameters)."""
        if not hasattr(self, "_projector"):
            q = self.calibration.q if self.validation is None else np.vstack([self.calibration.q, self.validation.q])
            J = error_model.jacobian_arrays(self.nominal.u0, self.nominal.b0, self.nominal.prismatic, q, self.layout.base, self.layout.hand)
            if self.calibration.position_only:
                J = J[:, 3:]
            J = np.vstack([J.reshape(-1, J.shape[-1]), error_model.unit_rows(self.nominal, self.layout.size)])
            _, s, Vt = np.linalg.svd(J, full_matrices=False)
            V = Vt[s > s[0] * max(J.shape) * np.finfo(float).eps]
            self._projector = V.T @ V
        return self._projector

    def param_error(self, de: ArrayLike) -> Array:
        """Distance to the true parameter errors in the identifiable subspace, (P,); NaN if unknown."""
        de = np.atleast_2d(np.asarray(de, dtype=float))
        if self.true_de is None:
            return np.full(de.shape[0], np.nan)
        return np.linalg.norm((de - self.true_de) @ self.identifiable_projector(), axis=1)

    def model_rank(self, n_poses: int = 60) -> int:
        """Rank of the error Jacobian over many random poses with this problem's kind of data:
        what the model can identify at best (the calibration data can only carry less)."""
        rng = np.random.default_rng(0)
        q = random_joints(self.nominal, n_poses, rng)
        J = error_model.error_jacobian(self.nominal, q, self.calibration.position_only, self.layout.base, self.layout.hand)
        return int(np.linalg.matrix_rank(J))

    def identifiability(self) -> error_model.IdentifiabilityReport:
        """Identifiability report of the calibration data (Jacobian at the nominal parameters)."""
        J = self._jacobian_at(np.zeros(self.layout.size))
        return error_model.identifiability(J, self.layout.names, self.nominal)


@dataclasses.dataclass(frozen=True)
class Simulation:
    """A simulated calibration case: the true robot and its measurements."""

    truth: ZRPRobot
    true_de: Array
    calibration: Measurements
    validation: Measurements


def random_joints(robot: ZRPRobot, M: int, rng: np.random.Generator) -> Array:
    """M random configurations (M, n): revolute joints uniform in [-pi, pi] rad, prismatic in [0, 0.5] m."""
    q = rng.uniform(-np.pi, np.pi, size=(M, robot.n))
    q[:, robot.prismatic] = rng.uniform(0.0, 0.5, size=(M, int(robot.prismatic.sum())))
    return q


def simulate(
    nominal: ZRPRobot,
    layout: Layout,
    rng: np.random.Generator,
    n_poses: int = 1,
    n_validation: int = 100,
    axis_error: float = 0.01,
    body_error: float = 5e-4,
    joint_noise: float = 1e-3,
    position_noise: float = 0.0,
    orientation_noise: float = 0.0,
    position_only: bool = False,
) -> Simulation:
    """The paper's case study (DESIGN.md section 3) for any arm and any number of poses.

    True parameters: axes ``u0 + U(+-axis_error)`` renormalised, body vectors
    ``b0 + U(+-body_error)`` (m) for the identified ones (base point too with ``layout.base``,
    the hand orientation turned by ``U(+-axis_error)`` rad per axis with ``layout.hand``).
    Measured poses: the true robot at ``q + U(+-joint_noise)`` plus Gaussian measurement noise
    (``position_noise`` m, ``orientation_noise`` rad, standard deviations); the model sees ``q``.
    The validation poses are drawn the same way and never enter the cost.
    """
    n = nominal.n
    u0 = nominal.u0 + rng.uniform(-axis_error, axis_error, size=(n, 3))
    u0 /= np.linalg.norm(u0, axis=1, keepdims=True)
    b0 = nominal.b0.copy()
    b0[1 if not layout.base else 0 :] += rng.uniform(-body_error, body_error, size=(n + 1 - (not layout.base), 3))
    R_h0 = nominal.R_h0
    phi = np.zeros(3)
    if layout.hand:
        phi = rng.uniform(-axis_error, axis_error, size=3)
        R_h0 = Rotation.from_rotvec(phi).as_matrix() @ R_h0
    truth = nominal.replace(u0=u0, b0=b0, R_h0=R_h0, name=f"{nominal.name} (true)")
    true_de = np.concatenate([(u0 - nominal.u0).ravel(), (b0[1:] - nominal.b0[1:]).ravel()]
                             + ([b0[0] - nominal.b0[0]] if layout.base else []) + ([phi] if layout.hand else []))

    def measure(M: int) -> Measurements:
        q = random_joints(nominal, M, rng)
        q_actual = q + rng.uniform(-joint_noise, joint_noise, size=q.shape)
        R, p = kinematics.forward(truth, q_actual)
        p = p + rng.normal(scale=position_noise, size=p.shape) if position_noise > 0 else p
        if orientation_noise > 0:
            R = Rotation.from_rotvec(rng.normal(scale=orientation_noise, size=(M, 3))).as_matrix() @ R
        return Measurements(q=q, p=p, R=None if position_only else R)

    return Simulation(truth, true_de, measure(n_poses), measure(n_validation))
