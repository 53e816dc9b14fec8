"""Which settings matter on which instance, from a report's ``runs.csv``: a thin wrapper.

    python experiments/suite_factors.py REPORT_DIR [--out FILE]

``zrp-ga-report`` now writes this view itself (``factors.md``, ``factors_by_instance.md`` and
the page's "Each setting over the others"): the main effect of each swept setting over the
others, per instance and across instances, paired by the other settings and the seed where the
design allows (:func:`zrp_ga.report.tables.factorial`). This script recomputes it from the
``runs.csv`` of an existing report, without the run directories.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from zrp_ga.report import conclusions
from zrp_ga.report.common import markdown
from zrp_ga.report.tables import factorial

NOT_SETTINGS = {"run", "configuration", "instance", "seed", "final_cost", "reference", "final_over_ref",
                "final_over_initial", "nevals", "val_rms_mm", "val_rms_nominal_mm", "wall_s", "evals_to_target",
                "auc", "auc_budget"}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path, help="a zrp-ga-report output directory (its runs.csv)")
    parser.add_argument("--out", type=Path, default=None, help="markdown file (default REPORT/factors_by_instance.md)")
    args = parser.parse_args()
    runs = pd.read_csv(args.report / "runs.csv", keep_default_na=False, na_values={"final_over_ref": ["", "nan"]})
    keys = [c for c in runs.columns if c not in NOT_SETTINGS and runs[c].nunique() > 1]
    runs[keys] = runs[keys].astype(str)
    tests, medians = factorial(runs, keys)
    wide = medians.pivot_table(index=["setting", "value"], columns="instance", values="median_final_over_ref", sort=False)
    said = conclusions.factors({"factors": tests, "factor_medians": medians, "floors": runs[["instance"]].drop_duplicates()})
    lines = [f"# Settings by instance ({len(runs)} runs, {runs['instance'].nunique()} instances)\n",
             f"Command: `python experiments/suite_factors.py {args.report}`.\n", *[f"- {s}" for s in said], "",
             "Median final cost / f_ref per value:\n", markdown(wide.reset_index()), "", "The tests:\n", markdown(tests)]  # fmt: skip
    out = args.out or args.report / "factors_by_instance.md"
    out.write_text("\n".join(lines))
    print("\n".join(lines[:3 + len(said)]))


if __name__ == "__main__":
    main()
