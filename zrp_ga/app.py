"""``python -m zrp_ga.app``: the command line (:mod:`zrp_ga.cli`), and the names scripts used
before the run layer existed: :func:`prepare` (:mod:`zrp_ga.run.build`), :func:`run`,
:func:`execute` and :func:`warm_up` (:mod:`zrp_ga.run.execute`), imported on first use so that
``--help`` starts fast; :func:`one_line` and :func:`cli`."""

from __future__ import annotations

from typing import Any

from zrp_ga.cli import cli, main, one_line

_RUN_LAYER = {"Prepared": "build", "prepare": "build", "run": "execute", "execute": "execute", "warm_up": "execute"}
__all__ = ["cli", "main", "one_line", *_RUN_LAYER]


def __getattr__(name: str) -> Any:
    if name in _RUN_LAYER:
        import importlib

        return getattr(importlib.import_module(f"zrp_ga.run.{_RUN_LAYER[name]}"), name)
    raise AttributeError(f"module 'zrp_ga.app' has no attribute {name!r}")


if __name__ == "__main__":
    cli()
