"""Variation operators on numpy genomes, one module per family, and :func:`build`, which turns
an operator's config node into the function the GA calls.

Every operator keeps DEAP's calling convention and changes its arguments in place:
``cx(ind1, ind2, rng, **params) -> (ind1, ind2)``, ``mut(ind, rng, **params) -> (ind,)``,
``select(costs, k, rng, **params) -> indices``. The operators here are :func:`batched`: an
argument may be one genome (K,) or a batch of genomes (N, K), each row varied independently, so
that the GA varies a whole generation in a few numpy calls; random numbers come from the
``numpy.random.Generator`` passed in, drawn for the whole batch at once, and the segment moves
are small compiled loops. Any other function named in a config, DEAP's own operators
(``deap.tools.cxBlend``) included, is applied one individual at a time through
:mod:`zrp_ga.operators.deap_adapter` (slower; for comparison).
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from typing import Any

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


# What the usual operator parameters must be, whichever operator takes them (DEAP's included).
RULES: dict[str, tuple[Callable[[Any], bool], str]] = {
    "indpb": (lambda v: 0.0 <= v <= 1.0, "a probability in [0, 1]"),
    "sigma": (lambda v: v > 0.0, "a number > 0"),
    "eta": (lambda v: v >= 0.0, "a number >= 0"),
    "alpha": (lambda v: v >= 0.0, "a number >= 0"),
    "size": (lambda v: v >= 1 and float(v).is_integer(), "a whole number >= 1"),
    "tournsize": (lambda v: v >= 1 and float(v).is_integer(), "a whole number >= 1"),
    "fraction": (lambda v: 0.0 < v <= 1.0, "a fraction in (0, 1]"),
    "rcond": (lambda v: 0.0 <= v < 1.0, "a number in [0, 1)"),
}


def _check(key: str, params: dict) -> None:
    for name, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        ok, what = RULES.get(name, (lambda v: True, "a finite number"))
        if not (np.isfinite(value) and ok(value)):
            raise ValueError(f"{key}.{name}: must be {what}, got {value}")


def target(node: Mapping[str, Any], key: str) -> tuple[Callable, dict]:
    """The function an operator node names by ``_target_`` and its parameters; ValueError naming
    ``key`` when the function cannot be found or a parameter is not one it takes.

    The nodes are Hydra ``_target_`` / ``_partial_`` configs, with the same meaning as
    ``hydra.utils.instantiate(node)``; they are bound here into a plain ``functools.partial``
    because hydra-core 1.3.8 wraps instantiated partials in a target-policy check that runs on
    every call (about 0.4 ms, more than a generation's variation).
    """
    from hydra.utils import get_method

    params = dict(node)
    name = params.pop("_target_", None)
    params.pop("_partial_", None)
    if not name:
        raise ValueError(f"{key}._target_: an operator needs the dotted name of a function")
    try:
        fn = get_method(name)
    except Exception as exc:  # Hydra wraps the import error; keep its first line
        raise ValueError(f"{key}._target_: cannot import {name!r} ({str(exc).splitlines()[0]})") from None
    takes = [k for k in inspect.signature(fn).parameters if k not in ("ind", "ind1", "ind2", "individual",
                                                                      "individuals", "costs", "k", "rng")]  # fmt: skip
    unknown = sorted(set(params) - set(takes))
    if unknown:
        raise ValueError(f"{key}: unknown parameter {unknown[0]!r} for {name} (takes: {', '.join(takes) or 'none'})")
    _check(key, params)
    return fn, params


def build(
    node: Mapping[str, Any] | None, key: str, family: str, rng: np.random.Generator, **context: Any
) -> Callable | None:
    """The operator of config node ``node`` (None: no operator), ready for the GA: the node's
    parameters, ``rng``, and whichever of ``context`` (the gene ranges ``low`` and ``up``, the
    gene ``blocks``, the ``problem``) the function takes bound; per-individual functions wrapped by the adapter for ``family``
    (``crossover``, ``mutation``, ``selection``)."""
    if node is None:
        return None
    fn, params = target(node, key)
    takes = inspect.signature(fn).parameters
    params.update({k: v for k, v in context.items() if k in takes and k not in params})
    if getattr(fn, "batched", False):
        return functools.partial(fn, rng=rng, **params)
    from zrp_ga.operators import deap_adapter

    return deap_adapter.wrap(fn, family, **params)
