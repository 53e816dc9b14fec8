"""Variation operators on numpy genomes, one module per family.

Every operator keeps DEAP's calling convention and changes its arguments in place:
``cx(ind1, ind2, rng, **params) -> (ind1, ind2)``, ``mut(ind, rng, **params) -> (ind,)``.
An argument may be one genome (K,) — a DEAP individual — or a batch of genomes (N, K), each row
varied independently, so that the GA varies a whole generation in a few numpy calls. Random
numbers come from the ``numpy.random.Generator`` passed in (DEAP's own operators use the
``random`` module, do not swap slices of numpy genomes, and ``tools.mutInversion`` never moves
the last gene, so none of them is used here).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def rows(a: Array) -> Array:
    """A 2-D view (N, K) of a genome or a batch; writing into it writes into ``a``."""
    if a.ndim == 1:
        return a[None]
    if a.ndim != 2:
        raise ValueError(f"genome: expected shape (K,) or (N, K), got {a.shape}")
    return a


def segments(rng: np.random.Generator, lo: NDArray, hi: NDArray) -> tuple[NDArray, NDArray]:
    """Random segments [i, j], i < j, uniform over the pairs of loci in [lo, hi) of each row."""
    x = rng.integers(lo, hi)
    y = rng.integers(lo, hi - 1)
    y = y + (y >= x)
    return np.minimum(x, y), np.maximum(x, y)


def block_bounds(rng: np.random.Generator, N: int, K: int, blocks: list[tuple[int, int]] | None) -> tuple[NDArray, NDArray]:
    """Per row, the [lo, hi) of a block chosen with probability proportional to its size
    (blocks of fewer than two genes never chosen); the whole genome when ``blocks`` is None."""
    if not blocks:
        return np.zeros(N, dtype=int), np.full(N, K)
    usable = np.array([(a, b) for a, b in blocks if b - a >= 2])
    sizes = usable[:, 1] - usable[:, 0]
    pick = rng.choice(len(usable), size=N, p=sizes / sizes.sum())
    return usable[pick, 0], usable[pick, 1]


def permute_rows(A: Array, src: NDArray) -> None:
    """``A[r] = A[r, src[r]]`` for every row, in place."""
    A[:] = np.take_along_axis(A, src, axis=1)


def repair(A: Array, low: Array, up: Array, method: str = "clip") -> Array:
    """Bring genes back into [low, up]: ``clip`` to the bound, or ``reflect`` off it (folding
    any distance back into the range). In place; returns A."""
    B = rows(A)
    if method == "clip":
        np.clip(B, low, up, out=B)
    elif method == "reflect":
        width = up - low
        y = np.mod(B - low, 2 * width)
        B[:] = low + np.where(y > width, 2 * width - y, y)
    else:
        raise ValueError(f"repair: unknown method {method!r}; known: clip, reflect")
    return A
