"""``zrp-ga-report DIR...``: tables, statistics and figures of finished runs, over one problem
instance or many, as COCO and IOHprofiler compare optimisers.

Reads only the files runs wrote (convergence.csv, summary.json, initial_population.csv,
best_params.csv, status.json, the sweep manifest and Hydra's overrides.yaml) and never re-runs
anything, so a report can be redrawn at any time, also of a sweep still running. A run that
failed, is still running or was interrupted, and a run whose convergence.csv or summary.json is
malformed or truncated, is left out, named with the reason on the console and in
``left_out.csv`` (:mod:`zrp_ga.report.runs`). Everything is written to a temporary folder first
and moved into ``--out`` at the end: an error leaves nothing half-written.

Words and numbers
-----------------
- **Instance**: summary.json's ``instance`` (the problem, its data and, for simulated problems,
  the instance seed); runs of one instance share it. A run needs ``instance``, ``nevals`` and
  ``final_cost`` in its summary.json, and convergence.csv's ``gen``, ``nevals`` and ``best``.
- **Configuration**: what the optimiser was built from (summary.json's resolved
  ``config.algorithm``); its label names the settings that tell the configurations apart, from
  the runs' Hydra choices and overrides (:mod:`zrp_ga.report.labels`).
- **Trace** of a run: the best cost within n evaluations, from ``convergence.csv`` (one row
  per generation; an improvement counts at the end of its generation) and, for the first
  generation, ``initial_population.csv`` one evaluation at a time. Runtime is evaluations.
- **Floor f*** of an instance: summary.json's ``floor`` when present (Levenberg-Marquardt's final
  cost on the instance), else the lowest final cost among the report's runs of that instance
  ("best known", as COCO does when the optimum is unknown); ``targets.csv`` says which.
- **Reference f_ref** = f*, except where f* < 1e-9 x the nominal cost (the cost of the nominal
  model; ``--round-off``): there f* is round-off (the one-pose paper problem is solved exactly,
  f* ~ 1e-18) and ratios to it are noise, so f_ref = 1e-9 x the nominal cost: there a run hits
  target c when its cost is down to c billionths of the nominal model's cost.
- **Targets**: c x f_ref for each level c (``--levels``, default 1.5, 1.1, 1.05, 1.01); a run
  hits a target when its best cost <= the target. ``--target COST`` sets one absolute target for
  every instance instead. The **primary target** (1.05, else the tightest level, or ``--target``)
  feeds the single-target columns ``evals_to_target`` and ``success_rate``.
- **ERT** (expected running time, COCO's aRT) per configuration and target: the evaluations of all
  runs (successful ones to their first hit, unsuccessful ones in full) over the number of
  successful runs; inf when none succeeds. Per instance, and pooled over the instances ("all",
  each run one trial, as COCO pools a function's instances).
- **ECDF** (fixed-target) per configuration: at each budget b, the fraction of (run, target) pairs
  hit within b evaluations, aggregated over the configuration's (instance, level) pairs, each
  pair weighing the same (within a pair, the share of its runs). ``ecdf.csv`` holds it for the
  levels; the figures use COCO-style targets instead: 51 per instance, their distances to f_ref
  log-spaced from f0 - f_ref (f0 the median first cost of the instance's runs) down to
  0.01 f_ref, so that the last is the tightest level, 1.01 x f_ref; budgets in evaluations per
  gene (``ecdf_targets.csv``).
- **Fixed budget** at b evaluations (``--budgets``, default 100, 1,000, 10,000): a run's best cost
  within b evaluations over f_ref (a run that stopped earlier counts with its final best), the
  median over runs per instance, and the median of those over instances.
- **Ranks across instances**: per instance the median final cost of each configuration, clipped
  below at the instance's tightest target (1.01 x f_ref by default: closer to the floor the
  targets tell nothing apart, so such configurations tie), ranked (1 = lowest, ties averaged)
  on the instances where every configuration ran; Friedman's test (the sign test for
  two configurations) and Nemenyi's post-hoc test with its critical difference at 0.05
  (:func:`zrp_ga.report.stats.friedman`).
- **Within one instance** (``within_instances``): the configurations compared on the final cost,
  paired by seed when they share their seeds (Friedman's test with the seeds as blocks, pairwise
  Wilcoxon signed-rank tests with Holm's correction, effect = the share of seeds where A ends
  lower), else Kruskal-Wallis and Mann-Whitney U (effect A12); the omnibus p-values Holm-corrected
  over the instances; 95% bootstrap intervals of the effects against the instance's best.
- **Each setting over the others** (``factors``, ``factors_by_instance.md``): the values of each
  setting compared on final cost / f_ref, paired by the other settings and the seed (and the
  instance, across instances) where the design is complete, per instance and over all.
- **Within pooled runs**: median and interquartile range of the final cost, of final cost / f_ref
  and of the final validation error (RMS over the validation poses, mm; none on measured data
  without a validation set); the final/initial cost ratio (the paper's measure); Kruskal-Wallis
  across configurations, pairwise Mann-Whitney U with Holm's correction and the Vargha-Delaney
  effect size A12 = P(a run of A ends lower than a run of B) + P(tie)/2 (``statistics``). Pooling runs of different
  instances mixes their scales in ``final_cost``; ``final_over_ref`` and the ranks do not.
- **Area under the curve** (``auc``): the mean of log10(best so far) over the evaluations from
  a run's first row to the smallest final evaluation count of all runs (lower is better).

Outputs in ``--out`` (default ``report`` beside the first DIR): ``index.html``, the whole report
as one self-contained page (design, conclusions in sentences, every figure inline as SVG with
its caption, the tables, the versions and the command; no script, no network), and its parts,
CSV with a Markdown twin where useful: ``targets`` (per instance: runs, nominal cost, f*, its source, round-off or not, f_ref,
the targets), ``summary`` (per configuration, pooled), ``per_instance``, ``ert`` (``ert.md``: pooled
over instances), ``ecdf``, ``fixed_budget`` (per instance; ``fixed_budget.md``: the medians over
instances), ``ranks`` (Friedman's test and the mean ranks; ``ranks_nemenyi.csv`` the pairwise
p-values), ``statistics``, ``factors``, ``runs`` (one row per run), ``tidy`` (one row per run and
generation), ``left_out`` (run, reason); figures (``--formats``, default PNG, PDF and SVG;
``none``: no figures; ``--style paper``, 3.5 in wide with 8-9 pt text, or ``screen``):
``fig2_convergence`` (the paper's Fig. 2: the median run of each configuration, up to eight, on
the instance with most runs), ``convergence_by_configuration`` (median and interquartile band
against evaluations; over f* where every floor is above round-off), ``ecdf_evals_to_target`` and
``ecdf_by_instance``, ``validation_error_boxplot`` (when a run has validation poses; every run a
point), ``critical_difference`` (when Friedman's test across instances separates three or more
configurations); ``table2_initial_population.md`` and ``table3_best_params.md`` of the median
run of the best configuration; ``ioh/`` (or ``--ioh DIR``) the runs in IOHprofiler's format
(:mod:`zrp_ga.report.ioh_export`). Files of an earlier report in the same folder that this one
does not write are removed; other files are left alone.
"""

from __future__ import annotations

from typing import Any

from zrp_ga.report.write import write_report

_LAZY = {  # imported on first use: the command checks its paths before loading pandas, scipy and matplotlib
    "pose_error_figure": "figures", "configurations": "labels", "describe": "labels", "Run": "runs", "find_runs": "runs",
    "build_tables": "tables", "TargetRule": "targets", "figures": None, "targets": None, "tables": None, "runs": None,
    "labels": None, "stats": None, "ioh_export": None, "common": None, "conclusions": None, "drawing": None, "page": None,
}  # fmt: skip


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'zrp_ga.report' has no attribute {name!r}")
    import importlib

    module = importlib.import_module(f"zrp_ga.report.{_LAZY[name] or name}")
    return module if _LAZY[name] is None else getattr(module, name)


__all__ = ["Run", "TargetRule", "build_tables", "configurations", "describe", "find_runs", "pose_error_figure",
           "write_report"]  # fmt: skip
