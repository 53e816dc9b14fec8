"""The genome: which parameter errors it holds, and the only path between genomes and models.

A genome is the vector of parameter errors ``x`` (K,) added to a nominal robot, ordered as
:func:`parameter_names` (also the columns of :func:`zrp_ga.model.error_model.pose_jacobians`):
``du0_1 .. du0_n, db0_2 .. db0_{n+1}`` (the paper's 6n), then optionally ``db0_1`` (``base``)
and a small rotation ``dphi_h`` of the hand (``hand``: ``R_h0 <- exp([dphi_h]x) R_h0``), then the last body vectors of tools 2..T
(``tools``: several tool points on one hand, laser-tracker practice; tool 1's is ``b0_{n+1}``).
:meth:`Layout.unpack` turns a population of genomes into model arrays, :meth:`Layout.pack` a
robot into its genome, :meth:`Layout.robot` a genome into a robot; nothing else converts
between them.

Several tools. Tool k's end point hangs off the same arm as tool 1's, ``b0_{n+1}^(k)``
replacing ``b0_{n+1}``. Its nominal vector is tool 1's plus ``R_h0 o_k`` with ``o_k`` its offset
from tool 1 in the hand frame (``tools``, m, from the registration); its genes add to that
independently of tool 1's. ``known_tools`` are tools without genes (a validation with a known
other tool point): their end point is the hand's, averaged over the identified tools
(``b0_{n+1}^(k) - R_h0 o_k``), plus ``R_h0 o`` with the calibrated hand orientation.

Fixed parameters (``fixed``: gene names of the full genome, :func:`mask` reads them from the
config's names). The genome then holds only the free genes: ``size``, ``names`` and ``blocks``
cover them, in the full genome's order; :meth:`Layout.expand` scatters a genome into the full
one with zeros (the nominal values) at the fixed places, and :meth:`Layout.unpack`,
:meth:`Layout.robot` take either. ``full_names`` and :attr:`Layout.unmasked` are the genome
without a mask (the Jacobian's columns before they are restricted to the free ones).

A linear subspace instead (``basis``: N, full_size x K; :func:`dh_mask` builds orthonormal
columns to hold DH parameters to first order, :mod:`zrp_ga.model.subspace` the directions the
data identify, with ``dual``, a left inverse G, K x full_size, ``G N = I``): the genome is z with
``x = N z``; :meth:`Layout.expand` computes it, :meth:`Layout.columns` maps a Jacobian (``J N``)
and :meth:`Layout.restrict` a full genome (``G x``, ``N^T x`` for orthonormal columns); one gene
block ``z``.

The model turns about the normalised axes ``(u0 + du0) / |u0 + du0|``; the unit-length rows
of the paper (Eq. 19-20) then keep ``|u0 + du0|`` near one (see :mod:`zrp_ga.model.cost`).
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga.model.robot import ZRPRobot
from zrp_ga.model.terms import Terms, TermSpec

Array = NDArray[np.float64]


def parameter_names(n: int, base: bool = False, hand: bool = False) -> list[str]:
    """Names of the parameter errors, also the columns of :func:`zrp_ga.model.error_model.pose_jacobians`:
    ``u0_1x .. u0_nz, b0_2x .. b0_{n+1}z`` [``b0_1x..z``, ``rh_x..z``]."""
    names = [f"u0_{i}{c}" for i in range(1, n + 1) for c in "xyz"]
    names += [f"b0_{i}{c}" for i in range(2, n + 2) for c in "xyz"]
    if base:
        names += [f"b0_1{c}" for c in "xyz"]
    if hand:
        names += [f"rh_{c}" for c in "xyz"]
    return names


Vec3 = tuple[float, float, float]


class ModelArrays(NamedTuple):
    """Parameters of P genomes with the population on the last axis, as the compiled kernels
    take them: unit axes ``U`` (n, 3, P), body vectors ``B`` (n+1, 3, P) (tool 1), hand
    orientations ``H`` (3, 3, P), the squared axis lengths before normalising ``length2``
    (n, P), and the last body vector of every tool ``ends`` (T, 3, P) (``ends[0]`` is ``B[n]``)."""

    U: Array
    B: Array
    H: Array
    length2: Array
    ends: Array
    theta: Array | None = None  # (F, P) the non-geometric term genes (None: none)

    def for_tool(self, k: int) -> ModelArrays:
        """The arrays with tool k's last body vector in ``B`` (tool 0: these arrays)."""
        if k == 0:
            return self
        B = self.B.copy()
        B[-1] = self.ends[k]
        return self._replace(B=B)

    def population_first(self) -> tuple[Array, Array, Array]:
        """``u0`` (P, n, 3), ``b0`` (P, n+1, 3), ``R_h0`` (P, 3, 3): views, as
        :func:`zrp_ga.model.kinematics.forward_batch` takes them."""
        return self.U.transpose(2, 0, 1), self.B.transpose(2, 0, 1), self.H.transpose(2, 0, 1)


