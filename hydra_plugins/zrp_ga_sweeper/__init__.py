"""zrp_ga's Hydra sweeper (``hydra/sweeper=zrp_ga``): Hydra's basic sweeper's grid (the same jobs
in the same order, numbered alike) with each job's config checked only where it can differ in what
it checks: see ``sweeper.py``."""
