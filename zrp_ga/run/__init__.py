"""The run layer: a run built from its typed config, executed and recorded, without Hydra.

- :mod:`zrp_ga.run.directory`: the run and sweep directories' files (the one module that names
  them), ``status.json``, the sweep manifest;
- :mod:`zrp_ga.run.shared`: what the runs of one process share (problem instances, their
  identifiability and floor);
- :mod:`zrp_ga.run.build`: :func:`~zrp_ga.run.build.prepare`, the checks every entry point
  passes, and the objects a config builds;
- :mod:`zrp_ga.run.execute`: :func:`~zrp_ga.run.execute.run` and
  :func:`~zrp_ga.run.execute.sweep_job`, which optimise and write the run's files (with
  :mod:`zrp_ga.run.callbacks`, :mod:`zrp_ga.run.checkpoint` and :mod:`zrp_ga.run.summary`).

The command line (:mod:`zrp_ga.cli.main`), :func:`zrp_ga.calibrate`, the experiments and zrp_ga's
launcher all run through it. This package imports nothing itself, so that its lowest module
(``directory``) can be imported without the rest.
"""