@dataclasses.dataclass(frozen=True)
class Layout:
    """Which parameter errors a genome holds: K = 6n (+3 with ``base``, +3 with ``hand``, +3 per
    tool beyond the first), less the ``fixed`` genes. ``tools``: offsets (m) of tools 2..T from
    tool 1 in the hand frame; ``known_tools``: the same for tools without genes; ``fixed``: names
    of genes held at their nominal values; ``basis``: N of a genome ``x = N z`` and ``dual`` its
    left inverse (None: N orthonormal, ``N^T``), ``dh_fixed``: the DH parameters it holds
    (module docstring)."""

    n: int
    base: bool = False
    hand: bool = False
    tools: tuple[Vec3, ...] = ()
    known_tools: tuple[Vec3, ...] = ()
    fixed: tuple[str, ...] = ()
    basis: Array | None = dataclasses.field(default=None, compare=False, repr=False)
    dh_fixed: tuple[str, ...] = ()
    dual: Array | None = dataclasses.field(default=None, compare=False, repr=False)
    terms: TermSpec = dataclasses.field(default_factory=TermSpec)

    def __post_init__(self) -> None:
        for name in ("tools", "known_tools"):
            value = tuple(tuple(float(v) for v in o) for o in getattr(self, name))
            if any(len(o) != 3 or not np.all(np.isfinite(o)) for o in value):
                raise ValueError(f"layout.{name}: expected offsets of 3 finite numbers, got {getattr(self, name)}")
            object.__setattr__(self, name, value)
        fixed = set(self.fixed)
        unknown = sorted(fixed - set(self.full_names))
        if unknown:
            raise ValueError(f"layout.fixed: {unknown[0]!r} is not a gene of this layout")
        object.__setattr__(self, "fixed", tuple(k for k in self.full_names if k in fixed))
        if self.fixed and len(self.fixed) == len(self.full_names):
            raise ValueError("layout.fixed: every parameter is fixed; nothing is left to calibrate")
        if self.basis is not None:
            N = np.array(self.basis, dtype=float)
            if N.ndim != 2 or N.shape[0] != self.full_size or not 1 <= N.shape[1] <= self.full_size:
                raise ValueError(f"layout.basis: expected a ({self.full_size}, K) matrix with K >= 1, got shape {N.shape}")
            G = N.T if self.dual is None else np.array(self.dual, dtype=float)
            if G.shape != N.shape[::-1] or not np.allclose(G @ N, np.eye(N.shape[1]), atol=1e-9):
                raise ValueError("layout.basis: the columns are not orthonormal (and no left inverse layout.dual is given)")
            G.setflags(write=False)
            self._left: Array  # declared for the type checker; frozen: set through object.__setattr__
            object.__setattr__(self, "_left", G)  # not the field: a replaced basis gets its own
            if self.fixed and np.abs(N[[self.full_names.index(k) for k in self.fixed]]).max() > 1e-9:
                raise ValueError("layout.basis: moves a fixed gene")
            N.setflags(write=False)
            object.__setattr__(self, "basis", N)

    @property
    def n_tools(self) -> int:
        """Tools with genes (tool 1 and ``tools``)."""
        return 1 + len(self.tools)

    @functools.cached_property
    def unmasked(self) -> Layout:
        """This layout with every gene free (itself when nothing is fixed)."""
        return dataclasses.replace(self, fixed=(), basis=None, dh_fixed=(), dual=None) if self.is_masked else self

    @property
    def is_masked(self) -> bool:
        """Whether the genome holds fewer than all genes (fixed genes or a basis)."""
        return bool(self.fixed) or self.basis is not None

    @functools.cached_property
    def matrix(self) -> Array:
        """The map N (full_size, size) from a genome to the full genome, ``x = N z``: the
        ``basis``, or the identity's columns of the free genes."""
        if self.basis is not None:
            return self.basis
        return np.eye(self.full_size)[:, self.free]

    def columns(self, J: ArrayLike) -> Array:
        """Columns (..., full_size) of a Jacobian in the full genome as columns of this genome
        (..., size): ``J N`` (chain rule through ``x = N z``; the free columns for a plain mask)."""
        J = np.asarray(J, dtype=float)
        if self.basis is not None:
            return J @ self.basis
        return J[..., self.free] if self.fixed else J

    def restrict(self, X: ArrayLike) -> Array:
        """Full genomes X (..., full_size) as genomes (..., size): ``G x`` (``N^T x`` for
        orthonormal columns: the genome nearest to x; the free genes for a plain mask); the
        inverse of :meth:`expand` on its range."""
        X = np.asarray(X, dtype=float)
        if self.basis is not None:
            return X @ self._left.T
        return X[..., self.free] if self.fixed else X.copy()

    @functools.cached_property
    def full_names(self) -> list[str]:
        """Names of every gene, fixed or free (the unmasked genome's order)."""
        names = parameter_names(self.n, self.base, self.hand)
        names += [f"b0_{self.n + 1}{c}_tool{k}" for k in range(2, self.n_tools + 1) for c in "xyz"]
        return names + self.terms.names

    @property
    def full_size(self) -> int:
        return 6 * self.n + 3 * self.base + 3 * self.hand + 3 * len(self.tools) + self.terms.size

    @functools.cached_property
    def free(self) -> NDArray[np.intp]:
        """Indices of the free genes in the full genome (ascending)."""
        fixed = set(self.fixed)
        return np.array([k for k, name in enumerate(self.full_names) if name not in fixed], dtype=np.intp)

    @property
    def names(self) -> list[str]:
        """Names of the genome's (free) genes; with a ``basis``, ``z_k_NAME`` after the full gene
        NAME with the largest weight in column k."""
        full = self.full_names
        if self.basis is not None:
            return [f"z_{k + 1}_{full[int(np.argmax(np.abs(c)))]}" for k, c in enumerate(self.basis.T)]
        return [full[k] for k in self.free] if self.fixed else list(full)

    @property
    def size(self) -> int:
        if self.basis is not None:
            return self.basis.shape[1]
        return self.full_size - len(self.fixed)

    @property
    def blocks(self) -> dict[str, slice]:
        """Gene blocks of the genome: ``u0`` (axes), ``b0`` (body vectors 2..n+1), ``base``,
        ``hand``, ``tool2`` .. ``toolT`` (the last body vectors of the other tools), each the
        free genes of that block (a block with none left is left out). With a ``basis``, one
        block ``z`` (each gene moves several parameters)."""
        if self.basis is not None:
            return {"z": slice(0, self.size)}
        full = self._full_blocks()
        if not self.fixed:
            return full
        position = np.cumsum(np.isin(np.arange(self.full_size), self.free)) - 1  # free index of each full gene
        out = {}
        for name, block in full.items():
            kept = np.isin(np.arange(block.start, block.stop), self.free)
            if kept.any():
                first = int(position[block.start + int(np.argmax(kept))])
                out[name] = slice(first, first + int(kept.sum()))
        return out

    def _full_blocks(self) -> dict[str, slice]:
        n = self.n
        out = {"u0": slice(0, 3 * n), "b0": slice(3 * n, 6 * n)}
        k = 6 * n
        parts = [("base", self.base), ("hand", self.hand)] + [(f"tool{t}", True) for t in range(2, self.n_tools + 1)]
        for name, on in parts:
            if on:
                out[name] = slice(k, k + 3)
                k += 3
        if self.terms:
            out["terms"] = slice(k, k + self.terms.size)
        return out

    def expand(self, X: ArrayLike) -> Array:
        """Genomes X (..., K) as full genomes (..., full_size), zero (nominal) at the fixed genes;
        full genomes are returned as they are (a copy)."""
        X = np.asarray(X, dtype=float)
        if X.shape[-1] == self.full_size:
            return X.copy()
        if X.shape[-1] != self.size:
            raise ValueError(f"layout: genomes of {X.shape[-1]} genes, expected {self.size} (or {self.full_size} with the fixed ones)")
        if self.basis is not None:  # einsum, not BLAS: each genome's numbers are the same alone or in a population
            return np.einsum("...k,jk->...j", X, self.basis)
        out = np.zeros(X.shape[:-1] + (self.full_size,))
        out[..., self.free] = X
        return out

    def unpack(self, nominal: ZRPRobot, X: ArrayLike, each: bool = False) -> ModelArrays:
        """Model arrays of genomes X (P, K) or (K,) (then P = 1), or of full genomes (with the fixed
        genes); NaN where genes break the model. ``each``: every genome's numbers exactly as
        unpacking it alone gives them (``np.einsum`` adds the axes' squares in another order for
        one genome than for many; runs evolved together judge their genomes so, to write what
        each writes alone)."""
        from scipy.spatial.transform import Rotation

        X = np.atleast_2d(self.expand(X))
        P, n, blocks = X.shape[0], self.n, self._full_blocks()
        D = np.ascontiguousarray(X.T)  # the kernels need C order: their loops vectorise over P
        U = nominal.u0[:, :, None] + D[blocks["u0"]].reshape(n, 3, P)
        if each and P > 1:  # each genome's squares summed as for P = 1: over a contiguous axis
            Ut = np.ascontiguousarray(U.transpose(2, 0, 1))
            length2 = np.ascontiguousarray(np.einsum("pik,pik->pi", Ut, Ut).T)
        else:
            length2 = np.einsum("ikp,ikp->ip", U, U)
        with np.errstate(all="ignore"):
            U /= np.sqrt(length2)[:, None, :]
        B = np.repeat(nominal.b0[:, :, None], P, axis=2)
        B[1:] += D[blocks["b0"]].reshape(n, 3, P)
        if self.base:
            B[0] += D[blocks["base"]]
        if self.hand:
            H = (Rotation.from_rotvec(X[:, blocks["hand"]]).as_matrix() @ nominal.R_h0).transpose(1, 2, 0)
        else:
            H = np.broadcast_to(nominal.R_h0[:, :, None], (3, 3, P))
        theta = np.ascontiguousarray(D[blocks["terms"]]) if self.terms else None
        return ModelArrays(U, B, np.ascontiguousarray(H), length2, self._ends(nominal, B, H, D, blocks), theta)

    def _ends(self, nominal: ZRPRobot, B: Array, H: Array, D: Array, blocks: dict[str, slice]) -> Array:
        """The last body vector of every tool (T, 3, P): tool 1, the tools with genes, the known
        tools (module docstring)."""
        if not self.tools and not self.known_tools:
            return B[-1:]
        ends = [B[-1]]
        for t, offset in enumerate(self.tools, start=2):
            ends.append((nominal.b0[-1] + nominal.R_h0 @ offset)[:, None] + D[blocks[f"tool{t}"]])
        if self.known_tools:
            offsets = np.array(((0.0, 0.0, 0.0),) + self.tools)  # (T, 3), tool 1's is zero
            hand = np.mean([e - np.einsum("ijp,j->ip", H, o) for e, o in zip(ends, offsets)], axis=0)
            ends += [hand + np.einsum("ijp,j->ip", H, np.array(o)) for o in self.known_tools]
        return np.stack(ends)

    def pack(self, nominal: ZRPRobot, robot: ZRPRobot, ends: ArrayLike | None = None) -> Array:
        """The genome (K,) that turns ``nominal`` into ``robot`` (same joints, tool 1) and whose
        tools 2..T have the last body vectors ``ends`` ((T-1, 3) m; default: the nominal ones);
        the inverse of :meth:`robot` for unit axes. ValueError where ``robot`` differs from
        ``nominal`` in a fixed gene."""
        from scipy.spatial.transform import Rotation

        parts = [(robot.u0 - nominal.u0).ravel(), (robot.b0[1:] - nominal.b0[1:]).ravel()]
        if self.base:
            parts.append(robot.b0[0] - nominal.b0[0])
        if self.hand:
            parts.append(Rotation.from_matrix(robot.R_h0 @ nominal.R_h0.T).as_rotvec())
        elif not np.allclose(robot.R_h0, nominal.R_h0, atol=1e-12):
            raise ValueError("layout: the robots' hand orientations differ, but the genome has no hand genes")
        if not self.base and not np.allclose(robot.b0[0], nominal.b0[0], atol=1e-15):
            raise ValueError("layout: the robots' base points differ, but the genome has no base genes")
        if self.tools:
            nominal_ends = nominal.b0[-1] + np.array(self.tools) @ nominal.R_h0.T
            ends = nominal_ends if ends is None else np.asarray(ends, dtype=float).reshape(len(self.tools), 3)
            parts.append((ends - nominal_ends).ravel())
        if self.terms:
            parts.append(_term_values(robot, self.terms))
        elif robot.terms is not None:
            raise ValueError("layout: the robot carries non-geometric terms, but the genome has none")
        x = np.concatenate(parts)
        if self.basis is not None:
            z = self.restrict(x)
            if np.abs(x - self.basis @ z).max() > 1e-9:  # (normalised axes: second order off)
                what = f"fixed DH parameters {', '.join(self.dh_fixed)}" if self.dh_fixed else "the combinations the genome holds"
                raise ValueError(f"layout: the robots differ outside the genome's subspace ({what})")
            return z
        if not self.fixed:
            return x
        moved = [name for name, v in zip(self.full_names, x) if name in set(self.fixed) and abs(v) > 1e-12]
        if moved:
            raise ValueError(f"layout: the robots differ in the fixed parameter {moved[0]}")
        return x[self.free]

    def robot(self, nominal: ZRPRobot, x: ArrayLike, name: str | None = None, tool: int = 0) -> ZRPRobot:
        """The robot of one genome ``x`` (K,) (or full genome) with the end point of tool ``tool`` (0: tool 1;
        then the tools with genes, then the known ones), axes normalised."""
        m = self.unpack(nominal, x)
        u0, b0, R_h0 = (a[0] for a in m.for_tool(tool).population_first())
        terms = None
        if self.terms:
            assert m.theta is not None  # unpack sets the term genes whenever the layout has terms
            terms = Terms(self.terms, m.theta[:, 0])
        return nominal.replace(u0=u0, b0=b0, R_h0=R_h0, name=name or nominal.name, normalize=True, terms=terms)


