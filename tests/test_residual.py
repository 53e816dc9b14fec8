"""The residual model (zrp_ga.model.residual): its posterior mean against the Gaussian-process
formula written here (a Matern 5/2 ARD kernel by hand), its fall back to the zero prior mean far
from the data, and a file round trip without pickle."""

import json

import numpy as np
import pytest

from zrp_ga.model.residual import FILE, Residual


def _data(rng, M=50, n=3):
    q = rng.uniform(-1.5, 1.5, (M, n))
    r = np.column_stack([2e-4 * np.sin(2 * q[:, 0]) * np.cos(q[:, 1]), 1e-4 * q[:, 1] ** 2, -1e-4 * q[:, 0]])
    return q, r + rng.normal(scale=1e-5, size=r.shape)


def _matern52(A, B, lengths):
    """Matern nu = 5/2 with one length per input (Rasmussen and Williams, eq. 4.17)."""
    d = np.sqrt((((A[:, None, :] - B[None, :, :]) / lengths) ** 2).sum(axis=2))
    s = np.sqrt(5.0) * d
    return (1.0 + s + s**2 / 3.0) * np.exp(-s)


def test_posterior_mean_is_the_gp_formula_with_the_fitted_hyperparameters(rng):
    q, r = _data(rng)
    gp = Residual.fit(q, r)
    signal, lengths, noise = np.exp(gp.theta[0]), np.exp(gp.theta[1:-1]), np.exp(gp.theta[-1])
    x = (q - q.mean(axis=0)) / q.std(axis=0)  # normalised inputs, as the module docstring says
    y_scale = np.sqrt(np.mean(r**2))  # outputs scaled, not centred
    q_new = rng.uniform(-1.5, 1.5, (7, 3))
    x_new = (q_new - q.mean(axis=0)) / q.std(axis=0)
    K = signal * _matern52(x, x, lengths) + noise * np.eye(len(x))
    expected = signal * _matern52(x_new, x, lengths) @ np.linalg.solve(K, r / y_scale) * y_scale
    np.testing.assert_allclose(gp.predict(q_new), expected, atol=1e-9 * y_scale)


def test_the_correction_fades_to_the_prior_mean_zero_far_from_the_data(rng):
    q, r = _data(rng)
    gp = Residual.fit(q, r)
    near = gp.predict(q[:5])
    assert np.abs(near).max() > 5e-5  # it does correct where it has data
    lengths = np.exp(gp.theta[1:-1]) * q.std(axis=0)  # in joint units
    for k in (1, 3, 10, 30):  # k fitted lengths beyond the data along every joint
        far = q.max(axis=0) + k * lengths
        size = np.abs(gp.predict(far[None])).max()
        if k == 30:
            assert size < 1e-12 * np.abs(r).max()  # the prior mean: zero, the parametric model alone
    steps = [np.abs(gp.predict((q.max(axis=0) + k * lengths)[None])).max() for k in (1, 3, 10)]
    assert steps[0] >= steps[1] >= steps[2]


def test_the_saved_model_predicts_the_same_after_reading_without_pickle(rng, tmp_path):
    q, r = _data(rng)
    gp = Residual.fit(q, r)
    gp.write(tmp_path / FILE)
    text = (tmp_path / FILE).read_text()
    assert json.loads(text)["kind"] == "gaussian_process"  # plain JSON
    back = Residual.read(tmp_path)
    q_new = rng.uniform(-2, 2, (20, 3))
    np.testing.assert_allclose(back.predict(q_new), gp.predict(q_new), rtol=0, atol=1e-12)


def test_bad_inputs_are_one_line(rng):
    with pytest.raises(ValueError, match="at least 2"):
        Residual.fit(np.zeros((1, 3)), np.zeros((1, 3)))
    q, r = _data(rng)
    r[3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Residual.fit(q, r)
    gp = Residual.fit(*_data(rng))
    with pytest.raises(ValueError, match="fitted on 3"):
        gp.predict(np.zeros((2, 4)))
