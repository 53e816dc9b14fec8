"""Rotation: shift a random segment of the genome cyclically (DEAP has no such operator).

Genes i..j move by a random k in 1..j-i places to the right, the ones pushed past j re-entering
at i. ``block`` keeps the segment inside one parameter block.
"""

from __future__ import annotations

import numpy as np

from zrp_ga.operators import Array, block_bounds, permute_rows, rows, segments


def _permute(ind: Array, rng: np.random.Generator, blocks: list[tuple[int, int]] | None) -> tuple[Array]:
    """Rotate genes i..j (inclusive) of each genome by a random shift; within a block if given."""
    A = rows(ind)
    N, K = A.shape
    i, j = segments(rng, *block_bounds(rng, N, K, blocks))
    length = j - i + 1
    shift = rng.integers(1, length)
    pos = np.arange(K)[None]
    inside = (pos >= i[:, None]) & (pos <= j[:, None])
    src = i[:, None] + (pos - i[:, None] - shift[:, None]) % length[:, None]
    permute_rows(A, np.where(inside, src, pos))
    return (ind,)


def block(ind: Array, rng: np.random.Generator, blocks: list[tuple[int, int]]) -> tuple[Array]:
    """:func:`segment` inside one parameter block (``blocks``: [start, stop) of each)."""
    return _permute(ind, rng, blocks)


def segment(ind: Array, rng: np.random.Generator) -> tuple[Array]:
    """A random segment anywhere in the genome."""
    return _permute(ind, rng, None)
