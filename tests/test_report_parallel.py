"""The report's figures are drawn by forked processes while this one writes the tables
(``zrp_ga.report.drawing._each``): the report is the one drawn one figure after the other in this
process, every file and the page alike (the page's time stamp aside)."""

import os
import re

import pytest
from report_fakes import crossover_study

from zrp_ga import report


def _files(out):
    files = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    page = files.pop(next(p for p in files if p.name == "index.html")).decode()
    return files, re.sub(r"Made \d{4}-\d\d-\d\d \d\d:\d\d UTC", "Made DATE", page)


@pytest.mark.slow  # two reports with their figures: 10 - 25 s on a busy machine (every report test draws forked as well)
def test_figures_drawn_by_other_processes_give_the_report_drawn_here(tmp_path, monkeypatch):
    crossover_study(tmp_path / "runs", instances=3, seeds=3)
    forked = []
    import multiprocessing.pool

    pool_init = multiprocessing.pool.Pool.__init__

    def counted(self, *args, **kwargs):
        forked.append(args)
        pool_init(self, *args, **kwargs)

    monkeypatch.setattr(multiprocessing.pool.Pool, "__init__", counted)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    report.write_report([tmp_path / "runs"], tmp_path / "forked", formats=("svg", "png"))
    assert forked  # the figures were drawn by other processes
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    report.write_report([tmp_path / "runs"], tmp_path / "here", formats=("svg", "png"))
    assert len(forked) == 1  # one core: drawn here
    (files, page), (files_here, page_here) = _files(tmp_path / "forked"), _files(tmp_path / "here")
    assert sorted(files) == sorted(files_here) and any(p.suffix == ".svg" for p in files) and any(p.suffix == ".csv" for p in files)
    for name in files:
        assert files[name] == files_here[name], name
    assert page.count("<svg") >= 5 and page == page_here


HANDLER_SET = r"""
import signal, sys
from zrp_ga.report import drawing

signal.signal(signal.SIGTERM, lambda *_: print("SIGTERM handled", file=sys.stderr))  # as zrp-ga's own: no exit
print(drawing._each(lambda spec: f"figure {spec['k']}", [{"k": k} for k in range(4)]))
"""


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="one core: the figures are drawn in the process itself")
def test_a_process_that_handles_sigterm_gets_its_figures_and_ends():
    """A process with a SIGTERM handler of its own (zrp-ga turns SIGTERM into Ctrl-C; the test
    suite's process had one from a test before) hands it to the forked children: ended by the
    pool's SIGTERM, a child that had not yet taken the default back outlived it, and the report
    waited for it forever (the whole test suite hung there once)."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", HANDLER_SET], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == str([f"figure {k}" for k in range(4)])
    assert "SIGTERM handled" not in proc.stderr  # no signal reached a child with the inherited handler
