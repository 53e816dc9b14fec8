"""The sweep manifest's names where readers found them before :mod:`zrp_ga.run.directory` owned
them (Hydra's callbacks are in :mod:`zrp_ga.cli.callbacks`)."""

from zrp_ga.run.directory import COLUMNS, MANIFEST, TABLE, job_states, read_manifest, repair, write_table

__all__ = ["COLUMNS", "MANIFEST", "TABLE", "job_states", "read_manifest", "repair", "write_table"]
