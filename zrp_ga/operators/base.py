"""What the batched operators share: genomes as rows of a batch (:func:`rows`), random segments
and blocks drawn for a whole batch, the segment moves, the :func:`batched` mark that
tells :func:`zrp_ga.operators.build` an operator takes a whole generation, and the random
streams of several runs (:class:`Streams`) through which one call varies the rows of many runs.

The segment moves (:func:`reverse_segments`, :func:`rotate_segments`, :func:`swap_segments`)
are numpy gathers over the whole batch: every index they use is checked by numpy, so that no
genome size (one gene included) can make them write outside a genome, and nothing is compiled.
A segment of fewer than two genes (a genome, or a block, of one gene) is left as it is.

Runs evolved together (:func:`zrp_ga.algorithms.ga.step_together`) pass an operator the rows of
all the runs that use it, one run's rows after another's, with a :class:`Streams` as ``rng``:
every random number is then drawn by :func:`draw` from the generator of the run whose rows it
varies, in the order and shapes that run alone draws them, so that each run's offspring are
exactly those it would have alone. An operator that draws only through :func:`draw` (and
:func:`parts`) says so with ``@batched(streams=True)``; the others are called once per run.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Sequence
from typing import Any, TypeVar, overload

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


class Streams:
    """The generators of several runs and how many consecutive rows of a batch each one owns
    (run ``i``: ``counts[i]`` rows, after those of the runs before it)."""

    def __init__(self, generators: Sequence[np.random.Generator], counts: Iterable[int]):
        self.generators, self.counts = list(generators), [int(c) for c in counts]
        ends = list(itertools.accumulate(self.counts))
        self.slices = [slice(e - c, e) for e, c in zip(ends, self.counts)]
        self.total = ends[-1] if ends else 0


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
    shared); where [lo, hi) holds fewer than two loci, there is no pair and the segment is
    [lo, lo] (a move of one gene or none: nothing moves). Drawn from one ``rng.random`` call
    (two numbers per row, whatever the span): ``rng.integers`` with array bounds costs 10x."""
    span = np.asarray(hi) - np.asarray(lo)
    r = draw(rng, N, lambda g, n: g.random((2, n)), axis=1)
    x = (r[0] * span).astype(np.intp)
    y = (r[1] * (span - 1)).astype(np.intp)
    y += y >= x
    pair = span >= 2
    return lo + np.where(pair, np.minimum(x, y), 0), lo + np.where(pair, np.maximum(x, y), 0)


def block_bounds(rng: np.random.Generator, N: int, blocks: list[tuple[int, int]]) -> tuple[NDArray, NDArray]:
    """Per row, the [lo, hi) of a block chosen with probability proportional to its size
    (blocks of fewer than two genes never chosen; [0, 0) for every row if no block has two)."""
    usable = np.array([(a, b) for a, b in blocks if b - a >= 2], dtype=np.intp).reshape(-1, 2)
    sizes = usable[:, 1] - usable[:, 0]
    u = draw(rng, N, lambda g, n: g.random(n))
    if not len(usable):
        return np.zeros(N, dtype=np.intp), np.zeros(N, dtype=np.intp)
    pick = np.searchsorted(np.cumsum(sizes), u * sizes.sum(), side="right")
    return usable[pick, 0], usable[pick, 1]


def _gather(A: Array, source: NDArray[np.intp]) -> None:
    """``A[r, k] = A[r, source[r, k]]`` for every row at once, in place (numpy checks the indices)."""
    A[:] = np.take_along_axis(A, source, axis=1)


def _inside(A: Array, i: NDArray, j: NDArray) -> tuple[NDArray, NDArray[np.bool_]]:
    """The loci (1, K) and, per row, which lie in [i, j] (N, K)."""
    k = np.arange(A.shape[1])[None]
    return k, (k >= np.asarray(i)[:, None]) & (k <= np.asarray(j)[:, None])


def reverse_segments(A: Array, i: NDArray, j: NDArray) -> None:
    """Reverse ``A[r, i[r] .. j[r]]`` (inclusive) of every row in place: locus k of the segment
    takes the gene at i + j - k. A row with j <= i is left as it is."""
    A = rows(A)
    k, inside = _inside(A, i, j)
    _gather(A, np.where(inside, np.asarray(i)[:, None] + np.asarray(j)[:, None] - k, k))


def rotate_segments(A: Array, i: NDArray, j: NDArray, shift: NDArray) -> None:
    """Shift ``A[r, i[r] .. j[r]]`` (inclusive) cyclically right by ``shift[r]`` places, in
    place: locus k of the segment takes the gene at i + ((k - i - shift) mod (j - i + 1))."""
    A = rows(A)
    k, inside = _inside(A, i, j)
    i, length = np.asarray(i)[:, None], np.maximum(np.asarray(j) - np.asarray(i) + 1, 1)[:, None]
    _gather(A, np.where(inside, i + (k - i - np.asarray(shift)[:, None]) % length, k))


def swap_segments(A: Array, B: Array, lo: NDArray, hi: NDArray) -> None:
    """Swap ``A[r, lo[r]:hi[r]]`` with ``B[r, lo[r]:hi[r]]`` for every row, in place."""
    A, B = rows(A), rows(B)
    k = np.arange(A.shape[1])[None]
    mask = (k >= np.asarray(lo)[:, None]) & (k < np.asarray(hi)[:, None])
    a = A.copy()  # numpy slices are views: swap through a copy
    np.copyto(A, B, where=mask)
    np.copyto(B, a, where=mask)


F = TypeVar("F", bound=Callable[..., Any])


@overload
def batched(fn: F, *, streams: bool = False) -> F: ...


@overload
def batched(fn: None = None, *, streams: bool = False) -> Callable[[F], F]: ...


def batched(fn: F | None = None, *, streams: bool = False) -> F | Callable[[F], F]:
    """Mark ``fn`` as taking batches of genomes (N, K) and a ``rng``: :func:`build` then calls it
    on a whole generation rather than one individual at a time. ``streams=True``: it draws only
    through :func:`draw` and :func:`parts`, so that one call can vary the rows of several runs
    (module docstring)."""

    def mark(fn: F) -> F:
        fn.batched, fn.streams = True, streams  # type: ignore[attr-defined]  # function attributes, read back with getattr
        return fn

    return mark if fn is None else mark(fn)
