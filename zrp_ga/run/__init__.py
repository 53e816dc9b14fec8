"""The run layer: a run built from its typed config (:class:`zrp_ga.core.schema.Config`),
executed and recorded, without Hydra.

- :mod:`zrp_ga.run.directory`: the run and sweep directories' files (the one module that names
  them), ``status.json``, the sweep manifest, the run directory's lock;
- :mod:`zrp_ga.run.shared`: what the runs of one process share (problem instances, their
  identifiability and floor);
- :mod:`zrp_ga.run.build`: :func:`~zrp_ga.run.build.prepare`, the checks every entry point
  passes, and the objects a config builds;
- :mod:`zrp_ga.run.assembly`: what a run is made of besides those objects, the same alone or
  evolved with others: its seeding and callbacks, its status and manifest line, its summary,
  files and warnings;
- :mod:`zrp_ga.run.execute`: :func:`~zrp_ga.run.execute.run`, a run alone;
- :mod:`zrp_ga.run.sweep`: a sweep's jobs (:class:`~zrp_ga.run.sweep.SweepJob`), alone or in
  batches; :mod:`zrp_ga.run.together`: runs evolved in lockstep;
- beside them :mod:`~zrp_ga.run.callbacks`, :mod:`~zrp_ga.run.checkpoint`,
  :mod:`~zrp_ga.run.summary` and :mod:`~zrp_ga.run.budget`.

The command line (:mod:`zrp_ga.cli.main`), :func:`zrp_ga.calibrate`, the experiments and zrp_ga's
launcher all run through it, turning their Hydra configs typed with :mod:`zrp_ga.config`. This
package imports nothing itself, so that its lowest module (``directory``) can be imported
without the rest.
"""
