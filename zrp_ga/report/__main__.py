"""``python -m zrp_ga.report``: the same as ``zrp-ga-report``."""

from zrp_ga.report.cli import main

main()
