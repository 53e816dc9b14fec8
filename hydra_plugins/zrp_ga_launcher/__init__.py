"""zrp_ga's Hydra launcher (``hydra/launcher=zrp_ga``): long-lived worker processes that import
and compile once, job configs composed from a few of Hydra's own; see ``launcher.py``.

Hydra finds it by scanning the ``hydra_plugins`` namespace package, which has no
``__init__.py`` of its own."""
