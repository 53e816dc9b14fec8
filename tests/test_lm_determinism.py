"""The Levenberg-Marquardt fit gives the same numbers, bit for bit, every time in one process,
whatever the process allocated before and with or without a limit on the BLAS threads.

scipy's MINPACK (C since scipy 1.15) reads, in its QR factorisation, one element past the end of
the Jacobian's array (:func:`zrp_ga.problems.least_squares._padded` tells the story); that
element decided the column pivoting, so the same fit took 39 to 47 evaluations and ended up to
1e-9 apart from one call to the next. Here the memory that array is about to get is filled first
with different numbers (an array of its size made and freed just before, as the process's other
work leaves it): every fit must still be the same. The calibration is that of
tests/test_api_data.py (a puma560 with link vectors off by up to 1 mm, 40 tracker points)."""

import numpy as np
import pytest
from test_api_data import ARM, PV, QV, P, Q
from threadpoolctl import threadpool_limits

import zrp_ga
from zrp_ga.problems.least_squares import levenberg_marquardt

JUNK = [0.0, 1.0, -1e3, 1e300, np.nan]  # what the freed memory holds


class Littered:
    """``problem`` whose Jacobian, once computed, fills memory with ``junk`` and frees it:
    arrays of the sizes MINPACK's Jacobian may take (with and without an added parameter or
    row, plus the element read past its end), several of each, made and freed together. scipy
    evaluates the Jacobian at the start just before MINPACK allocates its own, and malloc hands
    out memory of a size freed last."""

    def __init__(self, problem, junk: float) -> None:
        self.problem, self.junk = problem, junk
        m, n = problem.n_rows, problem.lower.size
        self.sizes = [r * c + 1 for r in (m, m + 1) for c in (n, n + 1)]

    def __getattr__(self, name: str):
        return getattr(self.problem, name)

    def jacobian(self, x):
        J = self.problem.jacobian(x)
        litter = [np.full(size, self.junk) for size in self.sizes for _ in range(4)]
        del litter
        return J


@pytest.fixture(scope="module")
def problem():
    return zrp_ga.calibrate(ARM, (Q, P), validation=(QV, PV), algorithm="lm").task.problem


def _same(fits) -> None:
    first = fits[0]
    for fit in fits[1:]:
        assert fit.nevals == first.nevals
        np.testing.assert_array_equal(fit.x, first.x)
        assert fit.cost == first.cost


def test_lm_fit_does_not_depend_on_what_the_memory_held(problem):
    fits = [levenberg_marquardt(Littered(problem, junk)) for junk in JUNK]
    _same(fits)
    # it is a fit: the cost went down from the nominal arm's, and a fresh fit agrees
    assert fits[0].cost < 0.2 * fits[0].initial_cost[0]
    _same([fits[0], levenberg_marquardt(problem)])


def test_lm_fit_is_the_same_with_and_without_a_blas_thread_limit(problem):
    fits = []
    for junk in JUNK[:3]:
        with threadpool_limits(limits=1, user_api="blas"):
            fits.append(levenberg_marquardt(Littered(problem, junk)))
        fits.append(levenberg_marquardt(Littered(problem, junk)))
    _same(fits)


def test_calibrate_gives_the_same_numbers_every_time():
    """The whole route (``zrp_ga.calibrate``, whose run layer limits the BLAS threads), three
    times in one process."""
    cals = [zrp_ga.calibrate(ARM, (Q, P), validation=(QV, PV), algorithm="lm") for _ in range(3)]
    for cal in cals[1:]:
        assert cal.result.nevals == cals[0].result.nevals
        np.testing.assert_array_equal(cal.result.x, cals[0].result.x)
        assert cal.summary["validation_rms_mm"] == cals[0].summary["validation_rms_mm"]
