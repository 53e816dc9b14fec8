"""Inversion: reverse a random segment of the genome.

Unlike DEAP's ``tools.mutInversion``, which never moves the last gene, the segment [i, j] is
uniform over all pairs of loci i < j, so every locus can move. ``block`` keeps the segment
inside one parameter block (axis genes among axis genes, body-vector genes among body-vector
genes), so that a gene never lands in a slot of another unit or scale.
"""

from __future__ import annotations

import numpy as np

from zrp_ga.operators.base import Array, batched, block_bounds, reverse_segments, rows, segments


def _permute(ind: Array, rng: np.random.Generator, blocks: list[tuple[int, int]] | None) -> tuple[Array]:
    """Reverse genes i..j (inclusive) of each genome; within a random block if ``blocks`` is given."""
    A = rows(ind)
    N, K = A.shape
    lo, hi = block_bounds(rng, N, blocks) if blocks else (0, K)
    reverse_segments(A, *segments(rng, lo, hi, N))
    return (ind,)


@batched(streams=True)
def block(ind: Array, rng: np.random.Generator, blocks: list[tuple[int, int]]) -> tuple[Array]:
    """:func:`segment` inside one parameter block (``blocks``: [start, stop) of each)."""
    return _permute(ind, rng, blocks)


@batched(streams=True)
def segment(ind: Array, rng: np.random.Generator) -> tuple[Array]:
    """A random segment anywhere in the genome."""
    return _permute(ind, rng, None)
