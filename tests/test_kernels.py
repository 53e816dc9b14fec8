"""The kernels' two paths and their guards: each numpy twin (zrp_ga.model._numpy_kernels) gives
the compiled kernel's numbers bit for bit, for every arm size from one joint, population sizes
around the compiled chunks and any number of poses; shapes the kernels would index past are
refused; the choice between the paths (zrp_ga.core.compiled); a default run that imports no
numba; and the shape tests run again with numba's bounds checking on.

The compiled kernels' values are checked against independent references in test_kinematics.py
and test_error_model.py (a DH chain, finite differences), on both paths.
"""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from zrp_ga.core import compiled
from zrp_ga.model import _kernels, _numpy_kernels, kinematics, so3

pytestmark = pytest.mark.boundscheck
ROOT = Path(__file__).resolve().parents[1]


def _arm(rng, n, P, prismatic=None):
    """P parameter sets of an n-joint arm in the kernels' layout, axes near unit, some joints
    prismatic; one gene NaN when P > 2."""
    prism = rng.random(n) < 0.3 if prismatic is None else prismatic
    u0 = rng.normal(size=(P, n, 3))
    u0 /= np.linalg.norm(u0, axis=-1, keepdims=True)
    u0 += rng.normal(scale=0.01, size=u0.shape)
    b0 = rng.normal(scale=0.3, size=(P, n + 1, 3))
    if P > 2:
        b0[P // 2, n // 2, 1] = np.nan
    R_h0 = so3.rodrigues(rng.uniform(-3, 3), rng.normal(size=3) / np.sqrt(3))
    U, B, H = kinematics._population(u0, b0, R_h0)
    return prism, U, B, H


def _terms(rng, M, prism):
    q = rng.uniform(-3, 3, size=(M, len(prism)))
    return q, tuple(np.ascontiguousarray(a) for a in kinematics.joint_terms(q, prism))


CASES = [(n, P, M) for n, P, M in itertools.product((1, 2, 3, 6, 8), (1, 2, 31, 32, 33, 65), (0, 1, 2, 5)) if (n + P + M) % 2 == 0 or M == 1]


@pytest.mark.parametrize("n, P, M", CASES)
def test_numpy_twins_give_the_compiled_kernels_numbers_bit_for_bit(n, P, M):
    rng = np.random.default_rng(100 * n + 10 * P + M)
    prism, U, B, H = _arm(rng, n, P)
    q, (c, s, t) = _terms(rng, M, prism)
    p_meas, wp = rng.normal(size=(M, 3)), rng.uniform(0.5, 2, size=(M, 3))
    R_meas = so3.rodrigues(rng.uniform(-3, 3, M), rng.normal(size=(M, 3)) / np.sqrt(3)) if M else np.zeros((0, 3, 3))
    outs = {}
    for name, mod in (("compiled", _kernels), ("numpy", _numpy_kernels)):
        R, p = np.full((P, M, 3, 3), 7.0), np.full((P, M, 3), 7.0)
        mod.forward(U, B, H, c, s, t, R, p) if mod is _numpy_kernels else mod.forward_kernel(U, B, H, c, s, t, R, p)
        sums = []
        for use_rot in (True, False):
            out = np.full((2, P), 7.0)
            args = (U, B, H, c, s, t, p_meas, wp, np.ascontiguousarray(R_meas), use_rot, out)
            if mod is _kernels:
                mod.residual_rodrigues(*args, 0, -(-P // _kernels.LANES))
            else:
                mod.residual_rodrigues(*args)
            sums.append(out)
        J, Rn = np.zeros((M, 6, 6 * n)), np.full((M, 3, 3), 7.0)
        jac = mod.jacobian_kernel if mod is _kernels else mod.jacobian
        jac(np.ascontiguousarray(U[:, :, 0]), np.ascontiguousarray(B[:, :, 0]), prism, np.cos(q), np.sin(q), q, J, Rn)
        outs[name] = [R, p, *sums, J, Rn]
    for a, b in zip(outs["compiled"], outs["numpy"]):
        np.testing.assert_array_equal(a, b)  # NaN where NaN, every other bit the same


def test_the_public_functions_agree_on_both_paths(monkeypatch):
    """forward_batch, residual_sums and jacobian_arrays through ZRP_GA_KERNELS=numpy and =compiled."""
    rng = np.random.default_rng(7)
    prism = np.array([False, True, False, False, True, False])
    u0 = rng.normal(size=(9, 6, 3))
    b0 = rng.normal(size=(9, 7, 3))
    q = rng.uniform(-2, 2, size=(4, 6))
    p_meas, R_meas = rng.normal(size=(4, 3)), so3.rodrigues(rng.uniform(-3, 3, 4), np.eye(3)[[0, 1, 2, 0]])
    from zrp_ga.model import error_model

    got = {}
    for path in ("numpy", "compiled"):
        monkeypatch.setenv("ZRP_GA_KERNELS", path)
        got[path] = [*kinematics.forward_batch(u0, b0, np.eye(3), q, prism),
                     kinematics.residual_sums(u0, b0, np.eye(3), q, p_meas, R_meas, prism),
                     error_model.jacobian_arrays(u0[0], b0[0], prism, q, base=True, hand=True)]  # fmt: skip
    for a, b in zip(got["numpy"], got["compiled"]):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    "change, message",
    [(lambda a: a.update(U=a["U"][:0]), r"U: expected shape \(n, 3, P\) with n >= 1"),
     (lambda a: a.update(B=a["B"][:-1]), r"B: expected shape \(7, 3, 5\)"),
     (lambda a: a.update(H=a["H"][:, :, :4]), r"H: expected shape \(3, 3, 5\)"),
     (lambda a: a.update(terms=tuple(x[:, :5] for x in a["terms"])), r"c: expected shape \(4, 6\)"),
     (lambda a: a.update(p_meas=a["p_meas"][:3]), r"p_meas: expected shape \(4, 3\)"),
     (lambda a: a.update(weights=np.ones((4, 2))), r"weights: expected shape \(4, 3\)"),
     (lambda a: a.update(R_meas=np.ones((4, 3, 2))), r"R_meas: expected shape \(4, 3, 3\)")],
)  # fmt: skip
@pytest.mark.parametrize("kernel", kinematics.KERNELS)
def test_shapes_the_kernels_would_index_past_are_refused(change, message, kernel):
    rng = np.random.default_rng(1)
    prism, U, B, H = _arm(rng, 6, 5, np.zeros(6, bool))
    _, terms = _terms(rng, 4, prism)
    args = dict(U=U, B=B, H=H, terms=terms, p_meas=np.zeros((4, 3)), R_meas=np.tile(np.eye(3), (4, 1, 1)), weights=None)
    change(args)
    with pytest.raises(ValueError, match=message):
        kinematics.residual_sums_unchecked(**args, kernel=kernel)


def test_jacobian_refuses_arrays_of_another_arm():
    from zrp_ga.model import error_model

    with pytest.raises(ValueError, match=r"jacobian_arrays: expected u0 \(6, 3\), b0 \(7, 3\), prism \(6,\)"):
        error_model.jacobian_arrays(np.zeros((5, 3)), np.zeros((7, 3)), np.zeros(6, bool), np.zeros((2, 6)))


@pytest.fixture
def fresh_choice(monkeypatch):
    """The path chooser's state of a process that has run no kernel yet."""
    monkeypatch.delenv("ZRP_GA_KERNELS", raising=False)
    monkeypatch.setattr(compiled, "_SPENT_S", {})
    monkeypatch.setattr(compiled, "_COMPILED", set())
    monkeypatch.setattr(compiled, "_WARM", {"cache": False})


def test_numpy_until_its_time_passes_the_budget_then_compiled(fresh_choice, monkeypatch):
    monkeypatch.setattr(compiled, "NUMPY_BUDGET_S", 0.05)
    clock, ran = [0.0], []
    monkeypatch.setattr(compiled, "_clock", lambda: clock[0])

    def numpy_path():  # 0.02 s each
        ran.append("numpy")
        clock[0] += 0.02

    for _ in range(5):
        compiled.call("k", 10, lambda: ran.append("compiled"), numpy_path)
    assert ran == ["numpy", "numpy", "numpy", "compiled", "compiled"]  # 0.06 s spent after three calls
    ran.clear()
    compiled.call("other", 10, lambda: ran.append("compiled"), numpy_path)  # each family on its own
    compiled.call("other", 1e9, lambda: ran.append("compiled"), numpy_path)  # a call too big for numpy
    assert ran == ["numpy", "compiled"]


def test_a_warm_cache_shortens_the_budget_and_the_environment_fixes_the_path(fresh_choice, monkeypatch):
    monkeypatch.setattr(compiled, "_WARM", {"cache": True})
    work = (compiled.NUMPY_BUDGET_WARM_S + compiled.NUMPY_BUDGET_S) / 2 / compiled.NUMPY_S_PER_WORK
    assert compiled.use_compiled("a", work)  # more than the warm budget
    monkeypatch.setattr(compiled, "_WARM", {"cache": False})
    assert not compiled.use_compiled("b", work)
    monkeypatch.setenv("ZRP_GA_KERNELS", "compiled")
    assert compiled.use_compiled("c", 0)
    monkeypatch.setenv("ZRP_GA_KERNELS", "numpy")
    assert not compiled.use_compiled("a", 1e12)
    monkeypatch.setenv("ZRP_GA_KERNELS", "fast")
    with pytest.raises(ValueError, match="ZRP_GA_KERNELS: must be one of auto, numpy, compiled, got 'fast'"):
        compiled.use_compiled("a", 0)


def _python(code: str, env: dict, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=timeout, cwd=ROOT)


def _env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "ZRP_GA_"))}
    return {**env, **extra}


