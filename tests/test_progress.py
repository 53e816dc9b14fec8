"""What a user watches: the sweep's progress line, a run's time left, the compile notice."""

import io
import os
import subprocess
import sys

import pytest

from hydra_plugins.zrp_ga_launcher import _progress
from zrp_ga.run import callbacks


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_sweep_progress_text_says_done_failed_running_and_time_left():
    # 3 of 8 jobs ended in 30 s: 0.1 job/s, 5 to go -> 50 s left
    assert _progress.text(3, 8, 1, 2, 30.0) == "3/8 jobs done, 1 failed, 2 running, 00:50 left, 00:30 so far"
    assert _progress.text(0, 8, 0, 2, 5.0).startswith("0/8 jobs done, 0 failed, 2 running, ? left")  # no pace yet
    assert "1:00:00 left" in _progress.text(1, 3, 0, 1, 1800.0)  # 2 jobs of 30 min


def test_sweep_progress_on_a_terminal_is_one_line_rewritten_in_place():
    out = Tty()
    p = _progress.SweepProgress(8, stream=out)
    p.show(0, 0, 2)
    p.show(3, 1, 2)
    p.close(8, 1)
    text = out.getvalue()
    assert "3/8 jobs done, 1 failed, 2 running" in text and "8/8 jobs done, 1 failed, 0 running" in text
    assert text.count("\n") == 1 and text.rstrip("\r").endswith("\n")  # one line, ended at the close
    assert text.split("\r").count("") >= 2  # each draw starts at the line's start


def test_sweep_progress_off_a_terminal_is_a_plain_line_now_and_then_or_nothing():
    out = io.StringIO()
    p = _progress.SweepProgress(4, stream=out, every_s=0.0)
    p.show(1, 0, 2)
    p.close(4, 0)
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and lines[0].startswith("1/4 jobs done, 0 failed, 2 running") and "\r" not in out.getvalue()
    quiet = io.StringIO()
    p = _progress.SweepProgress(4, stream=quiet, every_s=3600.0)
    p.show(1, 0, 2)
    p.close(4, 0)
    assert quiet.getvalue() == ""  # a short sweep off a terminal: not a line
    off = Tty()
    p = _progress.SweepProgress(4, enabled=False, stream=off)
    p.show(1, 0, 2)
    p.close(4, 0)
    assert off.getvalue() == ""  # progress=false


def test_time_left_leaves_out_the_first_generation():
    # generation 1 ends at 10 s with 10 % done (most of it compiling), 30 % at 14 s:
    # 20 % in 4 s, 70 % to go -> 14 s (from the start: 14 s * 0.7 / 0.3 = 32.7 s)
    assert callbacks.time_left((10.0, 0.1), (14.0, 0.3)) == pytest.approx(14.0)
    assert callbacks.time_left((10.0, 0.1), (10.0, 0.1)) is None  # no pace yet
    assert callbacks.time_left((10.0, None), (14.0, None)) is None  # budget unknown
    assert callbacks.time_left((10.0, 0.1), (20.0, 1.0)) is None  # done


def test_progress_line_time_left_comes_from_the_generations_after_the_first():
    class Partway:
        done = 0.1

        def fraction_done(self):
            return self.done

        def has_next(self):
            return True

    out, algorithm = io.StringIO(), Partway()
    progress = callbacks.Progress(stream=out, every_s=0)
    progress.on_generation(algorithm, {"gen": 1, "nevals": 40, "best": 1.0, "wall_s": 10.0})
    algorithm.done = 0.3
    progress.on_generation(algorithm, {"gen": 3, "nevals": 120, "best": 0.5, "wall_s": 14.0})
    first, second = out.getvalue().splitlines()
    assert "time left" not in first and second.endswith("time left   14.0 s")


def test_progress_line_time_left_starts_after_the_last_generation_that_compiled(monkeypatch):
    from zrp_ga.core import compiled as jit_module

    class Partway:
        done = 0.1

        def fraction_done(self):
            return self.done

        def has_next(self):
            return True

    compiled = [5]
    monkeypatch.setattr(jit_module, "compilations", lambda: compiled[0])
    out, algorithm = io.StringIO(), Partway()
    progress = callbacks.Progress(stream=out, every_s=0)
    progress.on_generation(algorithm, {"gen": 0, "nevals": 40, "best": 1.0, "wall_s": 10.0})
    algorithm.done, compiled[0] = 0.2, 9  # generation 1 compiled the variation operators
    progress.on_generation(algorithm, {"gen": 1, "nevals": 80, "best": 0.7, "wall_s": 30.0})
    algorithm.done = 0.4
    progress.on_generation(algorithm, {"gen": 3, "nevals": 160, "best": 0.5, "wall_s": 34.0})
    lines = out.getvalue().splitlines()
    assert "time left" not in lines[1]  # no pace yet: generation 1 compiled
    assert lines[2].endswith("time left   12.0 s")  # 20 % in 4 s, 60 % to go


CALL_ONE_KERNEL = "from zrp_ga.model import _kernels; _kernels._rotate(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0)"


def _python(code: str, cache) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["ZRP_GA_CACHE_DIR"] = str(cache)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)


def test_first_compilation_says_so_and_a_warm_cache_says_nothing(tmp_path):
    cold = _python(CALL_ONE_KERNEL, tmp_path)
    assert cold.returncode == 0, cold.stderr
    assert cold.stderr.count("compiling the kernels (once per machine, a few seconds each)...") == 1, cold.stderr
    assert list(tmp_path.rglob("*.nbi"))  # the compiled kernel went to this cache
    warm = _python(CALL_ONE_KERNEL, tmp_path)
    assert warm.returncode == 0, warm.stderr
    assert "compiling" not in warm.stderr
    plain = _python("import numba; numba.njit(lambda x: x + 1)(1)", tmp_path / "other")
    assert "compiling" not in plain.stderr  # numba code that is not this package's


def test_the_launcher_counts_jobs_ended_failed_and_running():
    from types import SimpleNamespace

    from hydra.core.utils import JobReturn, JobStatus

    from hydra_plugins.zrp_ga_launcher import _workers

    shown = []
    d = _workers._Dispatcher.__new__(_workers._Dispatcher)
    d.returns, d.failed = {}, 0
    for idx, status in enumerate([JobStatus.COMPLETED, JobStatus.FAILED, JobStatus.COMPLETED]):
        d.returned(idx, JobReturn(status=status))
    busy, idle = SimpleNamespace(batches=[[3], [5]]), SimpleNamespace(batches=[])
    d.pool = SimpleNamespace(workers=[busy, idle, SimpleNamespace(batches=[[4]])])
    d.progress = SimpleNamespace(show=lambda *a: shown.append(("show", *a)), close=lambda *a: shown.append(("close", *a)))
    d.show_progress()
    d.show_progress(close=True)
    assert shown == [("show", 3, 1, 2), ("close", 3, 1, 0)]  # a worker runs one job at a time
