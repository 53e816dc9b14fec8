"""What every module of the report shares: the command's defaults, its error and the Markdown
writer. The lowest module of the package: it imports no other module of the report."""

from __future__ import annotations

from typing import TYPE_CHECKING

from zrp_ga.run import directory

if TYPE_CHECKING:
    import pandas as pd

LEVELS = (1.5, 1.1, 1.05, 1.01)  # target levels c (targets c x f_ref)
BUDGETS = (100, 1_000, 10_000)  # fixed budgets, evaluations
ROUND_OFF = directory.ROUND_OFF  # a floor below ROUND_OFF x nominal cost is round-off
ALPHA = 0.05  # the significance level of every test the report reads in words


class ReportError(ValueError):
    """What is wrong with the command's input, in one line (the command prints it and exits with 2)."""


def markdown(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    """A DataFrame as a Markdown table (floats with ``floatfmt``)."""
    cols = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        cells = [format(v, floatfmt) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
