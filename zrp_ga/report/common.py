"""What every module of the report shares: the command's defaults, its error, the Markdown
writer and the CSV writer. The lowest module of the package: it imports no other module of the report."""

from __future__ import annotations

from typing import TYPE_CHECKING

from zrp_ga.run import directory

if TYPE_CHECKING:
    from pathlib import Path

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


def _csv_field(text: str) -> str:
    """``text`` as the csv module writes a field (quoted when it holds a comma, a quote or a line
    break; its quotes doubled)."""
    return f'"{text.replace(chr(34), chr(34) * 2)}"' if any(c in text for c in ',"\r\n') else text


def write_csv(df: pd.DataFrame, path: Path) -> None:
    """``df.to_csv(path, index=False)``, byte for byte, in a fraction of its time for the columns
    the report's tables hold (floats, integers, booleans, strings): a float is written as Python's
    ``repr`` (the shortest text that reads back the same: what numpy's ``str`` writes, and pandas
    with it), NaN and missing words as empty fields. Other tables are left to pandas."""
    import os

    import numpy as np
    import pandas as pd

    fields: list[list[str]] = []
    for name in df.columns:
        column = df[name]
        kind = column.dtype
        if kind == np.float64:
            # each value written once; told apart by its bits, which tell 0.0 from -0.0
            distinct, where = np.unique(np.ascontiguousarray(column.to_numpy()).view(np.int64), return_inverse=True)
            written = np.array([repr(v) if v == v else "" for v in distinct.view(np.float64).tolist()], dtype=object)
            texts = written[where].tolist()
        elif kind in (np.int64, np.int32, np.bool_):
            texts = list(map(str, column.to_numpy().tolist()))
        elif isinstance(kind, pd.StringDtype) or kind == np.dtype(object):
            words = column.to_numpy(dtype=object, na_value=None).tolist()
            try:
                known = dict.fromkeys(words)
            except TypeError:
                break
            if not all(v is None or isinstance(v, str) for v in known):
                break  # not a column of words: pandas knows how
            known = {v: "" if v is None else _csv_field(v) for v in known}
            texts = list(map(known.__getitem__, words))
        else:
            break
        fields.append(texts)
    if len(fields) < len(df.columns) or not len(df) or not fields or not all(isinstance(c, str) for c in df.columns):
        df.to_csv(path, index=False)
        return
    end = os.linesep  # pandas' line end
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(",".join(_csv_field(c) for c in df.columns) + end)
        f.write(end.join(map(",".join, zip(*fields))) + end)
