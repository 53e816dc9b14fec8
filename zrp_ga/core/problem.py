"""What an optimiser may ask of a problem: a required part and optional parts, each declared.

Every problem is a :class:`Problem`: gene ranges ``lower``/``upper`` (K,), gene ``names`` and
one vectorised ``costs(X)`` over a population (pymoo's shape: bounds plus one evaluation).
Whatever else an algorithm or operator uses is one of the small protocols below, and it asks
with ``isinstance(problem, Part)`` (they are ``runtime_checkable``), never by probing names:

- :class:`Sampling`: ``sample(rng, size)`` draws the first genomes (combinatorial genomes,
  which uniform draws in the ranges would not give); without it, uniform in the ranges;
- :class:`Repairing`: ``repair(X, rng)`` puts varied genomes back into the genome space, in
  place of ``algorithm.repair`` (clipping or reflecting into the ranges);
- :class:`GeneBlocks`: ``gene_blocks``, the [start, stop) of each block of genes that the
  block-wise operators (``inversion=block``, ``rotation=block``) keep apart; without it, one
  block of the whole genome;
- :class:`LeastSquares`: ``residual(x)``, ``jacobian(x)`` and ``n_rows`` of one genome, for
  Levenberg-Marquardt and the pseudo-inverse step (``refine=pinv``);
- the calibration problems' own parts (the calibration data behind a problem, a task that
  judges its own result) are in :mod:`zrp_ga.problems.protocol`.

:class:`zrp_ga.model.cost.CalibrationProblem` has every part; the pose-selection problem
(:class:`zrp_ga.problems.selection.SelectionProblem`) subclasses the parts it has (sampling,
repair, gene blocks, the identifiability of its candidates) and has no Jacobian. A problem
written for zrp_ga may subclass the parts it implements, as a declaration; ``isinstance``
checks the methods' presence either way (not their signatures).

>>> import numpy as np
>>> class Sphere:
...     lower, upper, names = -np.ones(2), np.ones(2), ["a", "b"]
...     def costs(self, X):
...         return np.sum(np.atleast_2d(X) ** 2, axis=1)
>>> isinstance(Sphere(), Problem), isinstance(Sphere(), Sampling)
(True, False)
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@runtime_checkable
class Problem(Protocol):
    """The required part: gene ranges ``lower``/``upper`` (K,), gene ``names`` (K) and the cost
    (P,) of every genome of a population X (P, K), NaN or inf where a genome breaks the model."""

    lower: Array
    upper: Array

    @property
    def names(self) -> list[str]: ...

    def costs(self, X: ArrayLike) -> Array: ...


@runtime_checkable
class Sampling(Protocol):
    """Draws the first genomes itself: ``sample(rng, size) -> (size, K)``."""

    def sample(self, rng: np.random.Generator, size: int) -> Array: ...


@runtime_checkable
class Repairing(Protocol):
    """Puts varied genomes X (N, K) back into its genome space, in place: ``repair(X, rng) -> X``."""

    def repair(self, X: Array, rng: np.random.Generator) -> Array: ...


@runtime_checkable
class GeneBlocks(Protocol):
    """Its genes come in blocks ``[(start, stop), ...]`` that block-wise operators keep apart."""

    gene_blocks: list[tuple[int, int]]


@runtime_checkable
class LeastSquares(Problem, Protocol):
    """A problem with a weighted residual (``n_rows``,) of one genome and its Jacobian
    (``n_rows``, K), with ``residual(x + d) ~ residual(x) - jacobian(x) d``."""

    n_rows: int

    def residual(self, x: ArrayLike) -> Array: ...

    def jacobian(self, x: ArrayLike) -> Array: ...
