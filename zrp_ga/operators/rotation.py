"""Rotation: shift a random segment of the genome cyclically (DEAP has no such operator).

Genes i..j move by a random k in 1..j-i places to the right, the ones pushed past j re-entering
at i. ``block`` keeps the segment inside one parameter block.
"""

from __future__ import annotations

import numpy as np

from zrp_ga.operators.base import Array, batched, block_bounds, draw, rotate_segments, rows, segments


def _permute(ind: Array, rng: np.random.Generator, blocks: list[tuple[int, int]] | None) -> tuple[Array]:
    """Rotate genes i..j (inclusive) of each genome by a random shift; within a block if given."""
    A = rows(ind)
    N, K = A.shape
    lo, hi = block_bounds(rng, N, blocks) if blocks else (0, K)
    i, j = segments(rng, lo, hi, N)
    shift = 1 + (draw(rng, N, lambda g, n: g.random(n)) * (j - i)).astype(np.intp)  # 1 .. length - 1
    rotate_segments(A, i, j, shift)
    return (ind,)


@batched(streams=True)
def block(ind: Array, rng: np.random.Generator, blocks: list[tuple[int, int]]) -> tuple[Array]:
    """:func:`segment` inside one parameter block (``blocks``: [start, stop) of each)."""
    return _permute(ind, rng, blocks)


@batched(streams=True)
def segment(ind: Array, rng: np.random.Generator) -> tuple[Array]:
    """A random segment anywhere in the genome."""
    return _permute(ind, rng, None)
