"""Crossover: one-point, two-point, uniform, blend, simulated binary (bounded)."""

from __future__ import annotations

import numpy as np

from zrp_ga.operators.base import Array, batched, draw, rows, segments, swap_segments


def _uniform(rng, shape: tuple[int, int]) -> Array:
    """U(0, 1) numbers of a batch's shape (N, K), each run's rows from its own stream."""
    return draw(rng, shape[0], lambda g, n: g.random((n, shape[1])))


def _swap(A: Array, B: Array, mask: np.ndarray) -> None:
    a = A.copy()  # numpy slices are views: swap through a copy
    A[:] = np.where(mask, B, A)
    B[:] = np.where(mask, a, B)


@batched(streams=True)
def one_point(ind1: Array, ind2: Array, rng: np.random.Generator) -> tuple[Array, Array]:
    """Swap the tails after a random cut point in 1..K-1 (a genome of one gene has no cut point:
    unchanged, nothing drawn)."""
    A, B = rows(ind1), rows(ind2)
    N, K = A.shape
    if K < 2:
        return ind1, ind2
    cut = draw(rng, N, lambda g, n: g.integers(1, K, size=n))
    swap_segments(A, B, cut, np.full(N, K))
    return ind1, ind2


@batched(streams=True)
def two_point(ind1: Array, ind2: Array, rng: np.random.Generator) -> tuple[Array, Array]:
    """Swap the genes between two distinct random cut points in 1..K-1. With K = 2 there is one
    cut point: the second gene is swapped; with K = 1 none: unchanged. Two numbers
    drawn per pair whatever K."""
    A, B = rows(ind1), rows(ind2)
    N, K = A.shape
    lo, hi = segments(rng, 1, K, N)  # two distinct cut points in 1..K-1
    if K == 2:
        lo, hi = np.ones(N, dtype=np.intp), np.full(N, 2)
    swap_segments(A, B, lo, hi)
    return ind1, ind2


@batched(streams=True)
def uniform(ind1: Array, ind2: Array, rng: np.random.Generator, indpb: float = 0.5) -> tuple[Array, Array]:
    """Swap each gene with probability ``indpb``."""
    A, B = rows(ind1), rows(ind2)
    _swap(A, B, _uniform(rng, A.shape) < indpb)
    return ind1, ind2


@batched(streams=True)
def blend(ind1: Array, ind2: Array, rng: np.random.Generator, alpha: float = 0.5) -> tuple[Array, Array]:
    """BLX-alpha: ``gamma = (1 + 2 alpha) U - alpha``, children ``(1-gamma) x1 + gamma x2`` and
    ``gamma x1 + (1-gamma) x2`` (as DEAP's ``cxBlend``)."""
    A, B = rows(ind1), rows(ind2)
    g = (1.0 + 2.0 * alpha) * _uniform(rng, A.shape) - alpha
    a = A.copy()
    A[:] = (1.0 - g) * a + g * B
    B[:] = g * a + (1.0 - g) * B
    return ind1, ind2


@batched(streams=True)
def sbx(
    ind1: Array, ind2: Array, rng: np.random.Generator, low: Array, up: Array, eta: float = 20.0, indpb: float = 0.5
) -> tuple[Array, Array]:
    """Simulated binary crossover bounded to [low, up] (Deb and Agrawal; the algorithm of DEAP's
    ``cxSimulatedBinaryBounded``), each gene with probability ``indpb``, vectorised."""
    A, B = rows(ind1), rows(ind2)
    x1, x2 = np.minimum(A, B), np.maximum(A, B)
    active = (_uniform(rng, A.shape) < indpb) & (x2 - x1 > 1e-14)
    u = _uniform(rng, A.shape)
    flip = _uniform(rng, A.shape) <= 0.5
    # the active genes only (element by element the same numbers as over the whole batch)
    r, c = np.nonzero(active)
    a1, a2, diff, u = x1[r, c], x2[r, c], (x2 - x1)[r, c], u[r, c]
    lo, hi = np.broadcast_to(low, A.shape)[r, c], np.broadcast_to(up, A.shape)[r, c]
    power = 1.0 / (eta + 1.0)

    def beta_q(beta: Array) -> Array:
        alpha = 2.0 - beta ** -(eta + 1.0)
        return np.where(u <= 1.0 / alpha, (u * alpha) ** power, (1.0 / (2.0 - u * alpha)) ** power)

    with np.errstate(all="ignore"):
        c1 = 0.5 * (a1 + a2 - beta_q(1.0 + 2.0 * (a1 - lo) / diff) * diff)
        c2 = 0.5 * (a1 + a2 + beta_q(1.0 + 2.0 * (hi - a2) / diff) * diff)
    c1, c2 = np.clip(c1, lo, hi), np.clip(c2, lo, hi)
    flip = flip[r, c]
    A[r, c] = np.where(flip, c2, c1)
    B[r, c] = np.where(flip, c1, c2)
    return ind1, ind2
