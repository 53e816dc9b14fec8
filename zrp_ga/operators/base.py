"""What the batched operators share: genomes as rows of a batch (:func:`rows`), random segments
and blocks drawn for a whole batch, the compiled segment moves, and the :func:`batched` mark
that tells :func:`zrp_ga.operators.build` an operator takes a whole generation."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from zrp_ga._numba import jit

Array = NDArray[np.float64]


def rows(a: Array) -> Array:
    """A 2-D view (N, K) of a genome or a batch; writing into it writes into ``a``."""
    if a.ndim == 1:
        return a[None]
    if a.ndim != 2:
        raise ValueError(f"genome: expected shape (K,) or (N, K), got {a.shape}")
    return a


def segments(rng: np.random.Generator, lo: NDArray | int, hi: NDArray | int, N: int) -> tuple[NDArray, NDArray]:
    """N random segments [i, j], i < j, uniform over the pairs of loci in [lo, hi) (per row or
    shared). Drawn from one ``rng.random`` call: ``rng.integers`` with array bounds costs 10x."""
    span = np.asarray(hi) - np.asarray(lo)
    r = rng.random((2, N))
    x = (r[0] * span).astype(np.intp)
    y = (r[1] * (span - 1)).astype(np.intp)
    y += y >= x
    return lo + np.minimum(x, y), lo + np.maximum(x, y)


def block_bounds(rng: np.random.Generator, N: int, blocks: list[tuple[int, int]]) -> tuple[NDArray, NDArray]:
    """Per row, the [lo, hi) of a block chosen with probability proportional to its size
    (blocks of fewer than two genes never chosen)."""
    usable = np.array([(a, b) for a, b in blocks if b - a >= 2])
    sizes = usable[:, 1] - usable[:, 0]
    pick = np.searchsorted(np.cumsum(sizes), rng.random(N) * sizes.sum(), side="right")
    return usable[pick, 0], usable[pick, 1]


@jit
def reverse_segments(A, i, j):  # pragma: no cover - compiled
    """Reverse ``A[r, i[r] .. j[r]]`` (inclusive) of every row in place."""
    for r in range(A.shape[0]):
        a, b = i[r], j[r]
        while a < b:
            A[r, a], A[r, b] = A[r, b], A[r, a]
            a += 1
            b -= 1


@jit
def rotate_segments(A, i, j, shift):  # pragma: no cover - compiled
    """Shift ``A[r, i[r] .. j[r]]`` (inclusive) cyclically right by ``shift[r]`` places, in place."""
    buf = np.empty(A.shape[1])
    for r in range(A.shape[0]):
        length = j[r] - i[r] + 1
        for k in range(length):
            buf[(k + shift[r]) % length] = A[r, i[r] + k]
        for k in range(length):
            A[r, i[r] + k] = buf[k]


@jit
def swap_segments(A, B, lo, hi):  # pragma: no cover - compiled
    """Swap ``A[r, lo[r]:hi[r]]`` with ``B[r, lo[r]:hi[r]]`` for every row, in place."""
    for r in range(A.shape[0]):
        for k in range(lo[r], hi[r]):
            A[r, k], B[r, k] = B[r, k], A[r, k]


def batched(fn: Callable) -> Callable:
    """Mark ``fn`` as taking batches of genomes (N, K) and a ``rng``: :func:`build` then calls it
    on a whole generation rather than one individual at a time."""
    fn.batched = True
    return fn
