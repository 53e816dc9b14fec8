"""``jit``: numba's ``njit`` with its on-disk cache outside the installed package.

numba's ``cache=True`` writes the compiled code into ``__pycache__`` beside the module when that
folder is writable, i.e. into ``site-packages/zrp_ga``: files that ``pip uninstall`` does not
remove and that a later install then mistakes for a namespace package. Here the cache of this
package's functions goes to a user cache folder instead (``$ZRP_GA_CACHE_DIR``, else
``$XDG_CACHE_HOME/zrp_ga``, else ``~/.cache/zrp_ga``), in a subfolder per source tree, and is
validated against the source file's time stamp as numba always does. A ``NUMBA_CACHE_DIR``
the user set keeps precedence. When no cache folder can be written, functions are compiled in
each process and nothing is written anywhere.

The first time this package's code is compiled in a process, one line on stderr says so (on a
fresh machine that takes about half a minute of otherwise silent work): a listener on numba's
``numba:compile`` event, which numba broadcasts only when it compiles, not when it loads a
function from the cache.

numba has no public hook for this: the locator below subclasses the one numba uses for its own
user-wide cache and is put in front of the in-tree locator. Should numba's internals change,
caching is switched off rather than falling back to the package folder.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from numba import njit
from numba.core import event

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # zrp_ga/, above core/


def cache_dir() -> Path:
    """The folder holding the compiled-code cache of this package."""
    root = os.environ.get("ZRP_GA_CACHE_DIR")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "zrp_ga")
    return Path(root) / "numba"


def _install_locator() -> bool:
    """Put this package's cache locator in numba's list; False if that cannot be done."""
    try:
        from numba.core import caching

        locators = caching.CacheImpl._locator_classes
        base = caching.UserWideCacheLocator
    except (ImportError, AttributeError):
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


def _cache_usable() -> bool:
    if not _install_locator():
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


CACHE = _cache_usable()


def cache_is_cold() -> bool:
    """True when the cache holds no compiled function yet (no numba index file)."""
    root = Path(os.environ.get("NUMBA_CACHE_DIR") or cache_dir())
    return not any(root.rglob("*.nbi"))


def compile_notice(cold: bool, cache: bool) -> str:
    """The line said before this package's code is compiled, for a cold or partly warm cache,
    or none usable."""
    if not cache:
        return "compiling the kernels (no writable cache folder: in every process, about 30 s)..."
    if cold:
        return "compiling the kernels (once per machine, about 30 s)..."
    return "compiling the kernels changed since they were cached..."


def compilations() -> int:
    """How many functions numba has compiled in this process so far (loads from the cache not
    counted): a progress line's time left leaves out the time before the last of them."""
    return _CompileNotice.count


class _CompileNotice(event.Listener):
    """Says :func:`compile_notice` on stderr once per process, when numba starts compiling a
    function of this package; counts the compilations (:func:`compilations`)."""

    said, count = False, 0

    def on_start(self, ev) -> None:
        if _CompileNotice.said:
            return
        fn = getattr(ev.data.get("dispatcher"), "py_func", None)
        code = getattr(fn, "__code__", None)
        if code is None or not Path(code.co_filename).resolve().is_relative_to(PACKAGE_DIR):
            return
        _CompileNotice.said = True
        try:
            sys.stderr.write(compile_notice(cache_is_cold(), CACHE) + "\n")
            sys.stderr.flush()
        except (OSError, ValueError):
            pass

    def on_end(self, ev) -> None:
        _CompileNotice.count += 1


event.register("numba:compile", _CompileNotice())


def jit(fn=None, **options):
    """``numba.njit`` with the cache described in the module docstring; ``options`` go to
    ``njit`` (e.g. ``fastmath``, ``inline``, ``nogil``), ``cache`` excepted.

    Use as ``@jit`` or ``@jit(fastmath={"contract"})``."""
    if "cache" in options:
        raise TypeError("jit: the cache is this module's business; do not pass cache=")
    if fn is None:
        return lambda f: njit(cache=CACHE, **options)(f)
    return njit(cache=CACHE, **options)(fn)
