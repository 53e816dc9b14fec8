"""A calibration problem: bounds and a vectorised cost for a population, in pymoo's shape, plus
the residual and its Jacobian for one genome (for least squares and the pseudo-inverse step).

Genomes are parameter errors laid out by :class:`zrp_ga.model.layout.Layout`. Costs of a population
(P, K) are one vectorised call:

- ``linear`` (the paper): ``|| [dr; dp; 0] - J x ||`` with J the error Jacobian at the nominal
  parameters (Eq. 21-27) and ``[dr; dp]`` the pose errors of the nominal robot;
- ``nonlinear``: the forward-kinematics residual over all poses plus the unit rows
  ``(|u0_i + du0_i|^2 - 1) / 2`` (equal to the paper's ``u0_i^T du0_i`` to first order),
  times ``unit_weight`` (0 for a genome whose axes only turn, the identified subspace of
  :mod:`zrp_ga.model.subspace`: there the rows would measure ``|du0_i|^2 / 2``, a bias the
  data never asked for, since the model turns about the normalised axes anyway).

The forward kinematics turns about the normalised axes: Rodrigues' formula with a stretched
axis no longer leaves the axis fixed, and least squares then fits noise with points slid metres
along the axes (seen with LM before this choice: b0 genes of 14 m).
``norm="spectral"`` is the 2-norm of the residual vector, ``"rms"`` divides by the square root
of its length. Orientation rows are multiplied by ``orientation_weight`` (m per rad).

Several tool points (``data.tool``, the layout's ``tools``): the poses are grouped by tool once,
and each group is one kernel call with that tool's last body vector; with one tool the cost is
the single call it always was.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.schema import Cost, Kernel, Norm
from zrp_ga.model import error_model, kinematics, so3, terms
from zrp_ga.model.layout import Layout
from zrp_ga.model.poses import Measurements
from zrp_ga.model.robot import ZRPRobot

Array = NDArray[np.float64]


@dataclasses.dataclass
class CalibrationProblem:
    """Nominal robot, calibration poses, genome layout and gene ranges ``lower``/``upper`` (K,)."""

    nominal: ZRPRobot
    data: Measurements
    layout: Layout
    lower: Array
    upper: Array
    cost: Cost = Cost.nonlinear
    norm: Norm = Norm.spectral
    orientation_weight: float = 1.0
    kernel: Kernel = Kernel.rodrigues  # which compiled cost evaluates a population (float64 unless float32)
    unit_weight: float = 1.0  # of the unit-length rows (0: a genome whose axes only turn, zrp_ga.model.subspace)

    def __post_init__(self) -> None:
        K, n = self.layout.size, self.nominal.n
        self.cost, self.norm, self.kernel = Cost(self.cost), Norm(self.norm), Kernel(self.kernel)
        if self.layout.n != n:
            raise ValueError(f"layout: made for {self.layout.n} joints, the robot has {n}")
        if self.data.q.shape[1] != n:
            raise ValueError(f"{self.data.source}: {self.data.q.shape[1]} joint values per pose, the robot has {n} joints")
        if not (np.isfinite(self.orientation_weight) and self.orientation_weight >= 0):
            raise ValueError(f"problem.orientation_weight: must be a number >= 0, got {self.orientation_weight}")
        self.lower = np.broadcast_to(np.asarray(self.lower, dtype=float), (K,)).copy()
        self.upper = np.broadcast_to(np.asarray(self.upper, dtype=float), (K,)).copy()
        if not np.all(self.lower < self.upper):
            k = int(np.argmin(self.upper - self.lower))
            raise ValueError(f"gene range of {self.layout.names[k]}: lower {self.lower[k]} is not below upper {self.upper[k]}")
        data = self.data
        self.n_rows = (3 if data.position_only else 6) * data.M + n
        self._position_weights = np.ones((data.M, 3)) if data.weights is None else data.weights
        pose = self._position_weights
        if not data.position_only:
            pose = np.hstack([np.full((data.M, 3), self.orientation_weight), pose])
        self._row_weights = np.concatenate([pose.ravel(), np.full(n, float(self.unit_weight))])
        self._groups = self._tool_groups()
        spec = self.layout.terms  # non-geometric terms: their features at each group's poses, on the nominal arm
        self._phi = [terms.features(spec, self.nominal, data.q[rows]) if spec else None for _, rows, *_ in self._groups]
        self.J_nominal = self._jacobian(np.zeros(K), exact=False)
        self.y_nominal = self._residual(np.zeros(K))  # [dr; dp; 0] of the nominal robot

    def _tool_groups(self) -> list[tuple[int, NDArray[np.intp] | slice, tuple[Array, Array, Array], Array, Array | None, Array]]:
        """Per tool with poses: (tool, rows, joint terms, positions, orientations, weights); one
        group holding every pose (rows a full slice) when the data name one tool."""
        data, tools = self.data, self.data.tools
        if tools.max(initial=0) >= self.layout.n_tools:
            raise ValueError(f"{data.source}: tool {data.tool_names[int(tools.max())]!r} has no genes in the layout "
                             f"({self.layout.n_tools} tools)")  # fmt: skip
        groups = []
        for k in np.unique(tools):
            rows = slice(None) if np.all(tools == k) else np.flatnonzero(tools == k)
            R = None if data.R is None else np.ascontiguousarray(data.R[rows])
            terms = kinematics.joint_terms(data.q[rows], self.nominal.prismatic)
            groups.append((int(k), rows, terms, np.ascontiguousarray(data.p[rows]), R,
                           np.ascontiguousarray(self._position_weights[rows])))  # fmt: skip
        return groups

    @property
    def names(self) -> list[str]:
        return self.layout.names

    @property
    def gene_blocks(self) -> list[tuple[int, int]]:
        """The layout's gene blocks as [start, stop) (axes, body vectors, base, hand, tools)."""
        return [(s.start, s.stop) for s in self.layout.blocks.values()]

    # --- a population -----------------------------------------------------------------------
    def costs(self, X: ArrayLike) -> Array:
        """Cost of every genome of X (P, K), (P,); NaN or inf where the genes break the model."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        with np.errstate(all="ignore"):
            if self.cost is Cost.linear:
                r = self.y_nominal[None] - X @ self.J_nominal.T
                total = np.einsum("pr,pr->p", r, r)
            else:
                m = self.layout.unpack(self.nominal, X)
                sums = np.zeros((2, X.shape[0]))
                for (k, rows, jt, p, R, w), phi in zip(self._groups, self._phi):
                    t = m.for_tool(k)
                    if phi is not None:  # each genome's own joint angles
                        assert m.theta is not None  # unpack sets the term genes whenever the layout has terms
                        dq = terms.offsets(self.layout.terms, self.nominal.n, phi, m.theta)
                        jt = kinematics.joint_terms_lanes(self.data.q[rows], dq, self.nominal.prismatic)
                    sums = sums + kinematics.residual_sums_unchecked(t.U, t.B, t.H, jt, p, R, w, kernel=self.kernel.value)
                unit = 0.5 * (m.length2 - 1.0)
                total = self.orientation_weight**2 * sums[0] + sums[1] + self.unit_weight**2 * np.einsum("ip,ip->p", unit, unit)
            if self.norm is Norm.rms:
                total = total / self.n_rows
            return np.sqrt(total)

    # --- one genome ---------------------------------------------------------------------------
    def residual(self, x: ArrayLike) -> Array:
        """Weighted residual vector (rows,) of one genome under this problem's cost."""
        x = np.asarray(x, dtype=float)
        if self.cost is Cost.linear:
            return self.y_nominal - self.J_nominal @ x
        return self._residual(x)

    def jacobian(self, x: ArrayLike) -> Array:
        """Jacobian of the model with respect to x, so that ``residual(x + d) ~ residual(x) - J d``."""
        if self.cost is Cost.linear:
            return self.J_nominal
        return self._jacobian(np.asarray(x, dtype=float), exact=True)

    def _poses(self, m) -> tuple[Array, Array]:
        """Modelled hand orientations (M, 3, 3) and positions (M, 3) of one genome's model arrays
        at every pose, each with its tool."""
        data = self.data
        R, p = np.empty((data.M, 3, 3)), np.empty((data.M, 3))
        for k, rows, *_ in self._groups:
            u0, b0, R_h0 = m.for_tool(k).population_first()
            q = data.q[rows] if m.theta is None else self._effective_q(m)[rows]
            R[rows], p[rows] = (a[0] for a in kinematics.forward_batch(u0, b0, R_h0, q, self.nominal.prismatic))
        return R, p

    def _effective_q(self, m) -> Array:
        """The joint values (M, n) the first genome of model arrays ``m`` turns its joints to
        (the commanded ones plus its terms' offsets)."""
        q = self.data.q.copy()
        for (_, rows, *_), phi in zip(self._groups, self._phi):
            if phi is not None:
                q[rows] += terms.offsets(self.layout.terms, self.nominal.n, phi, m.theta[:, 0])
        return q

    def _residual(self, x: Array) -> Array:
        """Nonlinear weighted residual: per pose [w dr; dp] (or dp), then -(|u0 + du0|^2 - 1) / 2."""
        data = self.data
        R, p = self._poses(self.layout.unpack(self.nominal, x))
        dp = data.p - p
        pose = dp if data.R is None else np.hstack([error_model.pose_error(data.R, data.p, R, p)[0], dp])
        du0 = self.layout.expand(x)[: 3 * self.nominal.n].reshape(-1, 3)  # every axis, fixed ones at nominal
        unit = -0.5 * (np.sum((self.nominal.u0 + du0) ** 2, axis=1) - 1.0)
        return np.concatenate([pose.ravel(), unit]) * self._row_weights

    def _jacobian(self, x: Array, exact: bool) -> Array:
        """Stacked, weighted error Jacobian at ``x``. ``exact``: the orientation rows are the
        derivative of this problem's residual ``vee(skew(W))``, ``W = R_meas R^T``, which is
        ``(tr(W) I - W^T) / 2`` times the paper's J1 rows (equal when W = I)). The columns of
        the genome's genes: computed for all genes, then mapped (:meth:`Layout.columns`)."""
        m = self.layout.unpack(self.nominal, x)
        x = self.layout.expand(x)
        data, n, blocks = self.data, self.nominal.n, self.layout.unmasked.blocks
        raw = self.nominal.u0 + x[blocks["u0"]].reshape(n, 3)
        length = np.linalg.norm(raw, axis=1)
        unit = raw / length[:, None]
        J = self._tool_jacobians(unit, m, compiled=exact)
        if self.layout.terms:
            J[:, :, blocks["terms"]] = self._term_columns(unit, m)
        if data.R is None:  # position only
            J = J[:, 3:]
        elif exact:
            if self.layout.hand:  # dexp of the hand rotation vector: its left Jacobian
                J[:, :3, blocks["hand"]] = J[:, :3, blocks["hand"]] @ so3.left_jacobian(x[blocks["hand"]])
            R, _ = self._poses(m)
            W = data.R @ np.swapaxes(R, -1, -2)
            G = 0.5 * (np.trace(W, axis1=1, axis2=2)[:, None, None] * np.eye(3) - np.swapaxes(W, -1, -2))
            J[:, :3] = G @ J[:, :3]
        # chain rule through the normalisation u / |u|: (I - u_hat u_hat^T) / |u|
        N = (np.eye(3) - unit[:, :, None] * unit[:, None, :]) / length[:, None, None]
        Ju = J[..., : 3 * n].reshape(J.shape[:2] + (n, 3))
        J[..., : 3 * n] = np.einsum("mrik,ikl->mril", Ju, N).reshape(J.shape[:2] + (3 * n,))
        U = np.zeros((n, self.layout.full_size))
        for i in range(n):
            U[i, 3 * i : 3 * i + 3] = raw[i]
        J = np.vstack([J.reshape(-1, J.shape[-1]), U]) * self._row_weights[:, None]
        return self.layout.columns(J)  # J N: the chain rule through x = N z (the free columns for a plain mask)

    def _term_columns(self, unit: Array, m) -> Array:
        """Columns (M, 6, F) of the term genes: the joint's column of the geometric Jacobian at the
        effective joint values times the term's feature, ``d pose / d q_j * phi_f``."""
        import types

        q, out = self._effective_q(m), np.empty((self.data.M, 6, self.layout.terms.size))
        joints = self.layout.terms.joints
        for (k, rows, *_), phi in zip(self._groups, self._phi):
            arm = types.SimpleNamespace(u0=unit, b0=m.for_tool(k).B[:, :, 0], R_h0=m.H[:, :, 0], prismatic=self.nominal.prismatic,
                                        n=self.nominal.n)  # fmt: skip
            Jq = terms.joint_jacobian(arm, q[rows])
            assert phi is not None  # every group has its features when the layout has terms
            out[rows] = Jq[:, :, joints] * phi[:, None, :]
        return out

    def _tool_jacobians(self, unit: Array, m, compiled: bool) -> Array:
        """Pose Jacobians (M, 6, K) at the unit axes ``unit`` (n, 3) and one genome's model
        arrays: each tool's poses with its last body vector, whose columns are that tool's genes.
        ``compiled``: the compiled Jacobian (the pseudo-inverse step and LM call it often), else
        the numpy reference (the nominal Jacobian, computed once: bit for bit zrp_ga 0.1's)."""
        data, layout, n = self.data, self.layout.unmasked, self.nominal.n
        q = data.q if m.theta is None else self._effective_q(m)
        if len(self._groups) == 1 and self._groups[0][0] == 0 and not layout.tools:
            Jg = error_model.jacobian_arrays(unit, m.B[:, :, 0], self.nominal.prismatic, q, layout.base, layout.hand, compiled)
            return Jg if not layout.terms else np.concatenate([Jg, np.zeros((data.M, 6, layout.terms.size))], axis=2)
        J = np.zeros((data.M, 6, layout.size))
        core = 6 * n + 3 * layout.base + 3 * layout.hand
        end = slice(6 * n - 3, 6 * n)  # db0_{n+1}: tool 1's last body vector
        for k, rows, *_ in self._groups:
            Jk = error_model.jacobian_arrays(unit, m.for_tool(k).B[:, :, 0], self.nominal.prismatic, q[rows],
                                             layout.base, layout.hand, compiled)  # fmt: skip
            if k:
                J[rows, :, layout.blocks[f"tool{k + 1}"]] = Jk[:, :, end]
                Jk[:, :, end] = 0.0
            J[rows, :, :core] = Jk
        return J

    def identifiability(self) -> error_model.IdentifiabilityReport:
        """Identifiability report of the calibration poses (Jacobian at the nominal parameters)."""
        return error_model.identifiability(self._jacobian(np.zeros(self.layout.size), exact=False), self.names, self.nominal)


def model_rank(nominal: ZRPRobot, layout: Layout, position_only: bool, n_poses: int = 60) -> int:
    """Rank of the stacked error Jacobian (unit rows included) of ``layout`` over ``n_poses``
    random poses (``numpy.random.default_rng(0)``) shared round-robin by its tools: what the
    model can identify at best with this kind of data."""
    from zrp_ga.model.simulation import random_joints

    T = layout.n_tools
    q = random_joints(nominal, max(n_poses, T), np.random.default_rng(0))
    R = None if position_only else np.broadcast_to(np.eye(3), (len(q), 3, 3))
    data = Measurements(q, np.zeros((len(q), 3)), R, tool=np.arange(len(q)) % T, tool_names=tuple(map(str, range(T))))
    K = layout.size
    return int(np.linalg.matrix_rank(CalibrationProblem(nominal, data, layout, -np.ones(K), np.ones(K)).J_nominal))
