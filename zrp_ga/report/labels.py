"""Configurations and their labels, from the runs' configs (never from free text).

A run's configuration is what its optimiser was built from: the resolved ``algorithm`` node of
``summary.json``'s ``config`` (the GA's population, operators and settings are resolved into
it; Levenberg-Marquardt's and CMA-ES's hold only their own), flattened to ``key: value``. The
problem, the robot and the seed are not part of it: they make the instance and the repetition.

A label names, in words, the fewest settings that tell the report's configurations apart:
settings are tried in a fixed order (the algorithm, then the option groups refine, crossover,
mutation, inversion, rotation, selection, population, each by its option name, then single
keys, those the runs' Hydra overrides name first) and a setting is kept when it splits
configurations that the kept ones do not. An option's name is Hydra's choice (``summary.json``'s
``choices``) or, for runs made without Hydra, the last part of the option's ``_target_``.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from zrp_ga.report.runs import Run

GROUPS = ("algorithm", "refine", "crossover", "mutation", "inversion", "rotation", "selection", "population")
_WORDS = {
    ("algorithm", "ga"): "GA", ("algorithm", "lm"): "Levenberg-Marquardt", ("algorithm", "cmaes"): "CMA-ES",
    ("refine", "pinv"): "pseudo-inverse step", ("refine", "none"): "no pseudo-inverse step",
}  # fmt: skip
_FAMILIES = ("crossover", "mutation", "inversion", "rotation", "selection")
_SHORT = {"population.mu": "mu", "population.lambda_": "lambda", "population.max_evals": "budget",
          "population.generations": "generations"}  # fmt: skip


def describe(key: str, value: str) -> str:
    """A setting in words: ``crossover=sbx`` -> ``sbx crossover``, ``inversion=none`` -> ``no inversion``.

    >>> describe("crossover", "two_point"), describe("population.mu", "50")
    ('two point crossover', 'mu 50')
    """
    if (key, value) in _WORDS:
        return _WORDS[(key, value)]
    if key in _FAMILIES:
        return f"no {key}" if value == "none" else f"{value.replace('_', ' ')} {key}"
    return f"{_SHORT.get(key, key)} {value}"


def flatten(node: Any, prefix: str = "") -> dict[str, str]:
    """Leaves of a nested config as ``{dotted.key: str(value)}``.

    >>> flatten({"a": 1, "b": {"c": None, "d": [1, 2]}})
    {'a': '1', 'b.c': 'None', 'b.d': '[1, 2]'}
    """
    if not isinstance(node, dict):
        return {prefix: str(node)} if prefix else {}
    out = {}
    for k, v in node.items():
        out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    return out


def settings(run: Run) -> dict[str, str]:
    """The run's configuration as flat settings: its algorithm node (keys relative to it), or,
    for a summary without a config, its Hydra choices and overrides."""
    node = (run.summary.get("config") or {}).get("algorithm")
    if isinstance(node, dict):
        return flatten(node)
    fallback = {k: v for k, v in run.choices.items() if k in GROUPS}
    fallback.update({k: v for k, v in run.overrides.items() if k != "seed" and not k.startswith(("problem", "robot"))})
    fallback.setdefault("algorithm", str(run.summary.get("algorithm", "?")))
    return fallback


def option(run: Run, flat: dict[str, str], group: str) -> str | None:
    """The name of the run's option of ``group`` (None when its optimiser has no such group)."""
    if group == "algorithm":
        return run.choices.get("algorithm") or str(run.summary.get("algorithm") or flat.get("_target_", "?").rsplit(".", 1)[-1].lower())
    if not any(k == group or k.startswith(group + ".") for k in flat):
        return None
    if group in run.choices:
        return run.choices[group]
    target = flat.get(f"{group}.op._target_")
    if target is not None:
        return target.rsplit(".", 1)[-1]
    return "none" if flat.get(f"{group}.op") == "None" else None


def configurations(runs: list[Run]) -> tuple[list[str], dict[str, dict[str, str]]]:
    """A label per run (see the module docstring) and, per label, the settings it shows as
    ``{key: value}`` (option groups by name, single keys dotted)."""
    flats = [settings(r) for r in runs]
    ids = [tuple(sorted(f.items())) for f in flats]
    parts: dict[tuple, dict[str, str]] = {}
    for r, f, i in zip(runs, flats, ids):
        if i not in parts:
            items = {g: option(r, f, g) for g in GROUPS}
            items.update(f)
            parts[i] = {k: v for k, v in items.items() if v is not None}
    overridden = {k for r in runs for k in r.overrides}
    leaves = sorted({k for p in parts.values() for k in p if k not in GROUPS}, key=lambda k: (k not in overridden, k))
    kept: list[str] = []
    classes: dict[Any, tuple[Any, ...]] = {i: () for i in parts}
    for key in list(GROUPS) + leaves:
        split = {i: classes[i] + (parts[i].get(key),) for i in parts}
        if len(set(split.values())) > len(set(classes.values())):
            kept.append(key)
            classes = split
    shown = {}
    for i, p in parts.items():
        words = [describe(k, p[k]) for k in kept if k in p]
        shown[i] = (", ".join(words) or describe("algorithm", p["algorithm"]), {k: p[k] for k in kept if k in p})
    labels = [shown[i][0] for i in ids]
    return labels, {label: keys for label, keys in shown.values()}


_WORD = {"polynomial": "poly", "gaussian": "Gauss", "uniform_reset": "reset", "two_point": "2-point", "one_point": "1-point",
         "sbx": "SBX", "cmaes": "CMA-ES", "ga": "GA", "lm": "LM"}  # fmt: skip
_KEY = {"inversion": "inv", "rotation": "rot", "selection": "sel"}


def short(settings_: dict[str, str]) -> str:
    """A configuration's label for a figure, a few words: the operators' short names (``poly``,
    ``2-point``), ``inv``/``rot`` for segment inversion and rotation (``no inv``: none), the
    algorithm, ``step``/``no step`` for the pseudo-inverse step, single settings with their short key.

    >>> short({"crossover": "blend", "mutation": "uniform_reset", "inversion": "none", "rotation": "segment"})
    'blend, reset, no inv, rot'
    >>> short({"algorithm": "lm"}), short({"population.mu": "50", "refine": "none"})
    ('LM', 'mu 50, no step')
    """
    words = []
    for key, value in settings_.items():
        if key == "refine":
            words.append("step" if value != "none" else "no step")
        elif key in _KEY:
            words.append(f"no {_KEY[key]}" if value == "none" else _KEY[key] if value == "segment" else f"{_WORD.get(value, value)} {_KEY[key]}")
        elif key in _FAMILIES or key == "algorithm":
            words.append(f"no {key}" if value == "none" else _WORD.get(value, value.replace("_", " ")))
        else:
            words.append(f"{_SHORT.get(key, key.rsplit('.', 1)[-1])} {value}")
    return ", ".join(words)


KEY_NOTE = "poly: polynomial, Gauss: Gaussian, reset: uniform reset mutation; inv, rot: segment inversion, rotation"


def short_labels(shown: dict[str, dict[str, str]]) -> dict[str, str]:
    """:func:`short` of every configuration, the long label where two would read the same."""
    out = {label: short(s) or label for label, s in shown.items()}
    counts = Counter(out.values())
    return {label: (s if counts[s] == 1 else label) for label, s in out.items()}
