"""Operators on subset genomes: k distinct pose indices out of N candidates (zrp_ga.problems.selection).

A genome is a row of k distinct integers in [0, N), stored as floats like every genome of the
GA. Its order does not change the subset, but it is what positional operators act on:
inversion and rotation (:mod:`zrp_ga.operators.inversion`, :mod:`zrp_ga.operators.rotation`)
reorder a subset without changing it, and so only change which genes one-point and two-point
crossover keep together. Any other operator may leave repeated or fractional indices;
:func:`repair` (the selection problem's ``repair``, which the GA applies after variation)
rounds them and replaces repeats with random candidates outside the subset.

- :func:`crossover`: the genes both parents hold stay; the j-th gene of one parent that the
  other lacks is exchanged with the j-th such gene of the other with probability ``indpb``
  (uniform crossover on the genes that differ), so both children hold k distinct parental genes.
- :func:`swap`: each gene, with probability ``indpb`` (and at least one per child), is replaced
  by a random candidate outside the subset.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from zrp_ga.operators.base import Array, batched, rows


def duplicates(A: Array, keep: NDArray[np.bool_] | None = None) -> NDArray[np.bool_]:
    """Genes (N, k) that repeat a gene of their row: of equal genes the first is not marked,
    genes flagged in ``keep`` counting as first (so that a repeat of a kept gene is the other)."""
    keep = np.zeros(A.shape, dtype=bool) if keep is None else keep
    order = np.lexsort((~keep, A), axis=-1)  # by value, kept genes first, then by position
    s = np.take_along_axis(A, order, axis=-1)
    repeat = np.zeros(A.shape, dtype=bool)
    np.put_along_axis(repeat, order[:, 1:], s[:, 1:] == s[:, :-1], axis=-1)
    return repeat


def redraw(
    A: Array, mask: NDArray[np.bool_], rng: np.random.Generator, n: int, avoid: Array | None = None
) -> Array:
    """Replace the genes in ``mask`` by uniform draws in [0, n) until every row holds distinct
    genes and none of the new ones is in its row of ``avoid`` (N, k'). In place; returns A.
    Rejection sampling, batched: each round redraws only the genes still in conflict (about
    k / n of them), which the caller must leave room for (at most n - k' new genes per row)."""
    todo = mask.copy()
    while todo.any():
        r, c = np.nonzero(todo)
        A[r, c] = rng.integers(0, n, size=r.size)
        conflict = duplicates(A, keep=~todo)
        if avoid is not None:
            conflict |= todo & (A[:, :, None] == avoid[:, None, :]).any(axis=2)
        todo &= conflict
    return A


def sample(rng: np.random.Generator, size: int, k: int, n: int) -> Array:
    """``size`` subsets of k distinct indices in [0, n), uniform over the subsets: (size, k)."""
    return np.argsort(rng.random((size, n)), axis=1)[:, :k].astype(float)


def repair(ind: Array, rng: np.random.Generator, n: int) -> Array:
    """Round genes to indices in [0, n) (non-finite ones to 0), then redraw repeats from the
    candidates outside the row. In place; returns ``ind``."""
    A = rows(ind)
    np.rint(np.nan_to_num(A, nan=0.0, posinf=n - 1, neginf=0.0), out=A)
    np.clip(A, 0, n - 1, out=A)
    repeat = duplicates(A)
    if repeat.any():
        redraw(A, repeat, rng, n)
    return ind


@batched
def crossover(ind1: Array, ind2: Array, rng: np.random.Generator, indpb: float = 0.5) -> tuple[Array, Array]:
    """Exchange genes the other parent lacks, pairwise, each pair with probability ``indpb``
    (see the module docstring). Parents must hold distinct genes; the children then do too."""
    A, B = rows(ind1), rows(ind2)
    a_only = ~(A[:, :, None] == B[:, None, :]).any(axis=2)
    b_only = ~(B[:, :, None] == A[:, None, :]).any(axis=2)
    pa = np.argsort(~a_only, axis=1, kind="stable")  # positions of A's own genes first, in order
    pb = np.argsort(~b_only, axis=1, kind="stable")
    differ = a_only.sum(axis=1)  # as many as B's own genes
    r, j = np.nonzero((rng.random(A.shape) < indpb) & (np.arange(A.shape[1]) < differ[:, None]))
    ia, ib = pa[r, j], pb[r, j]
    a = A[r, ia].copy()
    A[r, ia] = B[r, ib]
    B[r, ib] = a
    return ind1, ind2


@batched
def swap(ind: Array, rng: np.random.Generator, up: Array, indpb: float = 0.1) -> tuple[Array]:
    """Replace each gene with probability ``indpb`` (at least one per genome) by a candidate in
    [0, up] outside the subset; at most as many genes as there are such candidates."""
    A = rows(ind)
    k = A.shape[1]
    n = int(np.max(up)) + 1
    mask = rng.random(A.shape) < indpb
    none = np.flatnonzero(~mask.any(axis=1))
    mask[none, rng.integers(0, k, size=none.size)] = True
    mask &= np.cumsum(mask, axis=1) <= n - k
    redraw(A, mask, rng, n, avoid=A.copy())
    return (ind,)
