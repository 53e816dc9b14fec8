"""Small file helpers every layer may use: YAML text with libyaml's emitter, JSON written
atomically with numpy values and NaN as null, CSV with floats written exactly. They know nothing
of robots or runs (:mod:`zrp_ga.io.records` writes a run's files with them).
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np


def yaml_text(data, **options) -> str:
    """``yaml.safe_dump(data, **options)`` with libyaml's emitter when PyYAML has it (the same
    text, several times faster: a sweep job writes a dozen YAML documents)."""
    import yaml

    return yaml.dump(data, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), **options)


def replace(tmp: str | Path, path: str | Path) -> None:
    """``os.replace(tmp, path)``: ``path`` is the old file or the new one at every moment,
    whole. An existing ``path`` is swapped with ``tmp`` (Linux's ``renameat2`` with
    ``RENAME_EXCHANGE``) and the old file, now at ``tmp``, removed: ext4 writes a file renamed
    over another out to the disk at once (its ``auto_da_alloc``), which costs milliseconds on a
    busy disk; a run rewrites its checkpoint a dozen times. Elsewhere, or when the swap is
    refused (no such call, another file system, no ``path`` yet), ``os.replace``."""
    if _exchange is not None and _exchange(os.fsencode(tmp), os.fsencode(path)):
        try:
            os.unlink(tmp)
        except OSError:  # left as a temporary file: the run directory's next run removes it
            pass
        return
    os.replace(tmp, path)


def _exchanger():
    """A function swapping two paths (True when done), or None: Linux's renameat2, through ctypes."""
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return None
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):  # a C library without it (glibc before 2.28, musl)
        return None
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    renameat2.restype = ctypes.c_int
    at_fdcwd, rename_exchange = -100, 2  # <fcntl.h>, <linux/fs.h>

    def exchange(a: bytes, b: bytes) -> bool:
        return renameat2(at_fdcwd, a, at_fdcwd, b, rename_exchange) == 0

    return exchange


_exchange = _exchanger()


def _plain(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    return str(o)


def _finite_or_none(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _finite_or_none(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite_or_none(v) for v in o]
    return o


def write_json(path: str | Path, data: dict) -> None:
    """``data`` as JSON (numpy values as numbers, NaN and inf as null), written atomically."""
    text = json.dumps(_finite_or_none(json.loads(json.dumps(data, default=_plain))), indent=2)
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text + "\n")
        replace(tmp, path)
    except OSError as exc:  # a full disk: no temporary file left, and the error names the file
        tmp.unlink(missing_ok=True)
        raise named(exc, path) from None


def named(exc: OSError, path: str | Path) -> OSError:
    """``exc`` naming ``path`` when it names no file (a write's error names none: a full disk
    said "No space left on device" without saying where)."""
    return exc if exc.filename else type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def write_csv(path: str | Path, rows: Iterable[dict], columns: list[str] | None = None) -> None:
    """Rows of a table as CSV (floats written exactly, as ``repr`` does)."""
    rows = list(rows)
    columns = columns or (list(rows[0]) if rows else [])
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for row in rows:
            w.writerow({k: repr(float(v)) if isinstance(v, (float, np.floating)) else v for k, v in row.items()})


def package_versions(packages: Iterable[str], missing: str = "not installed") -> dict[str, str]:
    """Python's version and those of the installed ``packages`` (``missing`` for the absent)."""
    import platform
    from importlib import metadata

    out = {"python": platform.python_version()}
    for pkg in packages:
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = missing
    return out
