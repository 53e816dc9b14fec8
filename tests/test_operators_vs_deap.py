"""The batched operators draw from the same distributions as DEAP's own: many children of the
same parents from each, compared by a two-sample Kolmogorov-Smirnov test per gene; and a
deliberately different parameter is told apart (the test has the power to fail)."""

import random

import numpy as np
import pytest
from deap import tools
from scipy.stats import ks_2samp

from zrp_ga.operators import crossover, mutation

N = 4000
LOW, UP = np.array([0.0, -1.0, 0.0]), np.array([1.0, 1.0, 2.0])
P1, P2 = np.array([0.2, -0.9, 1.0]), np.array([0.6, 0.5, 1.9])  # one gene near a bound


def _ours_cx(op, **params):
    A, B = np.tile(P1, (N, 1)), np.tile(P2, (N, 1))
    op(A, B, rng=np.random.default_rng(1), **params)
    return np.vstack([A, B])


def _deap_cx(op, **params):
    random.seed(1)
    out = []
    for _ in range(N):
        a, b = P1.tolist(), P2.tolist()
        op(a, b, **params)
        out += [a, b]
    return np.array(out)


def _ours_mut(op, **params):
    A = np.tile(P1, (2 * N, 1))
    op(A, rng=np.random.default_rng(2), **params)
    return A


def _deap_mut(op, **params):
    random.seed(2)
    out = []
    for _ in range(2 * N):
        a = P1.tolist()
        op(a, **params)
        out.append(a)
    return np.array(out)


CASES = {
    "sbx": (lambda eta: _ours_cx(crossover.sbx, low=LOW, up=UP, eta=eta, indpb=0.5),
            lambda eta: _deap_cx(tools.cxSimulatedBinaryBounded, eta=eta, low=LOW.tolist(), up=UP.tolist())),
    "blend": (lambda alpha: _ours_cx(crossover.blend, alpha=alpha), lambda alpha: _deap_cx(tools.cxBlend, alpha=alpha)),
    "polynomial": (lambda eta: _ours_mut(mutation.polynomial, low=LOW, up=UP, eta=eta, indpb=0.7),
                   lambda eta: _deap_mut(tools.mutPolynomialBounded, eta=eta, low=LOW.tolist(), up=UP.tolist(), indpb=0.7)),
    "gaussian": (lambda s: _ours_mut(mutation.gaussian, low=LOW, up=UP, sigma=s, indpb=0.7),
                 lambda s: _deap_mut(tools.mutGaussian, mu=0.0, sigma=(s * (UP - LOW)).tolist(), indpb=0.7)),
}  # fmt: skip
PARAMS = {"sbx": (20.0, 5.0), "blend": (0.5, 0.3), "polynomial": (20.0, 5.0), "gaussian": (0.1, 0.13)}


@pytest.mark.parametrize("name", CASES)
def test_same_distribution_as_deap(name):
    ours, deap = CASES[name]
    same, other = PARAMS[name]
    a, b = ours(same), deap(same)
    for g in range(3):
        assert ks_2samp(a[:, g], b[:, g]).pvalue > 1e-3, (name, g)  # seeded: deterministic
        assert np.all(np.isfinite(a[:, g]))
    # the same test tells a different parameter apart on at least one gene
    c = ours(other)
    assert min(ks_2samp(c[:, g], b[:, g]).pvalue for g in range(3)) < 1e-6