def _term_values(robot: ZRPRobot, spec: TermSpec) -> Array:
    """The values (F,) of ``spec``'s terms in ``robot`` (0 where it carries none of them)."""
    have = {} if robot.terms is None else dict(zip(robot.terms.spec.names, robot.terms.values))
    extra = sorted(set(have) - set(spec.names))
    if extra:
        raise ValueError(f"layout: the robot carries the term {extra[0]}, which the genome does not hold")
    return np.array([have.get(k, 0.0) for k in spec.names])


def _groups(layout: Layout) -> dict[str, list[str]]:
    """The names a config may give, each with the genes it stands for (:func:`mask`)."""
    n, full = layout.n, layout.full_names
    vec = lambda stem: [f"{stem}{c}" for c in "xyz"]
    out = {f"u0_{i}": vec(f"u0_{i}") for i in range(1, n + 1)}
    out.update({f"b0_{i}": vec(f"b0_{i}") for i in range(1 if layout.base else 2, n + 2)})
    out["axes"] = [k for k in full if k.startswith("u0_")]
    if n >= 2:  # a one-joint arm has no link between two axes
        out["links"] = [f"b0_{i}{c}" for i in range(2, n + 1) for c in "xyz"]
    out["tool"] = vec(f"b0_{n + 1}")
    if layout.base:
        out["base"] = vec("b0_1")
    if layout.hand:
        out["hand"] = vec("rh_")
    if layout.tools:
        out["tools"] = [k for k in full if "_tool" in k]
        out.update({f"tool{t}": [f"b0_{n + 1}{c}_tool{t}" for c in "xyz"] for t in range(2, layout.n_tools + 1)})
    if layout.terms.compliance:
        out["compliance"] = [k for k in full if k.startswith("compliance_")]
    if layout.terms.harmonics:
        out["harmonics"] = [k for k in full if k.startswith("harmonic_")]
    out.update({k: [k] for k in full})  # one component: b0_3x, u0_2z, rh_x
    return out


