"""Files in and out: :mod:`~zrp_ga.io.measurements` (measurement CSV files, units found from the
data), :mod:`~zrp_ga.io.robot_files` (DH and modified DH tables, ZRP YAML),
:mod:`~zrp_ga.io.urdf` (URDF read and written), :mod:`~zrp_ga.io.presets` (the arms shipped with
zrp_ga) and :mod:`~zrp_ga.io.records` (a run's tables: summary, parameters, population)."""
