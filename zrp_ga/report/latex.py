"""The report's headline tables as LaTeX booktabs tables (``--latex``), ready for
``\\input{...}`` in a paper (``\\usepackage{booktabs}``): the configurations, the reference, each
setting's effect and the best configuration of each instance against the others.

By hand: pandas' ``to_latex`` needs jinja2, which is not a dependency, for two dozen lines."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pandas as pd

from zrp_ga.report.conclusions import oriented

_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{", "}": r"\}",
            "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}  # fmt: skip


def escape(text: str) -> str:
    """Text with LaTeX's special characters escaped.

    >>> escape("a_b & 5%")
    'a\\\\_b \\\\& 5\\\\%'
    """
    return re.sub(r"[\\&%$#_{}~^]", lambda m: _SPECIAL[m.group()], str(text))


def cell(v) -> str:
    """A table cell: numbers to 4 significant digits (thousands grouped), inf as "never", NaN empty."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        if isinstance(v, float) and math.isnan(v):
            return ""
        if isinstance(v, float) and math.isinf(v):
            return "never"
        return f"{v:,.4g}".replace(",", "{,}") if abs(v) >= 1e4 else f"{v:.4g}"
    return escape(v)


def booktabs(df: pd.DataFrame, caption: str, label: str, names: dict[str, str] | None = None) -> str:
    """``df`` as a ``table`` with a booktabs ``tabular`` (text columns left, numbers right)."""
    names = names or {}
    numeric = [pd.api.types.is_numeric_dtype(df[c]) and not pd.api.types.is_bool_dtype(df[c]) for c in df.columns]
    spec = "".join("r" if n else "l" for n in numeric)
    head = " & ".join(escape(names.get(c, c)) for c in df.columns) + r" \\"
    body = [" & ".join(cell(v.item() if hasattr(v, "item") else v) for v in row) + r" \\" for row in df.itertuples(index=False)]
    return "\n".join([r"\begin{table}[t]", r"\centering", r"\small", f"\\caption{{{escape(caption)}}}", f"\\label{{{label}}}",
                      f"\\begin{{tabular}}{{{spec}}}", r"\toprule", head, r"\midrule", *body, r"\bottomrule", r"\end{tabular}",
                      r"\end{table}", ""])  # fmt: skip


def write(t: dict, out: Path) -> list[str]:
    """The headline tables into ``out`` as .tex files; returns their names."""
    rule, s = t["rule"], t["summary"]
    tables = {
        "summary": (s[["configuration", "runs", "final_over_ref_median", "val_rms_mm_median", f"success_{rule.primary()}",
                       f"ert_{rule.primary()}"]],
                    f"Configurations, best first: median final cost over the floor, validation RMS error (mm), share of runs "
                    f"reaching {rule.primary()} x the floor and the expected evaluations to reach it.",
                    {"final_over_ref_median": "final/floor", "val_rms_mm_median": "val. RMS (mm)",
                     f"success_{rule.primary()}": f"hit {rule.primary()}", f"ert_{rule.primary()}": f"ERT {rule.primary()}"}),
        "reference": (t["reference"][["instance", "reference", "cost", "val_rms_mm", "nevals"]],
                      "The reference on each instance: its final cost, validation RMS error (mm) and evaluations.",
                      {"val_rms_mm": "val. RMS (mm)", "nevals": "evaluations"}),
    }  # fmt: skip
    f = t["factors"]
    if len(f):
        pooled = f[(f["a"] != "all") & ((f["a"] == f["best"]) | (f["b"] == f["best"]))]
        tables["factors"] = (pooled[["setting", "instance", "a", "b", "p_holm", "effect", "effect_lo", "effect_hi", "verdict"]],
                             "Each setting over the others: the best value against each other value, p (Holm), P(a ends lower "
                             "than b) with its 95% bootstrap interval and the verdict.",
                             {"p_holm": "p (Holm)", "effect": "P(a<b)", "effect_lo": "CI low", "effect_hi": "CI high"})  # fmt: skip
    w = t["within"]
    if len(w):
        best = w[(w["a"] != "all") & ((w["a"] == w["best"]) | (w["b"] == w["best"])) & w["question"].astype(bool)]
        seen = [dict(instance=row["instance"], best=row["best"], verdict=oriented(row, row["best"])[1]) for _, row in best.iterrows()]
        counts = pd.DataFrame(seen).groupby(["instance", "best", "verdict"], sort=False).size().unstack(fill_value=0).reset_index()
        tables["within_instances"] = (counts, "The best configuration of each instance (lowest median) against every other: "
                                              "how many it is better than, equivalent to, worse than or undecided against.", {})  # fmt: skip
    written = []
    for name, (df, caption, names) in tables.items():
        if len(df):
            (out / f"{name}.tex").write_text(booktabs(df, caption, f"tab:{name}", names))
            written.append(f"{name}.tex")
    return written