def valid_names(layout: Layout) -> str:
    """The names :func:`mask` takes for ``layout``, in one line."""
    n = layout.n
    first = 1 if layout.base else 2
    parts = [f"u0_1..u0_{n} (axis directions)", f"b0_{first}..b0_{n + 1} (body vectors{'; b0_1 = base' if layout.base else ''}; b0_{n + 1} = tool)",
             "axes", *[f"links (b0_2..b0_{n})"] * (n >= 2), "tool"]  # fmt: skip
    parts += ["base"] * layout.base + ["hand (hand orientation)"] * layout.hand
    if layout.tools:
        parts.append(f"tools (tool2..tool{layout.n_tools})")
    if layout.terms:
        parts.append(f"compliance, harmonics or one term ({', '.join(layout.terms.names)})")
    parts.append("or one component such as b0_3x")
    return ", ".join(parts)


_WHY = {"base": "the base point is identified only with problem.identify_base=true (measured problems: always)",
        "hand": "the hand orientation is identified only with problem.identify_hand=true (measured: use_orientation=true)",
        "b0_1": "the base point is identified only with problem.identify_base=true (measured problems: always)"}  # fmt: skip


def mask(layout: Layout, fixed: Iterable[str] | None = None, free: Iterable[str] | None = None, key: str = "problem") -> Layout:
    """``layout`` with the parameters named in ``fixed`` held at their nominal values, or, with
    ``free`` alone, every parameter but those; with both, ``fixed`` less ``free`` (fix the links
    but b0_3: ``fixed=[links], free=[b0_3]``). Names: ``u0_i`` (axis i's direction), ``b0_i``
    (body vector i; ``b0_1`` the base point, ``b0_{n+1}`` tool 1's last body vector), ``base``,
    ``tool``, ``hand`` (hand orientation), ``tools`` and ``tool2``.. (the other tools' last body
    vectors), ``axes`` (every u0), ``links`` (b0_2..b0_n), or one gene (``b0_3x``). An unknown
    name is a ValueError naming ``key.fixed`` (or ``key.free``) and the valid names in one line."""
    if fixed is None and free is None:
        return layout
    groups = _groups(layout)

    def genes(names: Iterable[str] | None, which: str) -> set[str]:
        if names is None:
            return set()
        if isinstance(names, str):
            names = [names]
        out: set[str] = set()
        for raw in names:
            name = str(raw).strip()
            if name not in groups:
                stem = re.sub(r"[xyz]$", "", name).rstrip("_")
                why = _WHY.get(name) or _WHY.get(stem)
                hint = f" ({why})" if why else ""
                raise ValueError(f"{key}.{which}: {name!r} is not a parameter of this problem{hint}; valid: {valid_names(layout)}")
            out.update(groups[name])
        return out

    fixed_genes, free_genes = genes(fixed, "fixed"), genes(free, "free")
    chosen = fixed_genes - free_genes if fixed is not None else set(layout.full_names) - free_genes
    if len(chosen) == len(layout.full_names):
        raise ValueError(f"{key}.{'fixed' if fixed is not None else 'free'}: every parameter would be fixed; nothing is left to calibrate")
    return dataclasses.replace(layout, fixed=tuple(sorted(chosen | set(layout.fixed))))


