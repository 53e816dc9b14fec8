"""Terms beyond geometry: joint compliance under gravity and joint-angle harmonics, both as
offsets added to a joint's angle (docs/model.md, section "Beyond geometry"):

    q_eff,j = q_j + c_j tau_j(q) + sum_{k=1}^{order} (a_jk sin(k q_j) + b_jk cos(k q_j))

- **compliance** of joint j: ``c_j`` (rad/(N m)) times the gravity torque about axis j,
  ``tau_j = u_j . sum_k (x_k - o_j) x (m_k g)`` over the masses k that joint j carries (the links
  after it and the payload), ``o_j`` a point on axis j, ``x_k`` mass k's centre, g along the
  base's -z (:data:`GRAVITY`). A positive ``c_j`` turns the joint the way gravity pulls it.
- **harmonics** of joint j: ``a_jk`` and ``b_jk`` (rad) of the commanded angle, k = 1..order.

The mass model (:class:`MassModel`) gives each link's mass and centre: from the URDF's
``<inertial>`` elements when the arm came from a URDF (:func:`zrp_ga.io.urdf.mass_model`), else
:func:`generic`: a point mass at the middle of each link, proportional to its length
(:data:`GENERIC_KG_PER_M`), so that a fitted ``c_j`` then carries that assumed density (only the
masses' ratios and places matter to the shape of the deflection). A payload (mass, kg; centre in
the hand frame from the end point, m) adds to the last link.

In a fit, each term's value at a pose is a fixed **feature** computed once from the commanded
angles on the nominal arm (:func:`features`): the torque changes by the geometric errors over the
link lengths (1e-3 relative), a second-order change of a deflection of 1e-4..1e-3 rad; the joint
offsets are then linear in the term genes, ``dq = phi theta`` (:func:`offsets`). A robot that
carries terms (:class:`Terms`, ``ZRPRobot.terms``) evaluates them on its own geometry
(:func:`deflection`). Terms apply to revolute joints only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
GRAVITY = np.array([0.0, 0.0, -9.80665])  # m/s^2, along the base frame's -z
GENERIC_KG_PER_M = 10.0  # the generic mass model: kg per metre of link length


@dataclasses.dataclass(frozen=True, eq=False)
class MassModel:
    """Masses ``masses`` (n,) kg of the links (link i: the body joint i moves, up to joint i+1;
    link n carries the hand) and their centres ``centres`` (n, 3) m at q = 0 in the world frame,
    relative to the point on axis i (ZRP's frames are world-aligned at q = 0); a payload
    ``payload_mass`` kg with its centre ``payload_com`` (3,) m in the hand frame from the end
    point; ``source`` says where the numbers came from."""

    masses: Array
    centres: Array
    payload_mass: float = 0.0
    payload_com: Array = dataclasses.field(default_factory=lambda: np.zeros(3))
    source: str = "given"
    gravity: Array = dataclasses.field(default_factory=lambda: GRAVITY.copy())  # m/s^2 in the robot's world frame

    def __post_init__(self) -> None:
        m = np.array(self.masses, dtype=float).ravel()
        c = np.array(self.centres, dtype=float).reshape(len(m), 3)
        com = np.array(self.payload_com, dtype=float).reshape(3)
        g = np.array(self.gravity, dtype=float).reshape(3)
        if not (np.all(np.isfinite(m)) and np.all(m >= 0) and np.all(np.isfinite(c)) and np.all(np.isfinite(com))):
            raise ValueError("mass model: masses must be finite and >= 0, centres finite")
        if not (np.isfinite(self.payload_mass) and self.payload_mass >= 0):
            raise ValueError(f"payload: mass must be a number >= 0 kg, got {self.payload_mass}")
        if not np.all(np.isfinite(g)):
            raise ValueError("mass model: gravity must be finite")
        for name, value in (("masses", m), ("centres", c), ("payload_com", com), ("gravity", g)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "payload_mass", float(self.payload_mass))

    def with_payload(self, mass: float, com: ArrayLike) -> MassModel:
        return dataclasses.replace(self, payload_mass=float(mass), payload_com=np.asarray(com, dtype=float))

    def rotated(self, R: ArrayLike) -> MassModel:
        """The same masses seen from a frame turned by R (3, 3): centres and gravity turn with it."""
        R = np.asarray(R, dtype=float)
        return dataclasses.replace(self, centres=self.centres @ R.T, gravity=R @ self.gravity)

    def to_dict(self) -> dict:
        return {"source": self.source, "masses": self.masses.tolist(), "centres": self.centres.tolist(),
                "payload_mass": self.payload_mass, "payload_com": self.payload_com.tolist(), "gravity": self.gravity.tolist()}  # fmt: skip

    @classmethod
    def from_dict(cls, data: Mapping, n: int, source: str = "mass") -> MassModel:
        if not isinstance(data, Mapping) or "masses" not in data or "centres" not in data:
            raise ValueError(f"{source}: expected a mapping with masses and centres")
        try:
            out = cls(np.asarray(data["masses"], dtype=float), np.asarray(data["centres"], dtype=float),
                      float(data.get("payload_mass", 0.0)), np.asarray(data.get("payload_com", [0, 0, 0]), dtype=float),
                      str(data.get("source", "given")), np.asarray(data.get("gravity", GRAVITY), dtype=float))  # fmt: skip
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{source}: {exc}") from None
        if len(out.masses) != n:
            raise ValueError(f"{source}: {len(out.masses)} masses, the robot has {n} joints")
        return out


def generic(robot) -> MassModel:
    """The generic mass model of ``robot``: link i a point mass ``GENERIC_KG_PER_M * |b0_{i+1}|``
    at the middle of its body vector (the last link: of the vector to the end point)."""
    lengths = np.linalg.norm(robot.b0[1:], axis=1)
    return MassModel(GENERIC_KG_PER_M * lengths, 0.5 * robot.b0[1:], source=f"generic: {GENERIC_KG_PER_M:g} kg/m at link midpoints")


@dataclasses.dataclass(frozen=True)
class TermSpec:
    """Which terms a model has: compliance on the joints ``compliance`` (1-based), harmonics of
    order ``order`` on the joints ``harmonics``. Its :attr:`names` are the term genes' names, in
    the genome's order: ``compliance_j`` (rad/(N m)), then ``harmonic_j_sinK``, ``harmonic_j_cosK``
    (rad)."""

    compliance: tuple[int, ...] = ()
    harmonics: tuple[int, ...] = ()
    order: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "compliance", tuple(sorted({int(j) for j in self.compliance})))
        object.__setattr__(self, "harmonics", tuple(sorted({int(j) for j in self.harmonics})))
        object.__setattr__(self, "order", int(self.order))

    def __bool__(self) -> bool:
        return bool(self.compliance or self.harmonics)

    @property
    def names(self) -> list[str]:
        out = [f"compliance_{j}" for j in self.compliance]
        for j in self.harmonics:
            for k in range(1, self.order + 1):
                out += [f"harmonic_{j}_sin{k}", f"harmonic_{j}_cos{k}"]
        return out

    @property
    def size(self) -> int:
        return len(self.compliance) + 2 * self.order * len(self.harmonics)

    @property
    def joints(self) -> NDArray[np.intp]:
        """The 0-based joint of each term gene (F,)."""
        out = [j - 1 for j in self.compliance]
        for j in self.harmonics:
            out += [j - 1] * (2 * self.order)
        return np.array(out, dtype=np.intp)

    def check(self, robot, key: str = "problem.terms") -> None:
        """ValueError naming ``key`` where a joint is out of range or prismatic."""
        for what, joints in (("compliance", self.compliance), ("harmonics", self.harmonics)):
            for j in joints:
                if not 1 <= j <= robot.n:
                    raise ValueError(f"{key}.{what}: joint {j} is not a joint of {robot.name} (1..{robot.n})")
                if robot.prismatic[j - 1]:
                    raise ValueError(f"{key}.{what}: joint {j} is prismatic; terms apply to revolute joints")
        if self.harmonics and not 1 <= self.order <= 10:
            raise ValueError(f"{key}.harmonics.order: must be 1..10, got {self.order}")

    def to_dict(self) -> dict:
        out: dict[str, Any] = {}
        if self.compliance:
            out["compliance"] = list(self.compliance)
        if self.harmonics:
            out["harmonics"] = {"order": self.order, "joints": list(self.harmonics)}
        return out


def _joint_list(value: Any, key: str) -> tuple[int, ...]:
    if value is None:
        return ()
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        value = [value]
    if isinstance(value, (str, Mapping)) or not isinstance(value, Iterable):
        raise ValueError(f"{key}: expected a list of joint numbers (1-based), got {value!r}")
    out: list[int] = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ValueError(f"{key}: expected joint numbers (1-based integers), got {v!r}")
        if int(v) in out:  # two genes of one effect: neither identifiable
            raise ValueError(f"{key}: joint {int(v)} named twice")
        out.append(int(v))
    return tuple(out)


def parse(value: Any, key: str = "problem.terms") -> tuple[TermSpec, tuple[float, Array] | None]:
    """The term spec and the payload (mass kg, centre (3,) m in the hand frame; None: none given)
    of the setting ``problem.terms``, a mapping (or None / empty: no terms)::

        {compliance: [2, 3], harmonics: {order: 1, joints: [1]}, payload: {mass: 5, com: [0, 0, 0.1]}}

    ``harmonics`` may also be a plain list of joints (order 1). ValueError naming the key."""
    if value is None or (isinstance(value, (Mapping, list, tuple, str)) and len(value) == 0):
        return TermSpec(), None
    if not isinstance(value, Mapping):
        raise ValueError(f"{key}: expected a mapping such as '{{compliance: [2, 3], harmonics: {{order: 1, joints: [1]}}}}', got {value!r}")
    unknown = sorted(set(map(str, value)) - {"compliance", "harmonics", "payload"})
    if unknown:
        raise ValueError(f"{key}: unknown key {unknown[0]!r}; valid: compliance, harmonics, payload")
    compliance = _joint_list(value.get("compliance"), f"{key}.compliance")
    h = value.get("harmonics")
    order = 1
    if isinstance(h, Mapping):
        bad = sorted(set(map(str, h)) - {"order", "joints"})
        if bad:
            raise ValueError(f"{key}.harmonics: unknown key {bad[0]!r}; valid: order, joints")
        order = h.get("order", 1)
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= 10:
            raise ValueError(f"{key}.harmonics.order: must be an integer 1..10, got {order!r}")
        harmonics = _joint_list(h.get("joints"), f"{key}.harmonics.joints")
        if not harmonics:  # an order alone would fit nothing
            raise ValueError(f"{key}.harmonics.joints: no joint named; give the joints whose angles have harmonics, "
                             "e.g. {order: 2, joints: [1]}")  # fmt: skip
    else:
        harmonics = _joint_list(h, f"{key}.harmonics")
    payload = None
    if value.get("payload") is not None:
        pl = value["payload"]
        if not isinstance(pl, Mapping) or set(map(str, pl)) - {"mass", "com"}:
            raise ValueError(f"{key}.payload: expected {{mass: KG, com: [x, y, z]}} (com in m, hand frame), got {pl!r}")
        try:
            mass, com = float(pl.get("mass", 0.0)), np.asarray(pl.get("com", [0.0, 0.0, 0.0]), dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise ValueError(f"{key}.payload: expected {{mass: KG, com: [x, y, z]}} (com in m, hand frame), got {pl!r}") from None
        if not (np.isfinite(mass) and mass >= 0 and np.all(np.isfinite(com))):
            raise ValueError(f"{key}.payload: mass must be >= 0 kg and com finite, got {pl!r}")
        payload = (mass, com)
    return TermSpec(compliance, harmonics, int(order)), payload


@dataclasses.dataclass(frozen=True, eq=False)
class Terms:
    """A spec with its values (F,) (the genes' units: rad/(N m), rad)."""

    spec: TermSpec
    values: Array

    def __post_init__(self) -> None:
        v = np.array(self.values, dtype=float).ravel()
        if v.shape != (self.spec.size,) or not np.all(np.isfinite(v)):
            raise ValueError(f"terms: expected {self.spec.size} finite values ({', '.join(self.spec.names)}), got {self.values!r}")
        v.setflags(write=False)
        object.__setattr__(self, "values", v)

    def to_dict(self) -> dict:
        """The YAML form: ``compliance: {joint: c}`` (rad/(N m)), ``harmonics: {order: K, joints:
        {joint: {sin: [a_1..a_K], cos: [b_1..b_K]}}}`` (rad)."""
        values = dict(zip(self.spec.names, self.values.tolist()))
        out: dict[str, Any] = {}
        if self.spec.compliance:
            out["compliance"] = {j: values[f"compliance_{j}"] for j in self.spec.compliance}
        if self.spec.harmonics:
            out["harmonics"] = {"order": self.spec.order, "joints": {
                j: {w: [values[f"harmonic_{j}_{w}{k}"] for k in range(1, self.spec.order + 1)] for w in ("sin", "cos")}
                for j in self.spec.harmonics}}  # fmt: skip
        return out

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "terms") -> Terms:
        try:
            comp = {int(j): float(c) for j, c in (data.get("compliance") or {}).items()}
            h = dict(data.get("harmonics") or {})
            order = int(h.get("order", 1))
            harm = {int(j): v for j, v in (h.get("joints") or {}).items()}
            spec = TermSpec(tuple(comp), tuple(harm), order)
            named = {f"compliance_{j}": c for j, c in comp.items()}
            for j, v in harm.items():
                for w in ("sin", "cos"):
                    seq = list(v[w])
                    if len(seq) != order:
                        raise ValueError(f"harmonics of joint {j}: {len(seq)} {w} values, order {order}")
                    named.update({f"harmonic_{j}_{w}{k}": float(seq[k - 1]) for k in range(1, order + 1)})
            return cls(spec, np.array([named[k] for k in spec.names]))
        except (AttributeError, KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{source}: bad terms ({exc})") from None


# --- the physics -----------------------------------------------------------------------------------
def frames(robot, q: ArrayLike) -> tuple[Array, Array, Array, Array]:
    """Axes ``u_i`` (M, n, 3), points ``o_i`` on them (M, n, 3) m, the rotations ``R_i`` (M, n, 3, 3)
    after each joint and the end point p (M, 3) m at joint values q (M, n) (Eq. 1-5, numpy)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    M, n = q.shape
    R = np.broadcast_to(np.eye(3), (M, 3, 3)).copy()
    p = np.zeros((M, 3))
    axes, points, rots = np.empty((M, n, 3)), np.empty((M, n, 3)), np.empty((M, n, 3, 3))
    for i in range(n):
        p = p + R @ robot.b0[i]
        axes[:, i], points[:, i] = R @ robot.u0[i], p
        if robot.prismatic[i]:
            p = p + q[:, i, None] * axes[:, i]
        else:
            R = R @ _rodrigues(q[:, i], robot.u0[i] / np.linalg.norm(robot.u0[i]))
        rots[:, i] = R
    return axes, points, rots, p + R @ robot.b0[n]


def _rodrigues(q: Array, u: Array) -> Array:
    """R(q, u) = cos q I + sin q [u]x + (1 - cos q) u u^T (Eq. 6-8) for angles q (M,): (M, 3, 3)."""
    c, s = np.cos(q)[:, None, None], np.sin(q)[:, None, None]
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return c * np.eye(3) + s * K + (1.0 - c) * np.outer(u, u)


def joint_jacobian(robot, q: ArrayLike) -> Array:
    """The geometric Jacobian (M, 6, n) at joint values q (M, n): rows 0-2 the hand's rotation,
    3-5 the end point's displacement per unit joint motion, ``[u_j; u_j x (p - o_j)]`` for a
    revolute joint, ``[0; u_j]`` for a prismatic one."""
    axes, points, _, p = frames(robot, q)
    J = np.empty((len(p), 6, robot.n))
    J[:, :3] = np.swapaxes(axes, 1, 2)
    J[:, 3:] = np.swapaxes(np.cross(axes, p[:, None] - points), 1, 2)
    J[:, :3, robot.prismatic] = 0.0
    J[:, 3:, robot.prismatic] = np.swapaxes(axes[:, robot.prismatic], 1, 2)
    return J


def gravity_torques(robot, q: ArrayLike, mass: MassModel | None = None) -> Array:
    """Gravity torques (M, n) N m about every joint axis at joint values q (M, n) (or (n,) giving
    (n,)), ``tau_j = u_j . sum_{k >= j} (x_k - o_j) x (m_k g)``, the payload with link n; 0 for a
    prismatic joint; g is ``mass.gravity``. ``mass``: default the robot's (``robot.mass``) or
    :func:`generic`."""
    q = np.asarray(q, dtype=float)
    one = q.ndim == 1
    mass = mass or getattr(robot, "mass", None) or generic(robot)
    axes, points, rots, p = frames(robot, q)
    g = mass.gravity
    x = points + np.einsum("mnab,nb->mna", rots, mass.centres)  # (M, n, 3) link centres
    f = mass.masses[None, :, None] * g  # (1, n, 3) forces
    moments = np.cross(x, f)  # about the origin; about o_j: sum (x_k - o_j) x f_k = sum x_k x f_k - o_j x sum f_k
    forces = np.broadcast_to(f, x.shape)
    if mass.payload_mass:
        xp = p + np.einsum("mab,b->ma", rots[:, -1] @ robot.R_h0, mass.payload_com)
        fp = mass.payload_mass * g
        moments = np.concatenate([moments, np.cross(xp, fp)[:, None]], axis=1)
        forces = np.concatenate([forces, np.broadcast_to(fp, (len(p), 1, 3))], axis=1)
    # carried by joint j: links j..n (and the payload): reverse cumulative sums
    M_tail = np.cumsum(moments[:, ::-1], axis=1)[:, ::-1][:, : robot.n]
    F_tail = np.cumsum(forces[:, ::-1], axis=1)[:, ::-1][:, : robot.n]
    tau = np.einsum("mnk,mnk->mn", axes, M_tail - np.cross(points, F_tail))
    tau[:, robot.prismatic] = 0.0
    return tau[0] if one else tau


def features(spec: TermSpec, robot, q: ArrayLike, mass: MassModel | None = None) -> Array:
    """The value of each term gene's feature at every pose (M, F): the gravity torque (N m) of a
    compliance term, ``sin(k q_j)``, ``cos(k q_j)`` of a harmonic; ``dq_j = sum_f phi_f theta_f``
    over the genes f of joint j."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    cols = []
    if spec.compliance:
        tau = gravity_torques(robot, q, mass)
        cols += [tau[:, j - 1] for j in spec.compliance]
    for j in spec.harmonics:
        for k in range(1, spec.order + 1):
            cols += [np.sin(k * q[:, j - 1]), np.cos(k * q[:, j - 1])]
    return np.stack(cols, axis=1) if cols else np.zeros((len(q), 0))


def offsets(spec: TermSpec, n: int, phi: Array, theta: ArrayLike) -> Array:
    """Joint offsets (M, n, P) of term genes theta (F, P) (or (F,), giving (M, n)) from the
    features phi (M, F): ``dq[m, j, p] = sum_{f of joint j} phi[m, f] theta[f, p]``."""
    theta = np.asarray(theta, dtype=float)
    one = theta.ndim == 1
    theta = theta.reshape(spec.size, -1)
    out = np.zeros((phi.shape[0], n, theta.shape[1]))
    for f, j in enumerate(spec.joints):
        out[:, j] += phi[:, f, None] * theta[f][None]
    return out[..., 0] if one else out


def deflection(robot, q: ArrayLike) -> Array:
    """The joint offsets (M, n) (or (n,)) of a robot carrying terms at joint values q: zero without."""
    q = np.asarray(q, dtype=float)
    t = getattr(robot, "terms", None)
    if t is None or not t.spec:
        return np.zeros_like(q)
    return offsets(t.spec, robot.n, features(t.spec, robot, q), t.values).reshape(q.shape)


def effective(robot, q: ArrayLike) -> Array:
    """The joint values the arm takes, ``q + deflection(robot, q)``."""
    q = np.asarray(q, dtype=float)
    return q + deflection(robot, q)


def effective_derivative(robot, q: ArrayLike, step: float = 1e-6) -> Array:
    """``d q_eff / d q`` (n, n) at one q (n,), by central differences (I without terms)."""
    q = np.asarray(q, dtype=float)
    n = len(q)
    if getattr(robot, "terms", None) is None:
        return np.eye(n)
    E = np.eye(n) * step
    return np.stack([(effective(robot, q + e) - effective(robot, q - e)) / (2 * step) for e in E], axis=1)
