"""Mutation: Gaussian (sigma relative to the gene range), polynomial (bounded), uniform reset."""

from __future__ import annotations

import numpy as np

from zrp_ga.operators.base import Array, batched, draw, parts, rows


def _uniform(rng, shape: tuple[int, int]) -> Array:
    """U(0, 1) numbers of a batch's shape (N, K), each run's rows from its own stream."""
    return draw(rng, shape[0], lambda g, n: g.random((n, shape[1])))


@batched(streams=True)
def gaussian(
    ind: Array, rng: np.random.Generator, low: Array, up: Array, sigma: float = 0.1, indpb: float = 0.2
) -> tuple[Array]:
    """Add ``N(0, (sigma (up - low))^2)`` to each gene with probability ``indpb``."""
    A = rows(ind)
    mask = _uniform(rng, A.shape) < indpb
    r, c = np.nonzero(mask)
    noise = [g.standard_normal(np.count_nonzero(mask[s])) for g, s in parts(rng, len(A))]
    A[r, c] += (noise[0] if len(noise) == 1 else np.concatenate(noise)) * (sigma * (up - low))[c]
    return (ind,)


@batched(streams=True)
def polynomial(
    ind: Array, rng: np.random.Generator, low: Array, up: Array, eta: float = 20.0, indpb: float = 0.2
) -> tuple[Array]:
    """Deb's bounded polynomial mutation (the algorithm of DEAP's ``mutPolynomialBounded``)."""
    A = rows(ind)
    mask = _uniform(rng, A.shape) < indpb
    u = _uniform(rng, A.shape)
    # the mutated genes only (element by element the same numbers as over the whole batch)
    r, c = np.nonzero(mask)
    lo, hi, u = np.broadcast_to(low, A.shape)[r, c], np.broadcast_to(up, A.shape)[r, c], u[r, c]
    x = np.clip(A[r, c], lo, hi)
    width = hi - lo
    d1, d2 = (x - lo) / width, (hi - x) / width
    power = 1.0 / (eta + 1.0)
    lower_side = u < 0.5
    with np.errstate(all="ignore"):
        v1 = 2.0 * u + (1.0 - 2.0 * u) * (1.0 - d1) ** (eta + 1.0)
        v2 = 2.0 * (1.0 - u) + 2.0 * (u - 0.5) * (1.0 - d2) ** (eta + 1.0)
        dq = np.where(lower_side, v1**power - 1.0, 1.0 - v2**power)
    A[r, c] = np.clip(x + dq * width, lo, hi)
    return (ind,)


@batched(streams=True)
def uniform_reset(ind: Array, rng: np.random.Generator, low: Array, up: Array, indpb: float = 0.1) -> tuple[Array]:
    """Replace each gene with probability ``indpb`` by a uniform draw in [low, up]."""
    A = rows(ind)
    mask = _uniform(rng, A.shape) < indpb
    A[:] = np.where(mask, draw(rng, len(A), lambda g, n: g.uniform(low, up, size=(n, A.shape[1]))), A)
    return (ind,)