DEFAULT_RUN = """
import sys, runpy
sys.argv = ["zrp-ga", "hydra.run.dir={out}", "progress=false"]
try:
    runpy.run_module("zrp_ga.cli", run_name="__main__")
finally:
    print("imported:", sorted(m for m in ("numba", "llvmlite", "zrp_ga.model._kernels") if m in sys.modules))
"""


def test_the_default_run_compiles_nothing_and_imports_no_numba(tmp_path):
    cache = tmp_path / "cache"
    done = _python(DEFAULT_RUN.format(out=tmp_path / "run"), _env(ZRP_GA_CACHE_DIR=str(cache)))
    assert done.returncode == 0, done.stderr
    assert "imported: []" in done.stdout
    assert "compiling" not in done.stderr
    assert not list(cache.rglob("*.nbi"))
    assert (tmp_path / "run" / "summary.json").is_file()


BOUNDS_CHECKED = ["tests/test_kernels.py", "tests/test_operators_shapes.py"]


@pytest.mark.slow  # 10 s: the kernels compiled again with bounds checking
def test_the_shape_tests_pass_with_bounds_checking_on():
    """The ``boundscheck`` tests (this module's and test_operators_shapes.py's: every genome size
    from 1 to 40 and subset size from 1 through every operator and the GA, every kernel at every
    arm and population size) again in a process with numba's bounds checking on and the compiled
    kernels forced: an index out of bounds raises there. Its compiled code is cached in a folder
    of its own (the cache does not tell bounds-checked code from the other)."""
    cache = Path(os.environ.get("ZRP_GA_CACHE_DIR") or compiled.cache_dir().parent) / "boundscheck"
    env = _env(NUMBA_BOUNDSCHECK="1", ZRP_GA_KERNELS="compiled", ZRP_GA_CACHE_DIR=str(cache))
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "boundscheck", "-x",
                           "-k", "not bounds_checking and not default_run", *BOUNDS_CHECKED],
                          env=env, capture_output=True, text=True, timeout=1800, cwd=ROOT)  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert " passed" in done.stdout and "failed" not in done.stdout


def test_bounds_checking_is_really_on_in_that_process():
    """The setting the test above relies on: with NUMBA_BOUNDSCHECK=1 a compiled out-of-bounds
    write raises IndexError (without it, it would write past the array)."""
    code = ("import numpy as np\nfrom numba import njit\n"
            "@njit\ndef poke(a, i):\n    a[i] = 1.0\n"
            "try:\n    poke(np.zeros(3), 3)\nexcept IndexError:\n    print('raised')\n")  # fmt: skip
    done = _python(code, _env(NUMBA_BOUNDSCHECK="1"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "raised"