def fixed_summary(layout: Layout) -> list[str]:
    """The fixed genes as a config would name them: whole vectors (``u0_1``, ``base``, ``tool``,
    ``hand``, ``tool2``) where all three are fixed, single genes otherwise."""
    fixed, n = set(layout.fixed), layout.n
    names = {"b0_1": "base", f"b0_{n + 1}": "tool", "rh_": "hand"}
    out = []
    for name in layout.full_names:
        if name not in fixed:
            continue
        stem = name[:-1] if not name.endswith(tuple(f"_tool{t}" for t in range(2, layout.n_tools + 1))) else None
        if stem is None:
            vec_stem, tool = name.split("_tool")
            trio = [f"{vec_stem[:-1]}{c}_tool{tool}" for c in "xyz"]
            label = f"tool{tool}"
        else:
            trio = [f"{stem}{c}" for c in "xyz"]
            label = names.get(stem, stem)
        if all(t in fixed for t in trio):
            if label not in out:
                out.append(label)
        else:
            out.append(name)
    return out


DH_STEP = 1e-7  # finite-difference step of the DH Jacobian (m, rad)
DH_JUMP = 1e-4  # a DH parameter moving more than this over one step is not smooth there (m, rad)


def dh_names_hint(n: int) -> str:
    """The DH names :func:`dh_mask` takes for an arm of n joints, in one line."""
    return f"dh_a_i, dh_alpha_i, dh_d_i, dh_theta_i, dh_beta_i with i the table's row 1..{n}"


