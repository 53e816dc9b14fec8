"""The bottom layer: small helpers every other layer may use, importing nothing of zrp_ga's
above them: :mod:`~zrp_ga.core.errors` (the warning class, one-line errors),
:mod:`~zrp_ga.core.checks` (settings that cannot run), :mod:`~zrp_ga.core.files` (every file
read is a regular file), :mod:`~zrp_ga.core.fileio` (YAML, JSON and CSV writers),
:mod:`~zrp_ga.core.compiled` (numba's ``jit`` with its cache outside the package)."""
