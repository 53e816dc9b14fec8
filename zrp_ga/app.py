"""``python -m zrp_ga.app``: the command line (:mod:`zrp_ga.cli`), and the names scripts used
before the run layer existed: :func:`prepare` and :func:`run` (:mod:`zrp_ga.run`),
:func:`one_line` and :func:`cli`."""

from __future__ import annotations

from zrp_ga.cli import cli, main, one_line
from zrp_ga.run.build import Prepared, prepare
from zrp_ga.run.execute import execute, run, warm_up

__all__ = ["Prepared", "cli", "execute", "main", "one_line", "prepare", "run", "warm_up"]

if __name__ == "__main__":
    cli()
