"""The package's warning class and the one helper every user-facing warning goes through.

On the command line a warning is a log line (as Hydra's logging shows it); inside
:func:`python_warnings` (what :func:`zrp_ga.calibrate` runs in) it is a Python warning of class
:class:`ZrpGaWarning`, which a notebook catches or filters with the :mod:`warnings` module
(``warnings.simplefilter("ignore", zrp_ga.ZrpGaWarning)``, ``pytest.warns``), each message once.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import warnings
from collections.abc import Iterator, Sequence


class ZrpGaWarning(UserWarning):
    """A warning of zrp_ga: the data, the problem or the result deserve a look."""


_seen: contextvars.ContextVar[set[str] | None] = contextvars.ContextVar("zrp_ga_python_warnings", default=None)


def warn(message: str, log: logging.Logger | None = None, category: type[ZrpGaWarning] = ZrpGaWarning,
         details: Sequence[str] = ()) -> None:  # fmt: skip
    """``message`` (one line: what, how bad, what to do) as a Python warning inside
    :func:`python_warnings` (once per message), else as a warning of ``log`` (the caller's
    logger); its ``details`` (lines) go to the log files only (:func:`to_log_files`), never to
    the console."""
    message = " ".join(message.split("\n"))  # one line, whatever the caller built
    seen = _seen.get()
    if seen is None:
        logger = log or logging.getLogger("zrp_ga")
        logger.warning("%s", message)
        if details:
            to_log_files(logger, logging.WARNING, [f"  {d}" for d in details])
    elif message not in seen:
        seen.add(message)
        warnings.warn(message, category, stacklevel=3)


def to_log_files(log: logging.Logger, level: int, lines: Sequence[str]) -> None:
    """``lines`` as records of ``log`` handed to the log files only: the file handlers of
    ``log`` and of its ancestors (Hydra's job log, ``hydra.job_logging``), not the console's
    stream handlers."""
    handlers: list[logging.FileHandler] = []
    logger: logging.Logger | None = log
    while logger is not None:
        handlers += [h for h in logger.handlers if isinstance(h, logging.FileHandler)]
        logger = logger.parent if logger.propagate else None
    if not handlers or not log.isEnabledFor(level):
        return
    for line in lines:
        record = log.makeRecord(log.name, level, "(details)", 0, "%s", (line,), None)
        for h in handlers:
            if record.levelno >= h.level:
                h.handle(record)


@contextlib.contextmanager
def python_warnings() -> Iterator[None]:
    """Within: warnings are Python warnings (:func:`warn`) instead of log lines."""
    token = _seen.set(set())
    try:
        yield
    finally:
        _seen.reset(token)


def one_line(exc: BaseException) -> str:
    """An error on one line: what is wrong and the key (or the options) it concerns."""
    for e in (exc.__cause__, exc):
        lines = [line.strip() for line in str(e or "").splitlines() if line.strip()]
        key = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("full_key:")), None)
        if key:
            return f"{lines[0]} (key: {key})"
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()] or [type(exc).__name__]
    heads = [k for k, line in enumerate(lines) if line.startswith("Available options in")]
    if heads:
        options = [line for line in lines[heads[0] + 1 :] if not line.startswith(("Config search path", "provider="))]
        return f"{lines[0]}; {lines[heads[0]].rstrip(':').lower()}: {', '.join(options)}"
    if isinstance(exc, OSError) and exc.filename:
        return f"{exc.filename}: {exc.strerror}"
    return lines[0]
