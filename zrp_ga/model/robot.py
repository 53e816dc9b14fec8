"""The ZRP description of a serial arm, its validation, DH conversion and YAML form.

A :class:`ZRPRobot` holds, for the reference position q = 0 and in the world frame
(docs/model.md, section 1): the unit joint axes ``u0`` (n, 3), the body vectors ``b0`` (n+1, 3)
(``b0[0]`` from the world origin to a point on axis 1, ``b0[i]`` from the point on axis i to the
point on axis i+1, ``b0[n]`` to the end-effector point), the hand orientation ``R_h0`` (3, 3)
and the joint types, ``"R"`` (revolute, rad) or ``"P"`` (prismatic, m). Lengths are metres.
Optional: the joint names and the joint limits (n, 2), lower and upper, rad or m;
:attr:`ZRPRobot.joint_limits` fills in :data:`DEFAULT_LIMITS` where none are given.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from zrp_ga.core.fileio import yaml_text
from zrp_ga.model import so3
from zrp_ga.model.terms import MassModel, Terms

UNIT_TOL = 1e-9
# Joint range assumed when a robot states none: revolute rad, prismatic m.
DEFAULT_LIMITS = {"R": (-np.pi, np.pi), "P": (0.0, 0.5)}
# Robot files with larger numbers are refused as absurd (zrp_ga.io.robot_files): m, rad (16 turns).
MAX_LENGTH_M = 1e4
MAX_ANGLE_RAD = 100.0


def _array(name: str, value: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not an array of numbers ({exc})") from None
    if a.shape != shape:
        want = "(" + ", ".join(map(str, shape)) + ")"
        raise ValueError(f"{name}: expected shape {want}, got {a.shape}")
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        raise ValueError(f"{name}: NaN or inf at index {tuple(int(i) for i in bad[0])}")
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class ZRPRobot:
    """A serial arm in the Zero Reference Position model; validates itself on construction.

    ``normalize=True`` rescales joint axes that are not of unit length; by default such axes
    are refused. Arrays are copied and made read-only. ``joint_names`` (n distinct strings) and
    ``limits`` (n, 2: lower < upper, rad for revolute and m for prismatic joints) are optional
    (None); :attr:`joint_limits` is always an (n, 2) array.

    >>> r = ZRPRobot(u0=[[0, 0, 1]], b0=[[0, 0, 0.5], [1.0, 0, 0]], joint_types="R")
    >>> r.n, r.b0.shape
    (1, (2, 3))
    >>> r.joint_limits
    array([[-3.14159265,  3.14159265]])
    """

    u0: NDArray[np.float64]
    b0: NDArray[np.float64]
    R_h0: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.eye(3))
    joint_types: str = ""
    name: str = "robot"
    joint_names: tuple[str, ...] | None = None
    limits: NDArray[np.float64] | None = None
    normalize: dataclasses.InitVar[bool] = False
    # Where the arm was read from (zrp_ga.io.urdf.URDFSource for a URDF), so that exports can write
    # the calibrated arm into that file; kept by replace(), not part of the YAML form.
    source: object = dataclasses.field(default=None, repr=False)
    # Beyond geometry (zrp_ga.model.terms): the mass model (URDF inertials, a robot file's, or None:
    # the generic one where needed) and fitted terms (compliance, harmonics; None: geometric only).
    mass: MassModel | None = dataclasses.field(default=None, repr=False)
    terms: Terms | None = dataclasses.field(default=None, repr=False)

    def __post_init__(self, normalize: bool) -> None:
        u0 = np.array(self.u0, dtype=float) if np.ndim(self.u0) == 2 else None
        n = u0.shape[0] if u0 is not None else -1
        if u0 is None or n < 1:
            raise ValueError(f"u0: expected shape (n, 3) with n >= 1, got {np.shape(self.u0)}")
        u0 = _array("u0", u0, (n, 3))
        lengths = np.linalg.norm(u0, axis=1)
        for i, length in enumerate(lengths):
            if length < 1e-12:
                raise ValueError(f"u0: axis of joint {i + 1} has length zero")
            if abs(length - 1.0) > UNIT_TOL and not normalize:
                raise ValueError(
                    f"u0: axis of joint {i + 1} has length {length:.12g}, not 1 "
                    "(pass normalize=True to rescale it)"
                )
        u0 = u0 / lengths[:, None]
        b0 = _array("b0", self.b0, (n + 1, 3))
        R_h0 = _array("R_h0", self.R_h0, (3, 3))
        if not np.allclose(R_h0.T @ R_h0, np.eye(3), atol=1e-9) or np.linalg.det(R_h0) < 0:
            raise ValueError("R_h0: not a rotation matrix (R^T R != I or det(R) != 1)")
        types = self.joint_types or "R" * n
        if not isinstance(types, str) or len(types) != n:
            raise ValueError(f"joint_types: expected a string of {n} letters R/P, got {types!r}")
        for i, t in enumerate(types):
            if t not in "RP":
                raise ValueError(f"joint_types: joint {i + 1} is {t!r}, expected 'R' or 'P'")
        limits = None if self.limits is None else _limits(self.limits, n)
        for attr, value in (("u0", u0), ("b0", b0), ("R_h0", R_h0), ("limits", limits)):
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, attr, value)
        object.__setattr__(self, "joint_types", types)
        object.__setattr__(self, "joint_names", _joint_names(self.joint_names, n))
        if self.mass is not None and len(self.mass.masses) != n:
            raise ValueError(f"mass: {len(self.mass.masses)} link masses, the robot has {n} joints")
        if self.terms is not None:
            self.terms.spec.check(self, "terms")
            if not self.terms.spec:
                object.__setattr__(self, "terms", None)

    @property
    def geometric(self) -> ZRPRobot:
        """This arm without its non-geometric terms (what URDF and DH tables carry)."""
        return self if self.terms is None else self.replace(terms=None)

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.u0.shape[0]

    @property
    def prismatic(self) -> NDArray[np.bool_]:
        """(n,) True where the joint is prismatic."""
        return np.array([t == "P" for t in self.joint_types])

    @property
    def joint_limits(self) -> NDArray[np.float64]:
        """(n, 2) lower and upper joint values, rad or m: ``limits``, or :data:`DEFAULT_LIMITS`
        by joint type when the robot states none."""
        if self.limits is not None:
            return self.limits
        return np.array([DEFAULT_LIMITS[t] for t in self.joint_types])

    def replace(self, **changes) -> ZRPRobot:
        """A copy with some fields changed (validated again)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return ZRPRobot(**{**fields, **changes})

    def transformed(self, R: ArrayLike, t: ArrayLike) -> ZRPRobot:
        """The same arm seen from another frame: ``x' = R x + t`` (R (3, 3) rotation, t (3,) m)."""
        R = _array("R", R, (3, 3))
        t = _array("t", t, (3,))
        b0 = self.b0 @ R.T
        b0[0] += t
        mass = None if self.mass is None else self.mass.rotated(R)
        return self.replace(u0=self.u0 @ R.T, b0=b0, R_h0=R @ self.R_h0, normalize=True, mass=mass)

    def with_tool(self, offset: ArrayLike) -> ZRPRobot:
        """The end point moved by ``offset`` (3,), m, given in the hand frame (e.g. a probe on the flange)."""
        b0 = self.b0.copy()
        b0[-1] += self.R_h0 @ _array("tool offset", offset, (3,))
        return self.replace(b0=b0)

    # --- DH tables -------------------------------------------------------------------------
    @classmethod
    def from_dh(
        cls,
        d: Sequence[float] | NDArray[np.float64],
        a: Sequence[float] | NDArray[np.float64],
        alpha: Sequence[float] | NDArray[np.float64],
        offset: Sequence[float] | NDArray[np.float64] | None = None,
        joint_types: str | None = None,
        tool: ArrayLike | None = None,
        base: ArrayLike | None = None,
        name: str = "robot",
        joint_names: Sequence[str] | None = None,
        limits: ArrayLike | None = None,
    ) -> ZRPRobot:
        """From a standard (distal) DH table: ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``.

        ``theta_i = q_i + offset_i`` for a revolute joint, ``d_i + q_i`` for a prismatic one;
        joint i turns about the z axis of frame i-1. ``base`` and ``tool`` are optional 4x4
        transforms before the first and after the last link. Lengths m, angles rad.
        ``joint_names`` and ``limits`` are passed on to the robot.
        """
        n = len(d)
        theta0 = np.zeros(n) if offset is None else np.asarray(offset, dtype=float)
        frames = [np.eye(4) if base is None else _array("base", base, (4, 4))]
        for i in range(n):
            frames.append(frames[-1] @ _dh(theta0[i], d[i], a[i], alpha[i]))
        axis_frames = frames[:-1]  # joint i turns about z of frame i-1
        extra = dict(joint_names=joint_names, limits=limits)
        return cls._from_frames(axis_frames, frames[-1], tool, joint_types, name, **extra)

    @classmethod
    def from_mdh(
        cls,
        d: Sequence[float] | NDArray[np.float64],
        a: Sequence[float] | NDArray[np.float64],
        alpha: Sequence[float] | NDArray[np.float64],
        offset: Sequence[float] | NDArray[np.float64] | None = None,
        joint_types: str | None = None,
        tool: ArrayLike | None = None,
        base: ArrayLike | None = None,
        name: str = "robot",
        joint_names: Sequence[str] | None = None,
        limits: ArrayLike | None = None,
    ) -> ZRPRobot:
        """From a modified (proximal, Craig) DH table: ``A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``.

        Row i holds ``a_{i-1}, alpha_{i-1}, d_i, offset_i``; joint i turns about the z axis of
        frame i.
        """
        n = len(d)
        theta0 = np.zeros(n) if offset is None else np.asarray(offset, dtype=float)
        T = np.eye(4) if base is None else _array("base", base, (4, 4))
        frames = []
        for i in range(n):
            T = T @ _rx(alpha[i]) @ _tx(a[i]) @ _rz(theta0[i]) @ _tz(d[i])
            frames.append(T)
        extra = dict(joint_names=joint_names, limits=limits)
        return cls._from_frames(frames, frames[-1], tool, joint_types, name, **extra)

    @classmethod
    def _from_frames(cls, axis_frames, last, tool, joint_types, name, **extra) -> ZRPRobot:
        """Walk the chain at q = 0: axes are the z axes, points the origins (docs/model.md, section 1)."""
        end = last if tool is None else last @ _array("tool", tool, (4, 4))
        points = np.array([F[:3, 3] for F in axis_frames] + [end[:3, 3]])
        u0 = np.array([F[:3, 2] for F in axis_frames])
        b0 = np.diff(np.vstack([np.zeros(3), points]), axis=0)
        return cls(
            u0=u0, b0=b0, R_h0=end[:3, :3], joint_types=joint_types or "", name=name, normalize=True, **extra
        )

    # --- YAML --------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain-Python form, the same as the YAML file (``joint_names`` and ``limits`` only when given)."""
        data = {
            "name": self.name,
            "joint_types": self.joint_types,
            "u0": self.u0.tolist(),
            "b0": self.b0.tolist(),
            "R_h0": self.R_h0.tolist(),
        }
        if self.joint_names is not None:
            data["joint_names"] = list(self.joint_names)
        if self.limits is not None:
            data["limits"] = self.limits.tolist()
        if self.terms is not None:
            data["terms"] = self.terms.to_dict()
        if self.mass is not None:
            data["mass"] = self.mass.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: dict, source: str = "dict", normalize: bool = False) -> ZRPRobot:
        """From :meth:`to_dict`'s form; errors name ``source`` and the missing or bad key."""
        if not isinstance(data, dict):
            raise ValueError(f"{source}: expected a mapping with keys u0, b0, got {type(data).__name__}")
        missing = [k for k in ("u0", "b0") if k not in data]
        if missing:
            raise ValueError(f"{source}: missing key(s) {', '.join(missing)}")
        unknown = set(data) - {"name", "joint_types", "u0", "b0", "R_h0", "joint_names", "limits", "terms", "mass"}
        if unknown:
            raise ValueError(f"{source}: unknown key(s) {', '.join(sorted(unknown))}")
        try:
            return cls(
                u0=data["u0"],
                b0=data["b0"],
                R_h0=data.get("R_h0", np.eye(3)),
                joint_types=data.get("joint_types", ""),
                name=str(data.get("name", "robot")),
                joint_names=data.get("joint_names"),
                limits=data.get("limits"),
                normalize=normalize,
                mass=None if data.get("mass") is None else MassModel.from_dict(data["mass"], len(data["u0"]), "mass"),
                terms=None if data.get("terms") is None else Terms.from_dict(data["terms"], "terms"),
            )
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None

    @classmethod
    def from_yaml(cls, path: str | Path, normalize: bool = False) -> ZRPRobot:
        """Read a robot written by :meth:`to_yaml`."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text())
        except yaml.YAMLError as exc:
            raise ValueError(f"{path}: malformed YAML ({exc})".replace("\n", " ")) from None
        return cls.from_dict(data, source=str(path), normalize=normalize)

    def to_yaml(self, path: str | Path | None = None) -> str:
        """YAML text of the robot (floats written exactly); also written to ``path`` if given."""
        text = yaml_text(self.to_dict(), sort_keys=False, default_flow_style=None)
        if path is not None:
            Path(path).write_text(text)
        return text

    def __repr__(self) -> str:
        return f"ZRPRobot(name={self.name!r}, n={self.n}, joint_types={self.joint_types!r})"


def _joint_names(names: Sequence[str] | None, n: int) -> tuple[str, ...] | None:
    """``names`` as a tuple of n distinct non-empty strings (None stays None)."""
    if names is None:
        return None
    if isinstance(names, str) or not isinstance(names, Sequence) or len(names) != n:
        raise ValueError(f"joint_names: expected a list of {n} names, got {names!r}")
    for i, name in enumerate(names):
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"joint_names: joint {i + 1} has no name (got {name!r})")
        if name in names[:i]:
            raise ValueError(f"joint_names: {name!r} names joints {names.index(name) + 1} and {i + 1}")
    return tuple(names)


def _limits(limits: ArrayLike, n: int) -> NDArray[np.float64]:
    """``limits`` as an (n, 2) array of finite lower < upper."""
    a = _array("limits", limits, (n, 2))
    for i, (lower, upper) in enumerate(a):
        if not lower < upper:
            raise ValueError(f"limits: joint {i + 1} has lower {lower:.6g} >= upper {upper:.6g}")
    return a


def _rz(t: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3] = so3.rodrigues(t, [0.0, 0.0, 1.0])
    return T


def _rx(t: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3] = so3.rodrigues(t, [1.0, 0.0, 0.0])
    return T


def _tz(d: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[2, 3] = d
    return T


def _tx(a: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[0, 3] = a
    return T


def _dh(theta: float, d: float, a: float, alpha: float) -> NDArray[np.float64]:
    return _rz(theta) @ _tz(d) @ _tx(a) @ _rx(alpha)