def dh_mask(layout: Layout, nominal: ZRPRobot, convention: str, names: Iterable[str], key: str = "problem") -> Layout:
    """``layout`` (possibly masked by kind) whose genome also keeps the DH parameters ``names``
    (:func:`zrp_ga.model.dh.parameters`: ``dh_theta_2``, ``dh_d_3``, ... of the ``convention`` table)
    of the arm at their nominal values, to first order (the tables of nearby arms read with the
    nominal table's base x axis, ``dh.parameters(..., base_x)``): with C (len(names), full_size) their
    Jacobian with respect to the full genome at zero (central differences, step
    :data:`DH_STEP`), the genome is z with ``x = N z``, N an orthonormal basis of the null space
    of C stacked on the unit rows of the fixed genes and on the slides of the axis points along
    their nominal axes (:func:`_slides`: no pose and no DH parameter moves along them, but
    left in, LM's damping moves freely along them, and slides of decimetres times axis tilts
    would move the fixed DH parameters by millimetres at second order; ``scipy.linalg.null_space``). An unknown
    name, or a parameter that is not a smooth function of the errors at the nominal arm (a DH
    sign or Hayati choice at its boundary there), is a ValueError naming ``key.fixed``."""
    from scipy.linalg import null_space

    from zrp_ga.model import dh

    names = [str(k).strip() for k in names]
    full = layout.unmasked
    zero = full.robot(nominal, np.zeros(full.size))
    base_x = dh.to_dh(zero, convention, samples=1)[0].base[:3, 0]  # held: the base frame's x turns with axis 1
    base = dh.parameters(zero, convention, base_x)
    for name in names:
        if name not in base:
            raise ValueError(f"{key}.fixed: {name!r} is not a DH parameter of this arm; valid: {dh_names_hint(nominal.n)}")
    angle = np.array([name.split("_")[1] in ("alpha", "theta", "beta") for name in names])

    def values(x: Array) -> Array:
        p = dh.parameters(full.robot(nominal, x), convention, base_x)
        return np.array([p[name] for name in names])

    f0 = values(np.zeros(full.size))
    C = np.empty((len(names), full.size))
    for k in range(full.size):
        e = np.zeros(full.size)
        e[k] = DH_STEP
        up, down = values(e) - f0, f0 - values(-e)
        up[angle], down[angle] = np.angle(np.exp(1j * up[angle])), np.angle(np.exp(1j * down[angle]))
        jump = np.maximum(np.abs(up), np.abs(down)) > DH_JUMP
        if jump.any():
            raise ValueError(f"{key}.fixed: {names[int(np.argmax(jump))]} is not a smooth function of the parameter errors at the "
                             f"nominal arm (a DH choice changes there, gene {full.full_names[k]}); fix it by kind instead")  # fmt: skip
        C[:, k] = (up + down) / (2 * DH_STEP)
    rows = [C, _slides(full, nominal).T] + [np.eye(full.size)[[full.full_names.index(g) for g in layout.fixed]]]
    N = null_space(np.vstack(rows))
    if N.shape[1] == 0:
        raise ValueError(f"{key}.fixed: every parameter would be fixed; nothing is left to calibrate")
    if layout.fixed:
        N[[full.full_names.index(g) for g in layout.fixed]] = 0.0  # exactly (null_space leaves ~1e-17)
    return dataclasses.replace(layout, basis=N, dh_fixed=tuple(dict.fromkeys(names)))


