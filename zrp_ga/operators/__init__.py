"""Variation operators on numpy genomes, one module per family, and :func:`build`, which turns
an operator's config node into the function the GA calls.

Every operator keeps DEAP's calling convention and changes its arguments in place:
``cx(ind1, ind2, rng, **params) -> (ind1, ind2)``, ``mut(ind, rng, **params) -> (ind,)``,
``select(costs, k, rng, **params) -> indices``. The operators here are :func:`batched`: an
argument may be one genome (K,) or a batch of genomes (N, K), each row varied independently, so
that the GA varies a whole generation in a few numpy calls; random numbers come from the
``numpy.random.Generator`` passed in, drawn for the whole batch at once, and the segment moves
are numpy gathers. Any other function named in a config, DEAP's own operators
(``deap.tools.cxBlend``) included, is applied one individual at a time through
:mod:`zrp_ga.operators.deap_adapter` (slower; for comparison). Whichever it is, :func:`target`
checks its parameters before any work: known to the function, in range, none missing.

In a DEAP toolbox of your own, on DEAP's list individuals, register them through
:func:`zrp_ga.operators.deap_tools.for_deap`, which converts the lists and binds the generator.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from typing import Any, overload

import numpy as np

from zrp_ga.core import targets
from zrp_ga.core.schema import ConfigError
from zrp_ga.operators import deap_adapter
from zrp_ga.operators.base import (  # noqa: F401 (the operators' shared helpers, importable from here as before)
    Array,
    batched,
    block_bounds,
    reverse_segments,
    rotate_segments,
    rows,
    segments,
    swap_segments,
)

# What the usual operator parameters must be, whichever operator takes them (DEAP's included).
RULES: dict[str, tuple[Callable[[Any], bool], str]] = {
    "indpb": (lambda v: 0.0 <= v <= 1.0, "a probability in [0, 1]"),
    "sigma": (lambda v: v > 0.0, "a number > 0"),
    "eta": (lambda v: v >= 0.0, "a number >= 0"),
    "alpha": (lambda v: v >= 0.0, "a number >= 0"),
    "size": (lambda v: v >= 1 and float(v).is_integer(), "a whole number >= 1"),
    "tournsize": (lambda v: v >= 1 and float(v).is_integer(), "a whole number >= 1"),
    "fraction": (lambda v: 0.0 < v <= 1.0, "a fraction in (0, 1]"),
    "rcond": (lambda v: 0.0 <= v < 1.0, "a number in [0, 1)"),
}


def _check(key: str, params: dict) -> None:
    for name, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        ok, what = RULES.get(name, (lambda v: True, "a finite number"))
        if not (np.isfinite(value) and ok(value)):
            raise ValueError(f"{key}.{name}: must be {what}, got {value}")


# The genomes (or costs) an operator of each family takes first, before its parameters; one
# genome for the others (mutation, inversion, rotation, refine).
GENOME_ARGS = {"crossover": 2, "selection": 2}
# What :func:`build` binds from the problem when the function takes it.
CONTEXT = ("low", "up", "blocks", "problem")


def parameters(fn: Callable, family: str) -> dict[str, inspect.Parameter]:
    """The parameters of operator ``fn`` a config may set: its own after the genomes it varies
    (two for crossover and selection, one for the others) and ``rng``."""
    params = list(inspect.signature(fn).parameters.values())[GENOME_ARGS.get(family, 1) :]
    kinds = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
    return {p.name: p for p in params if p.name != "rng" and p.kind not in kinds}


def _require(fn_name: str, takes: dict[str, inspect.Parameter], given: Mapping[str, Any], key: str) -> None:
    """ConfigError naming ``key`` and the first parameter without a default that is not ``given``."""
    missing = [k for k, p in takes.items() if p.default is inspect.Parameter.empty and k not in given]
    if missing:
        raise ConfigError(f"{key}.{missing[0]}: {fn_name} needs this parameter (missing: {', '.join(missing)}); "
                          f"add +{key}.{missing[0]}=VALUE")  # fmt: skip


def target(node: Mapping[str, Any], key: str, family: str | None = None) -> tuple[Callable, dict]:
    """The function an operator node names by ``_target_`` and its parameters, checked before
    any work: ValueError (ConfigError for a missing parameter) naming ``key`` when the function
    cannot be found, a parameter is not one it takes, a value is out of range or a parameter
    without a default is not given (the problem's ``low``, ``up``, ``blocks`` and ``problem``
    count as given: :func:`build` binds them). ``family``: the operator family (default: the
    first part of ``key``, e.g. ``mutation`` of ``mutation.op``).

    The nodes are ``_target_`` / ``_partial_`` specs, with the meaning
    :func:`zrp_ga.core.targets.instantiate` (and Hydra's ``instantiate``) gives them; they are
    bound here into a plain ``functools.partial`` with the problem's ranges and the generator.
    """
    params = dict(node)
    name = params.pop("_target_", None)
    params.pop("_partial_", None)
    if not name:
        raise ValueError(f"{key}._target_: an operator needs the dotted name of a function")
    try:
        fn = targets.locate(name)
    except targets.TargetError as exc:
        raise ValueError(f"{key}._target_: {exc}") from None
    takes = parameters(fn, family or key.split(".")[0])
    unknown = sorted(set(params) - set(takes))
    if unknown:
        raise ValueError(f"{key}: unknown parameter {unknown[0]!r} for {name} (takes: {', '.join(takes) or 'none'})")
    _check(key, params)
    _require(name, takes, {**params, **dict.fromkeys(CONTEXT)}, key)
    return fn, params


@overload
def build(node: Mapping[str, Any], key: str, family: str, rng: np.random.Generator, **context: Any) -> Callable[..., Any]: ...
@overload
def build(node: None, key: str, family: str, rng: np.random.Generator, **context: Any) -> None: ...
def build(
    node: Mapping[str, Any] | None, key: str, family: str, rng: np.random.Generator, **context: Any
) -> Callable[..., Any] | None:
    """The operator of config node ``node`` (None: no operator), ready for the GA: the node's
    parameters, ``rng``, and whichever of ``context`` (the gene ranges ``low`` and ``up``, the
    gene ``blocks``, the ``problem``) the function takes bound; per-individual functions wrapped by the adapter for ``family``
    (``crossover``, ``mutation``, ``selection``)."""
    if node is None:
        return None
    fn, params = target(node, key, family)
    takes = parameters(fn, family)
    params.update({k: v for k, v in context.items() if k in takes and k not in params})
    _require(node["_target_"], takes, params, key)  # a context value this family does not get
    if getattr(fn, "batched", False):
        return functools.partial(fn, rng=rng, **params)
    return deap_adapter.wrap(fn, family, **params)
