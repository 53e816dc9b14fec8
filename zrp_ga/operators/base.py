"""What the batched operators share: genomes as rows of a batch (:func:`rows`), random segments
and blocks drawn for a whole batch, the compiled segment moves, the :func:`batched` mark that
tells :func:`zrp_ga.operators.build` an operator takes a whole generation, and the random
streams of several runs (:class:`Streams`) through which one call varies the rows of many runs.

Runs evolved together (:func:`zrp_ga.algorithms.ga.step_together`) pass an operator the rows of
all the runs that use it, one run's rows after another's, with a :class:`Streams` as ``rng``:
every random number is then drawn by :func:`draw` from the generator of the run whose rows it
varies, in the order and shapes that run alone draws them, so that each run's offspring are
exactly those it would have alone. An operator that draws only through :func:`draw` (and
:func:`parts`) says so with ``@batched(streams=True)``; the others are called once per run.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from zrp_ga.core.compiled import jit

Array = NDArray[np.float64]


def rows(a: Array) -> Array:
    """A 2-D view (N, K) of a genome or a batch; writing into it writes into ``a``."""
    if a.ndim == 1:
        return a[None]
    if a.ndim != 2:
        raise ValueError(f"genome: expected shape (K,) or (N, K), got {a.shape}")
    return a


class Streams:
    """The generators of several runs and how many consecutive rows of a batch each one owns
    (run ``i``: ``counts[i]`` rows, after those of the runs before it)."""

    def __init__(self, generators: Sequence[np.random.Generator], counts: Sequence[int]):
        self.generators, self.counts = list(generators), [int(c) for c in counts]
        ends = np.cumsum(self.counts)
        self.slices = [slice(int(e - c), int(e)) for e, c in zip(ends, self.counts)]
        self.total = int(ends[-1]) if len(ends) else 0


def parts(rng: np.random.Generator | Streams, n: int) -> list[tuple[np.random.Generator, slice]]:
    """The (generator, rows) pairs of a batch of ``n`` rows: the one generator and all rows, or
    each run's own (a :class:`Streams` must own exactly ``n`` rows)."""
    if not isinstance(rng, Streams):
        return [(rng, slice(0, n))]
    if rng.total != n:
        raise ValueError(f"random streams own {rng.total} rows, the batch has {n}")
    return list(zip(rng.generators, rng.slices))


def draw(rng: np.random.Generator | Streams, n: int, fn: Callable[[np.random.Generator, int], NDArray],
         axis: int = 0) -> NDArray:  # fmt: skip
    """``fn(generator, rows)`` for a batch of ``n`` rows: called once with ``rng``, or once per
    run of a :class:`Streams` with its rows, the draws joined along ``axis`` (the rows' axis of
    what ``fn`` returns)."""
    if not isinstance(rng, Streams):
        return fn(rng, n)
    pieces = [fn(g, s.stop - s.start) for g, s in parts(rng, n)]
    return pieces[0] if len(pieces) == 1 else np.concatenate(pieces, axis=axis)


def segments(rng: np.random.Generator | Streams, lo: NDArray | int, hi: NDArray | int, N: int) -> tuple[NDArray, NDArray]:
    """N random segments [i, j], i < j, uniform over the pairs of loci in [lo, hi) (per row or
    shared). Drawn from one ``rng.random`` call: ``rng.integers`` with array bounds costs 10x."""
    span = np.asarray(hi) - np.asarray(lo)
    r = draw(rng, N, lambda g, n: g.random((2, n)), axis=1)
    x = (r[0] * span).astype(np.intp)
    y = (r[1] * (span - 1)).astype(np.intp)
    y += y >= x
    return lo + np.minimum(x, y), lo + np.maximum(x, y)


def block_bounds(rng: np.random.Generator, N: int, blocks: list[tuple[int, int]]) -> tuple[NDArray, NDArray]:
    """Per row, the [lo, hi) of a block chosen with probability proportional to its size
    (blocks of fewer than two genes never chosen)."""
    usable = np.array([(a, b) for a, b in blocks if b - a >= 2])
    sizes = usable[:, 1] - usable[:, 0]
    pick = np.searchsorted(np.cumsum(sizes), draw(rng, N, lambda g, n: g.random(n)) * sizes.sum(), side="right")
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


def batched(fn: Callable | None = None, *, streams: bool = False) -> Callable:
    """Mark ``fn`` as taking batches of genomes (N, K) and a ``rng``: :func:`build` then calls it
    on a whole generation rather than one individual at a time. ``streams=True``: it draws only
    through :func:`draw` and :func:`parts`, so that one call can vary the rows of several runs
    (module docstring)."""

    def mark(fn: Callable) -> Callable:
        fn.batched, fn.streams = True, streams
        return fn

    return mark if fn is None else mark(fn)
