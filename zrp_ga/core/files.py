"""The one check every file the program reads passes first: it is a regular file.

A FIFO (named pipe) given as a file would block the first read until something writes into it,
forever in practice; a device or a socket is no file of ours either. A symlink loop is named as
one, not as a missing file (``Path.exists`` says False for both). Each refusal is one
ValueError line naming the path.

>>> regular_file("/", "a robot file")
Traceback (most recent call last):
...
ValueError: /: is a directory, expected a robot file
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import Any

KINDS = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFSOCK: "a socket", stat.S_IFCHR: "a character device",
         stat.S_IFBLK: "a block device"}  # fmt: skip


def as_path(path: Any, what: str, alternative: str = "") -> Path:
    """``path`` as a Path; a TypeError naming ``what`` (and the ``alternative`` to a path, if
    any) for anything that is not a path: a list, an array, a DataFrame."""
    if isinstance(path, (str, os.PathLike)):
        return Path(path)
    kind = f"{type(path).__module__}.{type(path).__qualname__}".removeprefix("builtins.")
    raise TypeError(f"{what}: expected a file path (str or pathlib.Path){alternative}, got a {kind}")


def regular_file(path: str | os.PathLike, what: str, missing: str = "no such file") -> Path:
    """``path`` if it is a regular file (a symlink to one counts); ValueError, one line naming the
    path, otherwise: ``missing`` when nothing is there, a symlink loop, a broken symlink, a
    directory (expected ``what``), a FIFO, socket or device, no permission."""
    path = as_path(path, what)
    try:
        mode = path.stat().st_mode  # follows symlinks
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise ValueError(f"{path}: a symlink loop (too many levels of symbolic links), expected {what}") from None
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            if path.is_symlink():
                raise ValueError(f"{path}: a broken symlink (to {os.readlink(path)}), expected {what}") from None
            raise ValueError(f"{path}: {missing}") from None
        raise ValueError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise ValueError(f"{path}: is a directory, expected {what}")
    if not stat.S_ISREG(mode):
        kind = KINDS.get(stat.S_IFMT(mode), "not a regular file")
        raise ValueError(f"{path}: {kind}, not a regular file; expected {what}")
    return path


def writable_dir(path: Any, what: str) -> Path:
    """``path`` if a directory can be created there and written into: no file in the way, and
    the first existing folder on the way to it writable; ValueError naming ``what`` otherwise
    (before any work, so that nothing computed is lost to an output that cannot be written)."""
    path = as_path(path, what)
    for folder in (path, *path.parents):
        if folder.exists():
            if not folder.is_dir():
                raise ValueError(f"{what}: cannot create {path}: {folder} is a file, not a directory")
            if not os.access(folder, os.W_OK | os.X_OK):
                raise ValueError(f"{what}: cannot write into {folder} (permission denied)")
            return path
    return path
