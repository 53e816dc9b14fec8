"""The genome: which parameter errors it holds, and the only path between genomes and models.

A genome is the vector of parameter errors ``x`` (K,) added to a nominal robot, ordered as
:func:`zrp_ga.error_model.parameter_names`: ``du0_1 .. du0_n, db0_2 .. db0_{n+1}`` (the
paper's 6n), then optionally ``db0_1`` (``base``) and a small rotation ``dphi_h`` of the hand
(``hand``: ``R_h0 <- exp([dphi_h]x) R_h0``). :meth:`Layout.unpack` turns a population of
genomes into model arrays, :meth:`Layout.pack` a robot into its genome, :meth:`Layout.robot`
a genome into a robot; nothing else converts between them.

The model turns about the normalised axes ``(u0 + du0) / |u0 + du0|``; the unit-length rows
of the paper (Eq. 19-20) then keep ``|u0 + du0|`` near one (see :mod:`zrp_ga.problem`).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga import error_model
from zrp_ga.robot import ZRPRobot

Array = NDArray[np.float64]


class ModelArrays(NamedTuple):
    """Parameters of P genomes with the population on the last axis, as the compiled kernels
    take them: unit axes ``U`` (n, 3, P), body vectors ``B`` (n+1, 3, P), hand orientations
    ``H`` (3, 3, P), and the squared axis lengths before normalising ``length2`` (n, P)."""

    U: Array
    B: Array
    H: Array
    length2: Array

    def population_first(self) -> tuple[Array, Array, Array]:
        """``u0`` (P, n, 3), ``b0`` (P, n+1, 3), ``R_h0`` (P, 3, 3): views, as
        :func:`zrp_ga.kinematics.forward_batch` takes them."""
        return self.U.transpose(2, 0, 1), self.B.transpose(2, 0, 1), self.H.transpose(2, 0, 1)


@dataclasses.dataclass(frozen=True)
class Layout:
    """Which parameter errors a genome holds: K = 6n (+3 with ``base``, +3 with ``hand``)."""

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

    def unpack(self, nominal: ZRPRobot, X: ArrayLike) -> ModelArrays:
        """Model arrays of genomes X (P, K) or (K,) (then P = 1); NaN where genes break the model."""
        from scipy.spatial.transform import Rotation

        X = np.atleast_2d(np.asarray(X, dtype=float))
        P, n, blocks = X.shape[0], self.n, self.blocks
        D = np.ascontiguousarray(X.T)  # the kernels need C order: their loops vectorise over P
        U = nominal.u0[:, :, None] + D[blocks["u0"]].reshape(n, 3, P)
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
        return ModelArrays(U, B, np.ascontiguousarray(H), length2)

    def pack(self, nominal: ZRPRobot, robot: ZRPRobot) -> Array:
        """The genome (K,) that turns ``nominal`` into ``robot`` (same joints); the inverse of
        :meth:`robot` for unit axes."""
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
        return np.concatenate(parts)

    def robot(self, nominal: ZRPRobot, x: ArrayLike, name: str | None = None) -> ZRPRobot:
        """The robot of one genome ``x`` (K,), axes normalised."""
        u0, b0, R_h0 = (a[0] for a in self.unpack(nominal, x).population_first())
        return nominal.replace(u0=u0, b0=b0, R_h0=R_h0, name=name or nominal.name, normalize=True)
