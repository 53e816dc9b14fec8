"""Compiled code on demand: ``jit`` (numba's ``njit`` with its on-disk cache outside the
installed package) and :func:`call`, which runs a kernel's numpy twin until compiling pays.

**When to compile.** Compiling this package's kernels costs seconds (about 3-15 s on a fresh
machine, each kernel once), loading them from the cache about half a second (numba's import
and its compiler target), while the runs a newcomer starts first (the paper's case study, a
one-pose problem) need a few milliseconds of kernel work. Every kernel with a numpy twin
(:mod:`zrp_ga.model._numpy_kernels`, the same operations in the same order: the same bits) is
therefore called through :func:`call`: the numpy twin runs, timed, until that kernel family
has spent :data:`NUMPY_BUDGET_S` seconds in numpy in this process (:data:`NUMPY_BUDGET_WARM_S`
when the cache already holds compiled code), or until one call alone would take longer (its
work times :data:`NUMPY_S_PER_WORK`); from then on the compiled kernel runs. This is the rent-or-buy rule: a
short run never imports numba, a long one pays at most about twice the compile time it would
have paid anyway. ``ZRP_GA_KERNELS=numpy`` or ``compiled`` fixes the choice (the tests check
both paths this way); results do not depend on it.

**The cache.** numba's ``cache=True`` writes the compiled code into ``__pycache__`` beside the
module when that folder is writable, i.e. into ``site-packages/zrp_ga``: files that ``pip
uninstall`` does not remove and that a later install then mistakes for a namespace package.
Here the cache of this package's functions goes to a user cache folder instead
(``$ZRP_GA_CACHE_DIR``, else ``$XDG_CACHE_HOME/zrp_ga``, else ``~/.cache/zrp_ga``), in a
subfolder per source tree, and is validated against the source file's time stamp as numba
always does. A ``NUMBA_CACHE_DIR`` the user set keeps precedence. When no cache folder can be
written, functions are compiled in each process and nothing is written anywhere. numba has no
public hook for this: the locator below subclasses the one numba uses for its own user-wide
cache and is put in front of the in-tree locator. Should numba's internals change, caching is
switched off rather than falling back to the package folder.

The first time this package's code is compiled in a process, one line on stderr says so: a
listener on numba's ``numba:compile`` event, which numba broadcasts only when it compiles, not
when it loads a function from the cache. Nothing here imports numba until a kernel is compiled
or loaded.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # zrp_ga/, above core/
T = TypeVar("T")

NUMPY_BUDGET_S = 3.0  # seconds of numpy work per kernel family before compiling it (nothing cached yet)
NUMPY_BUDGET_WARM_S = 0.5  # the same when the cache holds compiled code (loading it costs about 0.5-1 s)
NUMPY_S_PER_WORK = 4e-7  # the numpy twins' time per unit of work (pose evaluation x joint), about
MODES = ("auto", "numpy", "compiled")


def cache_dir() -> Path:
    """The folder holding the compiled-code cache of this package."""
    root = os.environ.get("ZRP_GA_CACHE_DIR")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "zrp_ga")
    return Path(root) / "numba"


# --- which path ------------------------------------------------------------------------------------
_clock = time.perf_counter  # the clock of the numpy time spent (the tests set their own)
_SPENT_S: dict[str, float] = {}  # per kernel family, the seconds spent in its numpy twin in this process
_COMPILED: set[str] = set()  # the kernel families that run compiled from now on
_WARM: dict[str, bool] = {}  # whether the cache holds compiled code ("cache"), looked up once


def mode() -> str:
    """``$ZRP_GA_KERNELS``: ``auto`` (the default), ``numpy`` or ``compiled``."""
    value = os.environ.get("ZRP_GA_KERNELS", "auto") or "auto"
    if value not in MODES:
        raise ValueError(f"ZRP_GA_KERNELS: must be one of {', '.join(MODES)}, got {value!r}")
    return value


def _budget_s() -> float:
    if "cache" not in _WARM:
        _WARM["cache"] = not cache_is_cold()
    return NUMPY_BUDGET_WARM_S if _WARM["cache"] else NUMPY_BUDGET_S


def use_compiled(family: str, work: float) -> bool:
    """Whether the next call of kernel ``family`` with ``work`` (pose evaluations x joints, or
    any measure proportional to its time) should run compiled (module docstring)."""
    chosen = mode()
    if chosen != "auto":
        return chosen == "compiled"
    if family in _COMPILED or "*" in _COMPILED:
        return True
    if max(_SPENT_S.get(family, 0.0), work * NUMPY_S_PER_WORK) >= _budget_s():
        _COMPILED.add(family)
        _CompileCount.count += 1  # a progress line's pace starts after this generation
        return True
    return False


def prefer_compiled() -> None:
    """From now on in this process (and the processes it forks), every kernel family runs
    compiled: for a process that starts workers for many runs (zrp_ga's sweep launcher loads
    the compiled code once, before forking them)."""
    _COMPILED.add("*")


def call(family: str, work: float, compiled: Callable[[], T], numpy: Callable[[], T]) -> T:
    """``compiled()`` or ``numpy()`` (the same result), as :func:`use_compiled` decides; the time
    spent in ``numpy()`` counts toward compiling ``family``."""
    if use_compiled(family, work):
        return compiled()
    t0 = _clock()
    try:
        return numpy()
    finally:
        _SPENT_S[family] = _SPENT_S.get(family, 0.0) + _clock() - t0


# --- numba, its cache and the compile notice ---------------------------------------------------------
def cache_is_cold() -> bool:
    """True when the cache holds no compiled function yet (no numba index file)."""
    root = Path(os.environ.get("NUMBA_CACHE_DIR") or cache_dir())
    return not any(root.rglob("*.nbi"))


def compile_notice(cold: bool, cache: bool) -> str:
    """The line said before this package's code is compiled, for a cold or partly warm cache,
    or none usable."""
    if not cache:
        return "compiling the kernels (no writable cache folder: in every process, a few seconds each)..."
    if cold:
        return "compiling the kernels (once per machine, a few seconds each)..."
    return "compiling the kernels changed since they were cached..."


class _CompileCount:
    count = 0  # compilations of this package's functions, and kernel families switched to compiled


def compilations() -> int:
    """How many functions numba has compiled in this process so far (loads from the cache not
    counted), plus the kernel families that switched to compiled code: a progress line's time
    left leaves out the time before the last of them."""
    return _CompileCount.count


def _install_locator(caching) -> bool:
    """Put this package's cache locator in numba's list; False if that cannot be done."""
    try:
        locators = caching.CacheImpl._locator_classes
        base: Any = caching.UserWideCacheLocator  # a class found at run time (numba.core.caching)
    except AttributeError:
        return False

    class PackageCacheLocator(base):
        """numba's user-wide locator with this package's own cache folder, for its files only."""

        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = str(cache_dir() / self.get_suitable_cache_subpath(py_file))

        @classmethod
        def from_function(cls, py_func, py_file):
            if not Path(py_file).resolve().is_relative_to(PACKAGE_DIR):
                return None
            return super().from_function(py_func, py_file)  # None when the folder is not writable

    if not any(c.__name__ == "PackageCacheLocator" for c in locators):
        user_given = [c for c in locators if c.__name__ == "UserProvidedCacheLocator"]
        locators.insert(len(user_given), PackageCacheLocator)
    return True


def _cache_usable(caching) -> bool:
    if not _install_locator(caching):
        return False
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True
    try:
        path = cache_dir()
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError:
        return False
    return True


def _listener(event, cache: bool):
    """A listener on numba's compile event: says :func:`compile_notice` on stderr once per
    process when numba starts compiling a function of this package; counts the compilations."""

    class CompileNotice(event.Listener):
        said = False

        def on_start(self, ev) -> None:
            if CompileNotice.said:
                return
            fn = getattr(ev.data.get("dispatcher"), "py_func", None)
            code = getattr(fn, "__code__", None)
            if code is None or not Path(code.co_filename).resolve().is_relative_to(PACKAGE_DIR):
                return
            CompileNotice.said = True
            try:
                sys.stderr.write(compile_notice(cache_is_cold(), cache) + "\n")
                sys.stderr.flush()
            except (OSError, ValueError):
                pass

        def on_end(self, ev) -> None:
            _CompileCount.count += 1

    return CompileNotice()


class _Numba:
    """numba's ``njit`` and whether the cache is usable, set up on first use."""

    njit = None
    cache = False


def _numba():
    """numba, imported and set up (cache locator, compile listener) once per process."""
    if _Numba.njit is None:
        from numba import njit
        from numba.core import caching, event

        _Numba.cache = _cache_usable(caching)
        event.register("numba:compile", _listener(event, _Numba.cache))
        _Numba.njit = njit
    return _Numba


def jit(fn=None, **options):
    """``numba.njit`` with the cache described in the module docstring; ``options`` go to
    ``njit`` (e.g. ``fastmath``, ``inline``, ``nogil``), ``cache`` excepted. Imports numba:
    only modules of compiled kernels, themselves imported when first needed, use it.

    Use as ``@jit`` or ``@jit(fastmath={"contract"})``."""
    if "cache" in options:
        raise TypeError("jit: the cache is this module's business; do not pass cache=")
    nb = _numba()
    if fn is None:
        return lambda f: nb.njit(cache=nb.cache, **options)(f)
    return nb.njit(cache=nb.cache, **options)(fn)