def _slides(layout: Layout, nominal: ZRPRobot) -> Array:
    """The model's null directions at the nominal arm: :func:`slides` about the nominal axes."""
    return slides(layout, nominal, nominal.u0)


def slides(layout: Layout, nominal: ZRPRobot, axes: Array) -> Array:
    """The model's null directions (full_size, S) of an unmasked ``layout``, as
    :func:`zrp_ga.model.error_model.canonical` takes them: axis i's point slid along axis i (``axes``
    (n, 3); body vector i + d, body vector i+1 - d, and every other tool's end point with axis n's;
    a prismatic joint's point in any direction), for the points the genome can move (axis 1's
    only with a base)."""
    n, blocks = nominal.n, layout.blocks
    start = {i: blocks["b0"].start + 3 * (i - 2) for i in range(2, n + 2)}
    if layout.base:
        start[1] = blocks["base"].start
    vectors = []
    for i in range(1, n + 1):
        if i not in start:
            continue
        for d in np.eye(3) if nominal.joint_types[i - 1] == "P" else axes[i - 1][None]:
            v = np.zeros(layout.full_size)
            v[start[i] : start[i] + 3] += d
            v[start[i + 1] : start[i + 1] + 3] -= d
            for t in range(2, layout.n_tools + 1) if i == n else ():
                v[blocks[f"tool{t}"]] -= d
            vectors.append(v)
    return np.array(vectors).T if vectors else np.zeros((layout.full_size, 0))
