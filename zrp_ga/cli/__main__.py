"""``python -m zrp_ga.cli``: the same as ``zrp-ga``."""

from zrp_ga.cli.main import cli

cli()
