"""The sweep's progress line: jobs done of all, failed, running and the time left.

On a terminal it is one line on stderr, drawn by tqdm and rewritten in place; when stderr is not
a terminal (a log file, CI) it is a plain line every ``PLAIN_EVERY_S`` seconds, and with the app's
``progress=false`` nothing. The time left is the jobs still to do at the pace of the sweep so
far (jobs done over wall time since the launch).

The workers' own lines (one per finished job) go to the same terminal from other processes: the
bar is drawn with the cursor put back at its start, so that a worker's line overwrites it rather
than being appended to it, and the bar comes back on the next line at the next update. The
driver's own log lines on the terminal erase the bar's line first.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from typing import Any

from tqdm import tqdm

BAR = "{percentage:3.0f}%|{bar:20}| {n_fmt}/{total_fmt} jobs done{postfix}, {remaining} left"
PLAIN = "{n_fmt}/{total_fmt} jobs done{postfix}, {remaining} left, {elapsed} so far"
PLAIN_EVERY_S = 60.0


def text(done: int, total: int, failed: int, running: int, elapsed_s: float, bar_format: str = PLAIN) -> str:
    """The progress line of a sweep with ``done`` of ``total`` jobs ended (``failed`` of them
    failed), ``running`` jobs running, ``elapsed_s`` seconds after its launch."""
    return tqdm.format_meter(done, total, elapsed_s, ncols=80, bar_format=bar_format, postfix=_postfix(failed, running))


def _postfix(failed: int, running: int) -> str:
    return f"{failed} failed, {running} running"


class _CursorBack:
    """A stream that puts the cursor back at the start of the line after each draw."""

    def __init__(self, stream: Any):
        self.stream = stream

    def write(self, s: str) -> None:
        self.stream.write(s)

    def flush(self) -> None:
        self.stream.write("\r")
        self.stream.flush()


class _Erasing:
    """A stream that erases the line the cursor is on before each write."""

    def __init__(self, stream: Any):
        self.stream = stream

    def write(self, s: str) -> None:
        self.stream.write("\r\x1b[2K" + s)

    def flush(self) -> None:
        self.stream.flush()


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class SweepProgress:
    """See the module docstring: ``show`` the state now and then, ``close`` at the end."""

    def __init__(self, total: int, enabled: bool = True, stream: Any = None, every_s: float = PLAIN_EVERY_S):
        self.stream = stream if stream is not None else sys.stderr
        tty = _isatty(self.stream)
        self.total, self.every_s = total, every_s
        self.plain = enabled and not tty
        self.t0 = self.shown_at = time.monotonic()
        self.bar = None
        if enabled and tty:
            self.bar = tqdm(total=total, file=_CursorBack(self.stream), bar_format=BAR, smoothing=0,
                            mininterval=0.2, dynamic_ncols=True, leave=True, postfix=_postfix(0, 0))  # fmt: skip

    def show(self, done: int, failed: int, running: int) -> None:
        if self.bar is not None:
            self.bar.n = done
            self.bar.set_postfix_str(_postfix(failed, running), refresh=False)
            self.bar.refresh()
        elif self.plain and time.monotonic() - self.shown_at >= self.every_s:
            self._plain(done, failed, running)

    def _plain(self, done: int, failed: int, running: int) -> None:
        self.shown_at = time.monotonic()
        try:
            self.stream.write(text(done, self.total, failed, running, self.shown_at - self.t0) + "\n")
            self.stream.flush()
        except (OSError, ValueError):
            pass

    @contextlib.contextmanager
    def logging(self):
        """Within: the driver's log lines on the terminal erase the bar's line before they are written."""
        if self.bar is None:
            yield
            return
        handlers = [h for name in (None, "hydra") for h in logging.getLogger(name).handlers
                    if isinstance(h, logging.StreamHandler) and _isatty(h.stream)]  # fmt: skip
        old = [h.setStream(_Erasing(h.stream)) for h in handlers]
        try:
            yield
        finally:
            for h, stream in zip(handlers, old):
                h.setStream(stream)

    def close(self, done: int, failed: int, running: int = 0) -> None:
        if self.bar is not None:
            self.show(done, failed, running)
            self.bar.close()  # leaves the line, ended
            self.bar = None
        elif self.plain and self.shown_at > self.t0:  # a last line when there were lines before
            self._plain(done, failed, running)
