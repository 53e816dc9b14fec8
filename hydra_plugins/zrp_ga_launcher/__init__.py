"""zrp_ga's Hydra launcher (``hydra/launcher=zrp_ga``): long-lived worker processes that import
and compile once, job configs composed from a few of Hydra's own; see ``launcher.py``, and
``config.py`` for its settings (stored in Hydra's ConfigStore, as Hydra's launcher plugins keep
theirs). A job's config goes to the run layer typed (``zrp_ga.config.typed``).

Hydra finds it by scanning the ``hydra_plugins`` namespace package, which has no
``__init__.py`` of its own, and (hydra-core 1.4) by the ``hydra.plugins`` entry point in
pyproject.toml; ``zrp-ga`` registers it itself where neither finds it (an editable install under
hydra-core 1.3)."""
