"""A residual model on joint space: what no parametric term explains, learnt from the position
residuals of a calibrated model (docs/model.md, "Beyond geometry"; Rasmussen and Williams,
*Gaussian Processes for Machine Learning*, 2006, ch. 2 and 5).

The residuals ``r_k = p_meas,k - p_model(q_k)`` (M, 3) m at the calibration poses q_k (M, n)
(rad, m) are modelled by a Gaussian process with **zero prior mean**, one kernel shared by the
three coordinates, on inputs normalised per joint (centred by the poses' mean, divided by their
standard deviation) and outputs divided by their RMS (not centred: the prior mean stays zero):

    k(x, x') = s^2 Matern_{5/2}(x, x'; l_1 .. l_n) + w^2 delta(x, x')      (ARD: a length per joint)

with ``s``, ``l_j`` and ``w`` chosen by the log marginal likelihood (scikit-learn's
``GaussianProcessRegressor``, L-BFGS-B from unit lengths, no random restarts: deterministic). The
likelihood is maximised on at most :data:`MAX_FIT_POSES` poses (a fixed subset, every k-th pose)
and the process then conditioned on all of them with those hyperparameters. The correction at a
pose q is the posterior mean; far from every calibration pose (many length scales away in the
joints the kernel found to matter) it falls back to the prior mean, zero: the parametric model
alone. Joints whose fitted length is long (the residual does not depend on them) do not make a
pose "far".

Saved without pickle (:meth:`Residual.to_dict`, a run's :data:`FILE`): the training inputs and
residuals, the normalisation and the kernel's log-hyperparameters; :meth:`Residual.from_dict`
conditions the same process again without optimising (the same numbers, to round-off).

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> q = rng.uniform(-1, 1, (60, 2))
>>> r = np.column_stack([1e-4 * np.sin(2 * q[:, 0]), np.zeros(60), 1e-4 * q[:, 1]])
>>> gp = Residual.fit(q, r)
>>> bool(np.abs(gp.predict(q) - r).max() < 2e-5), bool(np.abs(gp.predict([[1e4, 1e4]])).max() < 1e-12)
(True, True)
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # scikit-learn has no type information: these names are Any to mypy, said for the reader
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import Kernel

Array = NDArray[np.float64]
FILE = "residual.json"
KIND = "gaussian_process"
MAX_FIT_POSES = 600  # the marginal likelihood is maximised on at most this many poses (O(M^3) per step)
NU = 2.5  # Matern smoothness
LENGTH_BOUNDS = (1e-2, 1e3)  # in normalised joint units (standard deviations of the calibration poses)
SIGNAL_BOUNDS = (1e-4, 1e2)  # s^2, in units of the residuals' mean square
NOISE_BOUNDS = (1e-6, 1e1)  # w^2, the same units


def _kernel(n: int) -> Kernel:
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    return ConstantKernel(1.0, SIGNAL_BOUNDS) * Matern(np.ones(n), LENGTH_BOUNDS, nu=NU) + WhiteKernel(0.1, NOISE_BOUNDS)


def _regressor(kernel: Kernel, optimise: bool) -> GaussianProcessRegressor:
    from sklearn.gaussian_process import GaussianProcessRegressor

    return GaussianProcessRegressor(kernel, optimizer="fmin_l_bfgs_b" if optimise else None, normalize_y=False,
                                    n_restarts_optimizer=0, copy_X_train=True, random_state=0)  # fmt: skip


@dataclasses.dataclass(frozen=True, eq=False)
class Residual:
    """A Gaussian process conditioned on residuals ``r`` (M, 3) m at poses ``q`` (M, n), with the
    inputs' ``centre`` and ``scale`` (n,), the outputs' ``y_scale`` (m) and the kernel's
    log-hyperparameters ``theta`` (module docstring)."""

    q: Array
    r: Array
    centre: Array
    scale: Array
    y_scale: float
    theta: Array
    _gp: Any = dataclasses.field(default=None, repr=False)  # the conditioned GaussianProcessRegressor

    @classmethod
    def fit(cls, q: ArrayLike, r: ArrayLike) -> Residual:
        """The process on residuals ``r`` (M, 3) m at poses ``q`` (M, n), its hyperparameters by
        the marginal likelihood (module docstring)."""
        q, r = _inputs(q, r)
        centre = q.mean(axis=0)
        scale = q.std(axis=0)
        scale = np.where(scale > 1e-9, scale, 1.0)  # a joint that never moves: left as is
        y_scale = float(np.sqrt(np.mean(r**2))) or 1.0
        x, y = (q - centre) / scale, r / y_scale
        step = max(1, int(np.ceil(len(x) / MAX_FIT_POSES)))
        import warnings

        from sklearn.exceptions import ConvergenceWarning
        from threadpoolctl import threadpool_limits

        with warnings.catch_warnings(), threadpool_limits(limits=1, user_api="blas"):  # as the runs (zrp_ga.run.execute)
            warnings.simplefilter("ignore", ConvergenceWarning)  # a length on its bound: the joint does not matter
            theta = _regressor(_kernel(q.shape[1]), True).fit(x[::step], y[::step]).kernel_.theta
            return cls._conditioned(q, r, centre, scale, y_scale, theta)

    @classmethod
    def _conditioned(cls, q: Array, r: Array, centre: Array, scale: Array, y_scale: float, theta: Array) -> Residual:
        kernel = _kernel(q.shape[1]).clone_with_theta(np.asarray(theta, dtype=float))
        gp = _regressor(kernel, False).fit((q - centre) / scale, r / y_scale)
        return cls(q, r, centre, scale, float(y_scale), np.asarray(theta, dtype=float), gp)

    def predict(self, q: ArrayLike, std: bool = False) -> Array | tuple[Array, Array]:
        """The correction (M, 3) m at poses ``q`` (M, n) (the posterior mean; with ``std`` also
        its standard deviation (M,) m per coordinate, the signal's only)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != self.q.shape[1]:
            raise ValueError(f"residual model: poses of {q.shape[1]} joints, it was fitted on {self.q.shape[1]}")
        if not len(q):
            return (np.zeros((0, 3)), np.zeros(0)) if std else np.zeros((0, 3))
        x = (q - self.centre) / self.scale
        if not std:
            return self._gp.predict(x) * self.y_scale
        mean, s = self._gp.predict(x, return_std=True)
        s = np.atleast_2d(s.T).T[:, 0] if s.ndim > 1 else s
        return mean * self.y_scale, np.sqrt(np.maximum(s**2 - self.noise, 0.0)) * self.y_scale

    def spread(self, q: ArrayLike) -> Array:
        """The predictive spread (M,) m at poses ``q`` (M, n) as a radius: ``sqrt(3) s``, ``s`` the
        standard deviation per coordinate (:meth:`predict`), which prediction, the run's pose
        table and compensation add in quadrature to the parametric model's 1-sigma radius."""
        return np.sqrt(3.0) * self.predict(q, std=True)[1]

    def correction(self, q: ArrayLike) -> Array:
        """The correction (M, 3) m at poses ``q`` (M, n): the posterior mean."""
        return self._gp.predict((np.atleast_2d(np.asarray(q, dtype=float)) - self.centre) / self.scale) * self.y_scale

    @property
    def noise(self) -> float:
        """The white noise's variance, in normalised output units."""
        return float(np.exp(self.theta[-1]))

    def hyperparameters(self) -> dict[str, Any]:
        """The kernel's fitted values: signal and noise RMS (m), each joint's length (rad or m)."""
        t = np.exp(self.theta)
        return {"kernel": f"{self._gp.kernel_}", "signal_rms_mm": float(np.sqrt(t[0])) * self.y_scale * 1e3,
                "noise_rms_mm": float(np.sqrt(t[-1])) * self.y_scale * 1e3,
                "length_per_joint": (t[1:-1] * self.scale).tolist(), "poses": len(self.q)}  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        """Everything :meth:`from_dict` needs, as plain numbers (no pickle)."""
        return {"kind": KIND, "kernel": f"ConstantKernel * Matern(nu={NU}, ARD) + WhiteKernel", "theta": self.theta.tolist(),
                "centre": self.centre.tolist(), "scale": self.scale.tolist(), "y_scale": self.y_scale,
                "q": self.q.tolist(), "residual_m": self.r.tolist(), "hyperparameters": self.hyperparameters()}  # fmt: skip

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Residual:
        """The process :meth:`to_dict` wrote, conditioned again with its hyperparameters."""
        if d.get("kind") != KIND:
            raise ValueError(f"residual model: kind {d.get('kind')!r}, expected {KIND!r}")
        q, r = _inputs(d["q"], d["residual_m"])
        return cls._conditioned(q, r, np.asarray(d["centre"], float), np.asarray(d["scale"], float), float(d["y_scale"]),
                                np.asarray(d["theta"], float))  # fmt: skip

    def write(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict()))

    @classmethod
    def read(cls, path: str | Path) -> Residual:
        """From a run directory's :data:`FILE` (or that file)."""
        path = Path(path)
        path = path / FILE if path.is_dir() else path
        return cls.from_dict(json.loads(path.read_text()))


def _inputs(q: ArrayLike, r: ArrayLike) -> tuple[Array, Array]:
    q = np.atleast_2d(np.asarray(q, dtype=float))
    r = np.asarray(r, dtype=float).reshape(len(q), 3)
    if len(q) < 2:
        raise ValueError(f"residual model: {len(q)} pose(s); it needs at least 2")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(r))):
        raise ValueError("residual model: NaN or inf among the poses or residuals")
    return q, r
