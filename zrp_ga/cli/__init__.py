"""The command line, the only code besides zrp_ga's launcher (``hydra_plugins/zrp_ga_launcher``)
and the API that talks to Hydra (through :mod:`zrp_ga.config` where it composes configs): the three console scripts, ``zrp-ga``
(:mod:`zrp_ga.cli.main`, Hydra's app; ``python -m zrp_ga.cli``), ``zrp-ga-report``
(:mod:`zrp_ga.cli.report`) and ``zrp-ga-compensate`` (:mod:`zrp_ga.cli.compensate`), and Hydra's
callbacks of ``zrp-ga`` (:mod:`zrp_ga.cli.callbacks`)."""
